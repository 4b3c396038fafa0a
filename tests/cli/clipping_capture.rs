//! A clipped capture is detected and reported (issue 21), end to end on the built-in mock lab:
//! the samples at the scope's ADC rails counted per channel (and per repetition), a warning with
//! what to change, the count in `summary.json` and `--json`, clipping products not taken for
//! targets, and nothing of it when nothing clipped.

use serde_json::Value;
use std::path::Path;

async fn radbench(dir: &Path, args: &[&str]) -> (i32, String, String) {
    crate::support::radbench_in(Some(dir), args).await
}

fn json_file(path: &Path) -> Value {
    serde_json::from_str(&std::fs::read_to_string(path).unwrap()).unwrap()
}

/// A scene of pillars `(range, amplitude)`, noise seed 1.
fn scene(snr_db: f64, pillars: &[(f64, f64)]) -> String {
    let mut s = format!("snr_db = {snr_db}\nseed = 1\n");
    for (r, a) in pillars {
        s += &format!("[[targets]]\nrange_m = {r}\namplitude = {a}\n");
    }
    s
}

/// The issue's scene: three pillars at 0.5, about 8 % of the MSK-LFM capture at the rails.
const ISSUE: [(f64, f64); 3] = [(1.5, 0.5), (2.2, 0.5), (3.1, 0.5)];
/// Two strong pillars clipping hard (28 %) and a weak one 25 dB under them, 1 m from their
/// nearest product (at 5.5 m, which the capture also shows).
const HARD: [(f64, f64); 3] = [(1.5, 0.9), (3.5, 0.9), (6.5, 0.05)];

/// Captures `pillars` with `args`; (stdout JSON, summary.json, capture folder).
async fn capture(
    d: &Path,
    name: &str,
    pillars: &[(f64, f64)],
    args: &[&str],
) -> (Value, Value, std::path::PathBuf) {
    let scene_file = format!("{name}.toml");
    std::fs::write(d.join(&scene_file), scene(25.0, pillars)).unwrap();
    let mut all = vec![
        "capture",
        "--allow-rf",
        "--json",
        "--scene",
        &scene_file,
        "--out",
        name,
    ];
    all.extend_from_slice(args);
    let (code, out, err) = radbench(d, &all).await;
    assert_eq!(code, 0, "{all:?}: {err}");
    let printed: Value = serde_json::from_str(&out).unwrap_or_else(|e| panic!("{e}: {out}"));
    let summary = json_file(&d.join(name).join("summary.json"));
    (printed, summary, d.join(name))
}

/// Every pillar within 1 cm and nothing else.
fn only_the_pillars(v: &Value, pillars: &[(f64, f64)], what: &str) {
    let found: Vec<f64> = v["targets"]
        .as_array()
        .unwrap()
        .iter()
        .map(|t| t["range_m"].as_f64().unwrap())
        .collect();
    assert_eq!(found.len(), pillars.len(), "{what}: {found:?}");
    for (r, _) in pillars {
        assert!(
            found.iter().any(|f| (f - r).abs() < 0.01),
            "{what}: no target within 1 cm of {r} m: {found:?}"
        );
    }
}

/// The keys docs/capture.md's `--json` table of `radbench capture` documents (first column, in
/// backticks).
fn documented_keys() -> Vec<String> {
    let page = Path::new(env!("CARGO_MANIFEST_DIR")).join("docs/capture.md");
    let page = std::fs::read_to_string(page).unwrap();
    let table = page
        .split("**`--json`** prints one object:")
        .nth(1)
        .expect("docs/capture.md has the --json table of capture");
    table
        .trim_start()
        .lines()
        .take_while(|l| l.starts_with('|'))
        .filter_map(|l| l.split('|').nth(1))
        .flat_map(|cell| cell.split('`').skip(1).step_by(2).map(str::to_owned))
        .collect()
}

fn clipping_warnings(v: &Value) -> Vec<String> {
    v["warnings"]
        .as_array()
        .unwrap()
        .iter()
        .filter_map(Value::as_str)
        .filter(|w| w.contains("clipped"))
        .map(str::to_owned)
        .collect()
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn the_issue_scene_is_counted_per_repetition_warned_about_and_finds_three_pillars() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let (printed, summary, folder) = capture(
        d,
        "issue",
        &ISSUE,
        &["--waveform", "msk-lfm", "--repetitions", "2"],
    )
    .await;
    // --json prints what summary.json holds.
    assert_eq!(printed["clipped_samples"], summary["clipped_samples"]);
    let c = &summary["clipped_samples"];
    let (i, q, n) = (
        c["i"].as_u64().unwrap(),
        c["q"].as_u64().unwrap(),
        c["samples"].as_u64().unwrap(),
    );
    // Two repetitions of 800 000 points; about 8 % of each channel at a rail.
    assert_eq!(n, 2 * 800_000, "{c}");
    for (what, k) in [("I", i), ("Q", q)] {
        let f = k as f64 / n as f64;
        assert!((0.05..0.12).contains(&f), "{what}: {k} of {n}");
    }
    assert_eq!(
        c["fraction"].as_f64().unwrap(),
        (i + q) as f64 / (2 * n) as f64
    );
    // Each repetition's own count; together the total.
    let each = summary["each_repetition"].as_array().unwrap();
    assert_eq!(each.len(), 2);
    let per: Vec<(u64, u64, u64)> = each
        .iter()
        .map(|r| {
            let c = &r["clipped_samples"];
            (
                c["i"].as_u64().unwrap(),
                c["q"].as_u64().unwrap(),
                c["samples"].as_u64().unwrap(),
            )
        })
        .collect();
    assert_eq!(per.iter().map(|p| p.0).sum::<u64>(), i);
    assert_eq!(per.iter().map(|p| p.1).sum::<u64>(), q);
    assert!(per.iter().all(|p| p.2 == 800_000 && p.0 > 0), "{per:?}");
    // The warning: how much, per channel, and what to change.
    let warnings = clipping_warnings(&summary);
    assert_eq!(warnings.len(), 1, "{:?}", summary["warnings"]);
    let w = &warnings[0];
    for part in [
        &format!("{i} of {n} I samples"),
        &format!("{q} of {n} Q samples"),
        "I (C1) is at 50 mV/div",
        "Q (C2) is at 50 mV/div",
        "set 100 mV/div",
        "dB of Rx attenuation",
        "Detection was made conservative",
    ] {
        assert!(w.contains(part), "{part:?} not in: {w}");
    }
    assert_eq!(c["conservative_detection"]["floor"], "model", "{c}");
    only_the_pillars(&summary, &ISSUE, "MSK-LFM, clipped");
    // The raw capture says where the rails are and what each repetition had at them.
    let meta = json_file(&folder.join("capture.sigmf-meta"));
    let global = &meta["global"];
    assert_eq!(global["radbench:adc"]["bits"], 8, "{global}");
    assert_eq!(global["radbench:adc"]["volts_per_div"][0], 0.05);
    let reps = global["radbench:repetitions"].as_array().unwrap();
    assert_eq!(reps[0]["clipped_samples"]["i"].as_u64(), Some(per[0].0));
    assert_eq!(reps[1]["clipped_samples"]["q"].as_u64(), Some(per[1].1));

    // OFDM's lower mean power does not reach the rails in the same scene: nothing to report.
    let (_, summary, _) = capture(d, "issue-ofdm", &ISSUE, &["--waveform", "ofdm"]).await;
    let c = &summary["clipped_samples"];
    assert_eq!(
        (c["i"].as_u64(), c["q"].as_u64()),
        (Some(0), Some(0)),
        "{c}"
    );
    assert!(c["conservative_detection"].is_null(), "{c}");
    assert!(clipping_warnings(&summary).is_empty(), "{summary}");
    only_the_pillars(&summary, &ISSUE, "OFDM");
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn hard_clipping_products_are_not_targets_and_process_repeats_it() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let (_, summary, _) = capture(d, "hard", &HARD, &["--waveform", "msk-lfm"]).await;
    let c = &summary["clipped_samples"];
    let f = c["fraction"].as_f64().unwrap();
    assert!((0.2..0.4).contains(&f), "{c}");
    // The product at 5.5 m is fitted, but not reported; the weak pillar is.
    let suppressed = c["conservative_detection"]["suppressed_m"]
        .as_array()
        .unwrap();
    assert!(
        suppressed
            .iter()
            .any(|r| (r.as_f64().unwrap() - 5.5).abs() < 0.02),
        "{c}"
    );
    only_the_pillars(&summary, &HARD, "MSK-LFM, 28 % clipped");
    let w = &clipping_warnings(&summary)[0];
    assert!(w.contains("not reported as target"), "{w}");
    // `process` counts the same samples from the saved words and decides the same.
    let (code, _, err) = radbench(d, &["process", "hard", "--out", "again"]).await;
    assert_eq!(code, 0, "{err}");
    let again = json_file(&d.join("again").join("hard").join("summary.json"));
    assert_eq!(again["clipped_samples"], summary["clipped_samples"]);
    assert_eq!(again["targets"], summary["targets"]);
    assert_eq!(again["warnings"], summary["warnings"]);
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn an_unclipped_capture_reports_zero_and_no_warning() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    // The scene of examples/scene.toml: well inside the rails for both waveforms.
    let readme = [(1.0, 0.5), (1.3, 0.3)];
    for waveform in ["msk-lfm", "ofdm"] {
        let name = format!("plain-{waveform}");
        let (printed, summary, _) = capture(d, &name, &readme, &["--waveform", waveform]).await;
        let c = &summary["clipped_samples"];
        assert_eq!(
            (c["i"].as_u64(), c["q"].as_u64(), c["fraction"].as_f64()),
            (Some(0), Some(0), Some(0.0)),
            "{waveform}: {c}"
        );
        assert!(c["conservative_detection"].is_null());
        assert!(clipping_warnings(&printed).is_empty(), "{printed}");
        // Every key capture prints is documented (docs/capture.md, "--json").
        let documented = documented_keys();
        for key in printed.as_object().unwrap().keys() {
            assert!(
                documented.contains(key),
                "`{key}` of capture --json is not in docs/capture.md's --json table ({documented:?})"
            );
        }
        only_the_pillars(&summary, &readme, waveform);
    }
}
