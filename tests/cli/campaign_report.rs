//! The campaign report: `report.md` and a self-contained `report.html`, each kind's plots drawn
//! from the run's own numbers, and `radbench campaign report RUN_DIR` writing both again byte for
//! byte. Each test runs one example campaign on the built-in mock lab (loopback only).

use radbench::campaign;
use radbench::campaign::Manifest;
use radbench::campaign::{wilson95, Figure};
use radbench::campaign::{AlgorithmResult, Results};
use std::path::{Path, PathBuf};

async fn radbench(args: &[&str]) -> (i32, String, String) {
    crate::support::radbench_in(None, args).await
}

/// Runs `examples/{name}.toml` into a fresh folder; (temp dir, run folder, manifest, results).
async fn run(name: &str) -> (tempfile::TempDir, PathBuf, Manifest, Results) {
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("run");
    let spec = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("examples")
        .join(format!("{name}.toml"));
    let (code, stdout, err) = radbench(&[
        "campaign",
        "run",
        spec.to_str().unwrap(),
        "--allow-rf",
        "--out",
        out.to_str().unwrap(),
    ])
    .await;
    assert_eq!(code, 0, "{err}");
    assert!(stdout.contains("report.html"), "{stdout}");
    let manifest = Manifest::load(&out).unwrap();
    let results = campaign::load_results(&out).unwrap();
    (tmp, out, manifest, results)
}

/// Tag balance of the page: every element closed in order (void ones self-closed), nothing after
/// `</html>`.
fn check_well_formed(html: &str) {
    let body = html
        .strip_prefix("<!DOCTYPE html>")
        .expect("starts with the doctype");
    let mut stack: Vec<String> = Vec::new();
    let mut rest = body;
    while let Some(k) = rest.find('<') {
        rest = &rest[k + 1..];
        let end = rest.find('>').expect("every tag closes");
        let tag = &rest[..end];
        rest = &rest[end + 1..];
        if tag.starts_with('!') || tag.starts_with('?') {
            continue;
        }
        if let Some(name) = tag.strip_prefix('/') {
            let open = stack
                .pop()
                .unwrap_or_else(|| panic!("</{name}> closes nothing"));
            assert_eq!(open, name.trim(), "</{name}> closes <{open}>");
        } else if !tag.ends_with('/') {
            let name = tag.split_whitespace().next().unwrap().to_string();
            stack.push(name);
        }
    }
    assert!(stack.is_empty(), "unclosed: {stack:?}");
    assert!(html.trim_end().ends_with("</html>"));
}

/// report.html: self-contained (no script, no external reference), every figure an inline SVG,
/// well-formed; `campaign report` writes both reports again byte for byte (and the manifest's
/// hashes still hold).
async fn check_reports(dir: &Path, figures: &[Figure]) {
    // Every report also shows every step's range profile, from the step folders.
    let results = campaign::load_results(dir).unwrap();
    let profiles = campaign::step_profiles(dir, &results).expect("the steps' profiles");
    assert_eq!(profiles.id, "step-profiles");
    let rows = profiles.chart.y_categories.as_ref().unwrap();
    assert_eq!(rows.len(), results.steps.len());
    let traces = profiles
        .chart
        .series
        .iter()
        .filter(|s| s.style == radbench::campaign::Style::Trace)
        .count();
    assert_eq!(traces, results.steps.len(), "one profile per step");
    let mut all = figures.to_vec();
    all.push(profiles);
    let figures = &all[..];
    let html = std::fs::read_to_string(dir.join("report.html")).unwrap();
    let md = std::fs::read_to_string(dir.join("report.md")).unwrap();
    check_well_formed(&html);
    let lower = html.to_lowercase();
    for banned in [
        "<script", "<link", "<img", "<iframe", "src=", "href=", "url(", "@import",
    ] {
        assert!(!lower.contains(banned), "report.html holds {banned}");
    }
    for f in figures {
        let at = html
            .find(&format!("<figure id=\"{}\"", f.id))
            .unwrap_or_else(|| panic!("no figure {}", f.id));
        let end = at + html[at..].find("</figure>").unwrap();
        let svg = &html[at..end];
        assert!(svg.contains("<svg") && svg.contains("</svg>"), "{}", f.id);
        assert!(
            svg.contains("<circle") || svg.contains("<polyline"),
            "{}",
            f.id
        );
        let png = format!("](figures/{}.png)", f.id);
        assert!(md.contains(&png), "report.md embeds {}", f.id);
        let bytes = std::fs::read(dir.join("figures").join(format!("{}.png", f.id))).unwrap();
        assert!(bytes.starts_with(b"\x89PNG"), "{} is a PNG", f.id);
    }
    assert_eq!(html.matches("\" class=\"plot\">").count(), figures.len());
    check_link_figures(dir, &results, &html);
    std::fs::remove_file(dir.join("report.html")).unwrap();
    std::fs::write(dir.join("report.md"), "stale").unwrap();
    let (code, stdout, err) = radbench(&["campaign", "report", dir.to_str().unwrap()]).await;
    assert_eq!(code, 0, "{err}");
    assert!(stdout.contains("report.html"), "{stdout}");
    assert_eq!(
        std::fs::read_to_string(dir.join("report.html")).unwrap(),
        html
    );
    assert_eq!(std::fs::read_to_string(dir.join("report.md")).unwrap(), md);
    let m = Manifest::load(dir).unwrap();
    for name in ["report.md", "report.html"] {
        let f = m
            .files
            .iter()
            .find(|f| f.path == Path::new(name))
            .unwrap_or_else(|| panic!("the manifest records {name}"));
        assert_eq!(f.check(dir), None, "{name}");
    }
}

/// Every step whose folder holds a `link.svg` (each example sends data) has its link figure
/// inline in report.html, captioned with its EVM and MER from results.json.
fn check_link_figures(dir: &Path, results: &Results, html: &str) {
    let with: Vec<usize> = results
        .steps
        .iter()
        .filter(|s| {
            dir.join(format!("step-{:03}", s.index))
                .join("link.svg")
                .is_file()
        })
        .map(|s| s.index)
        .collect();
    assert!(!with.is_empty(), "the steps drew their link");
    assert!(with.len() <= 12, "all shown");
    assert!(html.contains("<section id=\"link-steps\">"));
    assert_eq!(html.matches("class=\"link\">").count(), with.len());
    for s in results.steps.iter().filter(|s| with.contains(&s.index)) {
        let at = html
            .find(&format!(
                "<figure id=\"link-step-{:03}\" class=\"link\">",
                s.index
            ))
            .unwrap_or_else(|| panic!("no link figure for step {}", s.index));
        let end = at + html[at..].find("</figure>").unwrap();
        let fig = &html[at..end];
        assert!(fig.contains("<svg") && fig.contains("</svg>"));
        assert!(fig.matches("<circle").count() > 20, "a constellation");
        let p = s
            .algorithms
            .values()
            .find_map(|a| a.payload.as_ref())
            .unwrap();
        let caption = &fig[fig.find("<figcaption>").unwrap()..];
        assert!(
            caption.contains(&format!("EVM {:.2} % rms", p.evm_rms_pct.unwrap()))
                && caption.contains(&format!("{:.2} % at the 95th", p.evm_p95_pct.unwrap()))
                && caption.contains(&format!("MER {:.1} dB", p.mer_db.unwrap())),
            "step {}: {caption}",
            s.index
        );
    }
}

fn ids(figures: &[Figure]) -> Vec<&'static str> {
    figures.iter().map(|f| f.id).collect()
}

fn series<'a>(f: &'a Figure, starts: &str) -> &'a radbench::campaign::Series {
    f.chart
        .series
        .iter()
        .find(|s| s.label.starts_with(starts))
        .unwrap_or_else(|| panic!("{}: no series {starts}", f.id))
}

fn close(a: f64, b: f64) -> bool {
    (a - b).abs() <= 1e-12 * b.abs().max(1.0)
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn accuracy_plots_the_error_with_and_without_interpolation_within_the_bounds() {
    let (_tmp, dir, manifest, results) = run("accuracy").await;
    let figures = campaign::figures(&manifest, &results);
    assert_eq!(ids(&figures), ["accuracy-error"]);
    let f = &figures[0];
    let interp = series(f, "correlation, sub-sample");
    let grid = series(f, "correlation, on the grid");
    assert_eq!(interp.points.len(), 6);
    assert_eq!(grid.points.len(), 6);
    for (k, s) in results.steps.iter().enumerate() {
        let a = &s.algorithms["correlation"];
        assert!(close(interp.points[k].x, s.nominal.targets[0].range_m));
        assert!(close(interp.points[k].y, a.error_m.unwrap() * 100.0));
        assert!(close(grid.points[k].y, a.error_on_grid_m.unwrap() * 100.0));
    }
    // The bounds: +-c0/(2 fs) and +-c0/(4 fs) at 16 GSa/s, in cm.
    let mut bounds: Vec<f64> = f.chart.hlines.iter().map(|h| h.y).collect();
    bounds.sort_by(f64::total_cmp);
    let c = 299_792_458.0 / 16e9 * 100.0;
    let want = [-c / 2.0, -c / 4.0, c / 4.0, c / 2.0];
    for (b, w) in bounds.iter().zip(want) {
        assert!(close(*b, w), "{bounds:?}");
    }
    check_reports(&dir, &figures).await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn resolution_plots_resolved_or_not_per_bandwidth() {
    let (_tmp, dir, manifest, results) = run("resolution").await;
    let figures = campaign::figures(&manifest, &results);
    assert_eq!(ids(&figures), ["resolution"]);
    let f = &figures[0];
    assert_eq!(
        f.chart.y_categories.as_deref().unwrap(),
        ["correlation, 1 GHz", "correlation, 2 GHz"]
    );
    for (k, s) in results.steps.iter().enumerate() {
        let p = f.chart.series[k].points[0];
        assert_eq!(
            p.filled,
            s.algorithms["correlation"].resolved.unwrap(),
            "{k}"
        );
        assert!(close(p.x, 8.0), "{}", p.x);
    }
    // The resolution cells c0/(2B), cm.
    let cells: Vec<f64> = f.chart.vlines.iter().map(|v| v.0).collect();
    assert!(close(cells[0], 299_792_458.0 / 2e9 * 100.0), "{cells:?}");
    assert!(close(cells[1], 299_792_458.0 / 4e9 * 100.0), "{cells:?}");
    // As the thesis (4.4.3): 8 cm not resolved at 1 GHz, resolved at 2 GHz.
    assert!(!f.chart.series[0].points[0].filled);
    assert!(f.chart.series[1].points[0].filled);
    check_reports(&dir, &figures).await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn single_target_plots_width_and_psl_beside_the_thesis() {
    let (_tmp, dir, manifest, results) = run("single-target").await;
    let figures = campaign::figures(&manifest, &results);
    assert_eq!(ids(&figures), ["single-width", "single-psl"]);
    let a: &AlgorithmResult = &results.steps[0].algorithms["correlation"];
    // Four repetitions: mean +- std of the repetitions.
    let spread = a.spread.as_ref().expect("four repetitions have a spread");
    let w = spread.width_3db_cm.unwrap();
    let p = spread.sidelobe_db.unwrap();
    assert_eq!(w.n, 4);
    let wp = figures[0].chart.series[0].points[0];
    assert!(close(wp.y, w.mean));
    assert_eq!(wp.bar, Some((w.mean - w.std, w.mean + w.std)));
    assert!(close(figures[1].chart.series[0].points[0].y, p.mean));
    // The thesis' simulation (Table 4.5) and lab (4.4.1) values for MSK-LFM.
    let lines = |f: &Figure| f.chart.hlines.iter().map(|h| h.y).collect::<Vec<f64>>();
    assert_eq!(lines(&figures[0]), [13.2, 12.73]);
    assert_eq!(lines(&figures[1]), [-13.24, -10.49]);
    let md = std::fs::read_to_string(dir.join("report.md")).unwrap();
    // Mean ± std with the deviation's two significant digits (two decimals at least).
    let d = ((1.0 - w.std.log10().floor()).max(0.0) as usize).clamp(2, 6);
    let want = format!("{:.d$} ± {:.d$} (n=4)", w.mean, w.std);
    assert!(md.contains(&want), "{want} not in {md}");
    assert!(
        md.contains("13.2 (Table 4.5)") && md.contains("-10.49 (4.4.1)"),
        "{md}"
    );
    check_reports(&dir, &figures).await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn link_plots_ber_with_theory_and_the_radar_figures() {
    let (_tmp, dir, manifest, results) = run("link").await;
    let figures = campaign::figures(&manifest, &results);
    assert_eq!(
        ids(&figures),
        [
            "link-ber",
            "link-evm",
            "link-width",
            "link-psl",
            "link-error"
        ]
    );
    let ber = series(&figures[0], "fourier measured");
    assert_eq!(ber.points.len(), results.steps.len());
    let mut with_errors = 0;
    for (k, s) in results.steps.iter().enumerate() {
        let pay = s.algorithms["fourier"].payload.as_ref().unwrap();
        let p = ber.points[k];
        assert!(close(p.x, s.nominal.tx_attenuation_db.unwrap()));
        if pay.bit_errors == 0 {
            assert!(!p.filled);
            assert!(close(p.y, wilson95(0, pay.bits).1));
        } else {
            with_errors += 1;
            assert!(close(p.y, pay.ber));
            assert_eq!(p.bar, Some(wilson95(pay.bit_errors, pay.bits)));
        }
    }
    // The mock lab's Tx attenuation reaches bit errors at the high end: theory is drawn.
    assert!(with_errors >= 1);
    let theory = series(&figures[0], "ofdm theory");
    assert!(theory.points.len() >= 5);
    // EVM and MER of every step in results.json, plotted against the attenuation, and the BER
    // the measured MER implies beside the measured one.
    let evm = series(&figures[1], "fourier EVM rms");
    assert_eq!(evm.points.len(), results.steps.len());
    for (k, s) in results.steps.iter().enumerate() {
        let pay = s.algorithms["fourier"].payload.as_ref().unwrap();
        assert!(close(evm.points[k].y, pay.evm_rms_pct.unwrap()));
        assert!(pay.mer_db.unwrap().is_finite() && pay.evm_p95_pct.unwrap() > 0.0);
    }
    assert!(!series(&figures[0], "fourier: Q(sqrt(MER))")
        .points
        .is_empty());
    let width = &figures[2].chart.series[0];
    for (k, s) in results.steps.iter().enumerate() {
        let m = s.algorithms["fourier"]
            .spread
            .as_ref()
            .unwrap()
            .width_3db_cm
            .unwrap();
        assert!(close(width.points[k].y, m.mean));
    }
    check_reports(&dir, &figures).await;
}

/// A pillar left where it was (the stage did not move): the step that misses its nominal target
/// says MISSED on the console, and the report's error cells say "missed" rather than "-".
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_missed_target_is_said_on_the_console_and_in_the_report() {
    let tmp = tempfile::tempdir().unwrap();
    let d = tmp.path();
    std::fs::write(
        d.join("lab.toml"),
        "snr_db = 30.0\n[[targets]]\nrange_m = 1.0\namplitude = 0.5\n",
    )
    .unwrap();
    std::fs::write(
        d.join("spec.toml"),
        "name = \"stuck stage\"\n[bench]\nscene = \"lab.toml\"\n\
         [positioner]\nkind = \"command\"\nprogram = \"true\"\n\
         [sweep]\nparameter = \"position\"\nvalues = [1.0, 1.3]\n",
    )
    .unwrap();
    let (code, stdout, err) = crate::support::radbench_in(
        Some(d),
        &["campaign", "run", "spec.toml", "--allow-rf", "--out", "run"],
    )
    .await;
    assert_eq!(code, 0, "{err}");
    let lines: Vec<&str> = stdout
        .lines()
        .chain(err.lines())
        .filter(|l| l.starts_with("step "))
        .collect();
    assert_eq!(lines.len(), 2, "{stdout}{err}");
    assert!(!lines[0].contains("MISSED"), "{}", lines[0]);
    assert!(lines[1].contains("MISSED 1"), "{}", lines[1]);
    let md = std::fs::read_to_string(d.join("run/report.md")).unwrap();
    assert!(md.contains("| missed 1 |"), "{md}");
    // The summary leads with the verdict: a missed target fails the run.
    assert!(md.contains("**FAIL: 1 nominal target(s) missed.**"), "{md}");
    let html = std::fs::read_to_string(d.join("run/report.html")).unwrap();
    assert!(html.contains("missed 1"), "the page says it too");
    assert!(html.contains("<p class=\"verdict fail\">FAIL: 1 nominal target(s) missed.</p>"));
}

/// `campaign report` on a damaged run folder: a missing, binary or truncated `results.json` is
/// bad input (exit 2) each; an edited one is refused (its hash is not the manifest's) unless
/// `--force`, which renders it and records the new hashes, so the manifest stays true.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn report_on_a_damaged_or_edited_results_json() {
    let (_tmp, dir, _, _) = run("accuracy").await;
    let results = dir.join("results.json");
    let original = std::fs::read(&results).unwrap();
    let report = |force: bool| {
        let dir = dir.to_str().unwrap().to_string();
        async move {
            let mut args = vec!["campaign", "report", dir.as_str()];
            if force {
                args.push("--force");
            }
            radbench(&args).await
        }
    };
    std::fs::remove_file(&results).unwrap();
    let (code, _, err) = report(false).await;
    assert_eq!(code, 2, "missing: {err}");
    assert!(err.contains("missing"), "{err}");
    for (what, bytes) in [
        ("binary", vec![0xff, 0xfe, 0x00, 0x80]),
        ("truncated", original[..original.len() / 2].to_vec()),
    ] {
        std::fs::write(&results, &bytes).unwrap();
        let (code, _, err) = report(true).await;
        assert_eq!(code, 2, "{what}: {err}");
        assert!(err.contains("results.json"), "{what}: {err}");
    }
    // Edited but valid: refused without --force, nothing rewritten.
    let mut edited = original.clone();
    edited.extend_from_slice(b"\n");
    std::fs::write(&results, &edited).unwrap();
    let html_before = std::fs::read(dir.join("report.html")).unwrap();
    let (code, _, err) = report(false).await;
    assert_eq!(code, 2, "{err}");
    assert!(err.contains("--force") && err.contains("changed"), "{err}");
    assert_eq!(std::fs::read(dir.join("report.html")).unwrap(), html_before);
    let (code, _, err) = report(true).await;
    assert_eq!(code, 0, "{err}");
    assert!(err.contains("new SHA-256"), "{err}");
    let manifest = Manifest::load(&dir).unwrap();
    for file in ["results.json", "report.md", "report.html"] {
        let record = manifest
            .files
            .iter()
            .find(|f| f.path == Path::new(file))
            .unwrap_or_else(|| panic!("{file} recorded"));
        assert_eq!(
            record.check(&dir),
            None,
            "{file}: the manifest's hash is true"
        );
    }
    // And from then on a plain report agrees with the manifest.
    let (code, _, err) = report(false).await;
    assert_eq!(code, 0, "{err}");
}
