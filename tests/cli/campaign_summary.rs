//! A report that leads with the answer, on the built-in mock lab: `report.md` and `report.html`
//! open with the summary (pass/fail, worst error, false targets, operator, the instruments'
//! `*IDN?`) before the steps table and before the first figure; a false target (a static
//! reflector no step names) is a marked cell of the steps table; `report.md`'s images are PNG
//! files of the run folder linked by relative path; past 24 steps the profiles are a heat map.

use radbench::campaign::Manifest;
use std::path::Path;
use std::process::Stdio;
use tokio::process::Command;

use super::support::{radbench_in, LIMIT};

const BIN: &str = env!("CARGO_BIN_EXE_radbench");

/// The `](path)` targets of report.md's images.
fn image_links(md: &str) -> Vec<String> {
    md.match_indices("![")
        .filter_map(|(at, _)| {
            let rest = &md[at..];
            let open = rest.find("](")? + 2;
            let close = rest[open..].find(')')? + open;
            Some(rest[open..close].to_string())
        })
        .collect()
}

/// Every image of report.md is a PNG file of the run folder, linked by a relative path.
fn check_images(dir: &Path, md: &str) -> Vec<String> {
    let links = image_links(md);
    assert!(!links.is_empty(), "report.md embeds its figures");
    for l in &links {
        assert!(
            !l.starts_with('/') && !l.contains("..") && !l.contains(':'),
            "{l} is relative, inside the run folder"
        );
        let bytes = std::fs::read(dir.join(l)).unwrap_or_else(|e| panic!("{l}: {e}"));
        assert!(bytes.starts_with(b"\x89PNG\r\n\x1a\n"), "{l} is a PNG");
    }
    links
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn the_report_leads_with_the_answer_and_marks_a_false_target() {
    let tmp = tempfile::tempdir().unwrap();
    let d = tmp.path();
    // A table edge at 1.6 m: a static reflector every step sees and none names.
    std::fs::write(
        d.join("lab.toml"),
        "snr_db = 30.0\n[[targets]]\nrange_m = 1.0\namplitude = 0.5\n\
         [[clutter]]\nrange_m = 1.6\namplitude = 0.3\n",
    )
    .unwrap();
    std::fs::write(
        d.join("spec.toml"),
        "name = \"table edge\"\n[run]\noperator = \"A. Tester\"\n[bench]\nscene = \"lab.toml\"\n\
         [sweep]\nparameter = \"position\"\nvalues = [1.0, 1.05]\n",
    )
    .unwrap();
    let (code, _, err) = radbench_in(
        Some(d),
        &["campaign", "run", "spec.toml", "--allow-rf", "--out", "run"],
    )
    .await;
    assert_eq!(code, 0, "{err}");
    let dir = d.join("run");
    let manifest = Manifest::load(&dir).unwrap();
    assert_eq!(manifest.operator.as_deref(), Some("A. Tester"));
    let idn = manifest
        .instruments
        .clone()
        .expect("the instruments' *IDN?");
    let md = std::fs::read_to_string(dir.join("report.md")).unwrap();
    let html = std::fs::read_to_string(dir.join("report.html")).unwrap();

    // report.md: the summary, then the steps, then the figures.
    let summary = md.find("## Summary").expect("a summary");
    let steps = md.find("## Steps").expect("a steps table");
    let figure = md.find("![").expect("a figure");
    assert!(summary < steps && steps < figure, "{md}");
    let head = &md[summary..steps];
    assert!(head.contains("**PASS: "), "{head}");
    for fact in [
        "| Operator | A. Tester |",
        "Worst error",
        "| Date | ",
        "| Duration | ",
        "| Retries | none |",
        "Calibrations",
    ] {
        assert!(head.contains(fact), "{fact}: {head}");
    }
    for line in [&idn.awg, &idn.scope] {
        assert!(head.contains(line.as_str()), "{line}: {head}");
    }
    assert!(head.contains(idn.tx.as_deref().unwrap()), "{head}");
    assert!(
        head.contains("| **False targets** | **⚠ 2: step 1 correlation at 1.6"),
        "{head}"
    );
    // The steps table marks the cell, not just lists another range.
    let rows: Vec<&str> = md[steps..figure]
        .lines()
        .filter(|l| l.starts_with("| 1 |") || l.starts_with("| 2 |"))
        .collect();
    assert_eq!(rows.len(), 2, "{md}");
    for r in rows {
        assert!(r.contains("| **⚠ FALSE TARGET 1.6"), "{r}");
    }
    check_images(&dir, &md);

    // report.html: the same order, the false target a marked cell.
    let summary = html.find("<section id=\"summary\">").expect("a summary");
    let steps = html.find("<h2>Steps</h2>").expect("a steps table");
    let figure = html.find("<figure").expect("a figure");
    assert!(summary < steps && steps < figure);
    let head = &html[summary..steps];
    assert!(head.contains("<p class=\"verdict pass\">PASS: "), "{head}");
    assert!(
        head.contains("<th>Operator</th><td>A. Tester</td>"),
        "{head}"
    );
    assert!(
        head.contains(&idn.awg) && head.contains(&idn.scope),
        "{head}"
    );
    assert!(head.contains("<tr class=\"alarm\"><th>False targets</th>"));
    assert_eq!(
        html[steps..figure]
            .matches("<td class=\"false-target\">⚠ FALSE TARGET 1.6")
            .count(),
        2
    );
}

/// 30 steps: the profiles are a heat map with its colour bar (not 30 stacked rows), in both
/// reports; without `[run] operator` the report names the environment's user.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn thirty_steps_draw_a_heat_map_and_the_user_is_the_operator() {
    let tmp = tempfile::tempdir().unwrap();
    let d = tmp.path();
    std::fs::write(
        d.join("spec.toml"),
        "name = \"thirty\"\n[sweep]\nparameter = \"position\"\nstart = 0.8\nstep = 0.02\n\
         count = 30\n",
    )
    .unwrap();
    let child = Command::new(BIN)
        .args(["campaign", "run", "spec.toml", "--allow-rf", "--out", "run"])
        .current_dir(d)
        .env("USER", "night-shift")
        .env_remove("LOGNAME")
        .stdin(Stdio::null())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .kill_on_drop(true)
        .spawn()
        .unwrap();
    let out = tokio::time::timeout(LIMIT, child.wait_with_output())
        .await
        .expect("the run ends in time")
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let dir = d.join("run");
    let md = std::fs::read_to_string(dir.join("report.md")).unwrap();
    let html = std::fs::read_to_string(dir.join("report.html")).unwrap();
    assert!(md.contains("| Operator | night-shift |"), "{md}");
    let links = check_images(&dir, &md);
    assert!(
        links.contains(&"figures/step-heatmap.png".to_string()),
        "{links:?}"
    );
    assert!(
        !links.iter().any(|l| l.contains("step-profiles")),
        "{links:?}"
    );
    assert!(html.contains("<figure id=\"step-heatmap\" class=\"heatmap\">"));
    assert!(html.contains("<img src=\"data:image/png;base64,iVBORw0KGgo"));
    assert!(!html.contains("id=\"step-profiles\""));
    // The summary still comes before it.
    assert!(html.find("id=\"summary\"").unwrap() < html.find("<figure").unwrap());
}
