//! Campaigns over any settings and several axes, end to end on the built-in mock lab: a
//! position x bandwidth spec runs its 6 steps in the documented order (the last table fastest),
//! resumes after SIGKILL at step 4 with results equal to an uninterrupted run's, and its
//! `results.csv` has a column per axis; an AWG-amplitude sweep and a window sweep run and their
//! reports plot the metrics against the swept value; bad names are refused with the table, the
//! key and what is allowed.

use radbench::campaign::{Manifest, Status};
use serde_json::Value;
use std::path::{Path, PathBuf};
use std::process::Stdio;
use tokio::process::Command;

use super::support::{radbench_in, LIMIT};

const BIN: &str = env!("CARGO_BIN_EXE_radbench");

const TWO_AXES: &str = r#"
name = "position-by-bandwidth"
seed = 3

[[sweep]]
parameter = "position"
values = [0.95, 1.0, 1.05]

[[sweep]]
parameter = "bandwidth"
values = [1e9, 2e9]
"#;

fn write_spec(dir: &Path, text: &str) -> PathBuf {
    let p = dir.join("spec.toml");
    std::fs::write(&p, text).unwrap();
    p
}

fn read_json(path: &Path) -> Value {
    let text = std::fs::read_to_string(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    serde_json::from_str(&text).unwrap()
}

async fn run(spec: &Path, out: &Path, extra: &[&str]) -> (i32, String, String) {
    let mut args = vec![
        "campaign",
        "run",
        spec.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
    ];
    args.extend_from_slice(extra);
    radbench_in(None, &args).await
}

/// The header of a CSV file and its rows as column -> text (no quoted commas in these runs).
fn csv(path: &Path) -> (Vec<String>, Vec<Vec<String>>) {
    let text = std::fs::read_to_string(path).unwrap();
    let mut lines = text.lines();
    let header: Vec<String> = lines
        .next()
        .unwrap()
        .split(',')
        .map(str::to_string)
        .collect();
    let rows = lines
        .map(|l| l.split(',').map(str::to_string).collect())
        .collect();
    (header, rows)
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn two_axes_run_in_order_resume_after_sigkill_and_have_a_column_each() {
    let dir = tempfile::tempdir().unwrap();
    let spec = write_spec(dir.path(), TWO_AXES);
    // The plan: 6 steps, the bandwidth (the last table) varying fastest.
    let (code, plan, err) = run(&spec, &dir.path().join("none"), &["--dry-run"]).await;
    assert_eq!(code, 0, "{err}");
    assert!(plan.contains("6 steps"), "{plan}");
    assert!(
        plan.contains("step 2/6: position 0.95 m, bandwidth 2000000000 Hz"),
        "{plan}"
    );
    // The uninterrupted run.
    let whole = dir.path().join("whole");
    let (code, stdout, err) = run(&spec, &whole, &["--allow-rf", "--json"]).await;
    assert_eq!(code, 0, "{err}");
    let steps: Vec<Value> = stdout
        .lines()
        .map(|l| serde_json::from_str::<Value>(l).unwrap())
        .filter(|v| v["event"] == "step")
        .collect();
    assert_eq!(steps.len(), 6, "{stdout}");
    let order = [
        (0.95, 1e9),
        (0.95, 2e9),
        (1.0, 1e9),
        (1.0, 2e9),
        (1.05, 1e9),
        (1.05, 2e9),
    ];
    for (s, (position, bandwidth)) in steps.iter().zip(order) {
        let axes = &s["nominal"]["axes"];
        assert_eq!(axes[0]["name"], "position", "{s}");
        assert_eq!(axes[0]["value"].as_f64(), Some(position), "{s}");
        assert_eq!(axes[1]["name"], "bandwidth", "{s}");
        assert_eq!(axes[1]["value"].as_f64(), Some(bandwidth), "{s}");
        assert_eq!(s["nominal"]["bandwidth_hz"].as_f64(), Some(bandwidth));
        assert_eq!(
            s["nominal"]["targets"][0]["range_m"].as_f64(),
            Some(position)
        );
    }
    let (header, rows) = csv(&whole.join("results.csv"));
    let col = |name: &str| {
        header
            .iter()
            .position(|h| h == name)
            .unwrap_or_else(|| panic!("no {name} in {header:?}"))
    };
    let (p, b) = (col("swept_position"), col("swept_bandwidth"));
    assert_eq!(rows.len(), 6);
    for (row, (position, bandwidth)) in rows.iter().zip(order) {
        assert_eq!(row[p].parse::<f64>().unwrap(), position);
        assert_eq!(row[b].parse::<f64>().unwrap(), bandwidth);
    }
    // The report plots each metric against the bandwidth, a line per position.
    let html = std::fs::read_to_string(whole.join("report.html")).unwrap();
    assert!(html.contains("id=\"sweep-error\""));
    assert!(html.contains("position 0.95"), "a line per outer value");

    // The same run killed (SIGKILL: no chance to record anything) as step 4 starts, resumed.
    let killed = dir.path().join("killed");
    let (mut child, _lines) = super::support::campaign_at_step(&spec, &killed, 4).await;
    child.start_kill().unwrap();
    tokio::time::timeout(LIMIT, child.wait())
        .await
        .expect("killed")
        .unwrap();
    // Nothing recorded the stop: the manifest reads as a run that was cut short.
    assert_ne!(Manifest::load(&killed).unwrap().status, Status::Complete);
    let (code, _, err) = radbench_in(
        None,
        &["campaign", "resume", killed.to_str().unwrap(), "--allow-rf"],
    )
    .await;
    assert_eq!(code, 0, "{err}");
    assert_eq!(Manifest::load(&killed).unwrap().status, Status::Complete);
    assert_eq!(
        read_json(&killed.join("results.json")),
        read_json(&whole.join("results.json"))
    );
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn an_awg_amplitude_sweep_sets_the_awg_and_reports_against_it() {
    let dir = tempfile::tempdir().unwrap();
    let spec = write_spec(
        dir.path(),
        "[sweep]\nparameter = \"awg-amplitude\"\nvalues = [0.2, 0.4]\ntargets = [1.0]\n",
    );
    let out = dir.path().join("run");
    let (code, _, err) = run(&spec, &out, &["--allow-rf"]).await;
    assert_eq!(code, 0, "{err}");
    // Each step configured the AWG at its amplitude.
    let journal = std::fs::read_to_string(out.join("io-journal.jsonl")).unwrap();
    let first = journal.find(":VOLT1 0.2").expect("the AWG set to 0.2 Vpp");
    assert!(journal[first..].contains(":VOLT1 0.4"), "then to 0.4 Vpp");
    let (header, rows) = csv(&out.join("results.csv"));
    let a = header
        .iter()
        .position(|h| h == "swept_awg_amplitude")
        .unwrap();
    assert_eq!(rows[1][a], "0.4");
    let html = std::fs::read_to_string(out.join("report.html")).unwrap();
    assert!(html.contains("id=\"sweep-error\""));
    assert!(html.contains("awg-amplitude (Vpp)"));
    let md = std::fs::read_to_string(out.join("report.md")).unwrap();
    assert!(md.contains("Range error against awg-amplitude"), "{md}");
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_window_sweep_processes_each_step_with_its_window() {
    let dir = tempfile::tempdir().unwrap();
    let spec = write_spec(
        dir.path(),
        "[sweep]\nparameter = \"window\"\nvalues = [\"rect\", \"hann\"]\ntargets = [1.0]\n",
    );
    let out = dir.path().join("run");
    let (code, _, err) = run(&spec, &out, &["--allow-rf"]).await;
    assert_eq!(code, 0, "{err}");
    let results = read_json(&out.join("results.json"));
    let psl = |k: usize| {
        results["steps"][k]["algorithms"]["correlation"]["sidelobe_db"]
            .as_f64()
            .unwrap()
    };
    // Hann's side-lobes sit far below the rectangular window's -13 dB.
    assert!(psl(1) < psl(0) - 10.0, "rect {} hann {}", psl(0), psl(1));
    let summary = read_json(&out.join("step-002/summary.json"));
    assert_eq!(summary["processing"]["window"], "hann", "{summary}");
    let html = std::fs::read_to_string(out.join("report.html")).unwrap();
    assert!(html.contains("id=\"sweep-psl\""));
    assert!(html.contains("Peak side-lobe level against window"));
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn bad_settings_name_the_table_the_key_and_what_is_allowed() {
    let dir = tempfile::tempdir().unwrap();
    let cases = [
        (
            "[[sweep]]\nparameter = \"position\"\nvalues = [1.0]\n[[sweep]]\nparameter = \"height\"\nvalues = [1]\n",
            "`sweep[1].parameter`",
            "awg-amplitude",
        ),
        (
            "[sweep]\nparameter = \"window\"\nvalues = [\"hann\", \"box\"]\n",
            "`sweep.values[1]`",
            "\"taylor\"",
        ),
        (
            "[sweep]\nparameter = \"window\"\nstart = 1\nstep = 1\ncount = 2\n",
            "`sweep`",
            "values = [\"rect\"",
        ),
        (
            "[sweep]\nparameter = \"awg-amplitude\"\nvalues = [0.3, 9.0]\n",
            "`sweep.values`",
            "Vpp",
        ),
        (
            "[[steps]]\ntargets = [1.0]\nawg-amplitud = 0.3\n",
            "`steps[0].awg-amplitud`",
            "awg-amplitude",
        ),
        (
            "[[steps]]\ntargets = [1.0]\nrepetitions = 0\n",
            "`steps[0].repetitions`",
            "1..=",
        ),
    ];
    for (text, field, allowed) in cases {
        let spec = write_spec(dir.path(), text);
        let (code, _, err) = run(&spec, &dir.path().join("none"), &["--dry-run"]).await;
        assert_eq!(code, 2, "{text}: {err}");
        assert!(err.contains(field), "{text}: {err}");
        assert!(err.contains(allowed), "{text}: {err}");
    }
}

/// Runs radbench with `args` and the environment `env`; (exit code, stdout, stderr), bounded.
async fn radbench_env(args: &[&str], env: &[(&str, &str)]) -> (i32, String, String) {
    let mut command = Command::new(BIN);
    command
        .args(args)
        .envs(env.iter().copied())
        .stdin(Stdio::null())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .kill_on_drop(true);
    let out = tokio::time::timeout(LIMIT, command.output())
        .await
        .expect("radbench finishes in time")
        .unwrap();
    (
        out.status.code().unwrap_or(-1),
        String::from_utf8_lossy(&out.stdout).into_owned(),
        String::from_utf8_lossy(&out.stderr).into_owned(),
    )
}

/// Bytes of every file under `dir`.
fn bytes_under(dir: &Path) -> u64 {
    std::fs::read_dir(dir)
        .unwrap()
        .map(|e| {
            let e = e.unwrap();
            let meta = e.metadata().unwrap();
            if meta.is_dir() {
                bytes_under(&e.path())
            } else {
                meta.len()
            }
        })
        .sum()
}

const THREE_STEPS: &str = "[sweep]\nparameter = \"position\"\nvalues = [0.9, 1.0, 1.1]\n";

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn the_dry_runs_disk_estimate_is_within_20_percent_default_and_thinned() {
    let dir = tempfile::tempdir().unwrap();
    for (name, output) in [
        ("default", ""),
        ("with-trc", "\n[output]\nkeep_trc = true\n"),
        ("night", "\n[output]\nkeep_bitmaps = false\n"),
        (
            "thinned",
            "\n[output]\nkeep_trc = false\nkeep_bitmaps = false\nkeep_link_plots = false\n",
        ),
    ] {
        let spec = write_spec(dir.path(), &format!("{THREE_STEPS}{output}"));
        let out = dir.path().join(name);
        let (code, plan, err) = run(&spec, &out, &["--dry-run", "--json"]).await;
        assert_eq!(code, 0, "{err}");
        let plan: Value = serde_json::from_str(plan.trim()).unwrap();
        let estimate = plan["estimate_bytes"].as_u64().unwrap() as f64;
        let (code, _, err) = run(&spec, &out, &["--allow-rf"]).await;
        assert_eq!(code, 0, "{err}");
        let written = bytes_under(&out) as f64;
        let off = (estimate - written).abs() / written;
        assert!(
            off < 0.2,
            "{name}: estimated {estimate} B, wrote {written} B ({:.0} % off)",
            off * 100.0
        );
        let step = out.join("step-001");
        assert_eq!(step.join("C1.trc").exists(), name == "with-trc", "{name}");
        assert_eq!(
            step.join("profile.png").exists(),
            matches!(name, "default" | "with-trc")
        );
        assert_eq!(step.join("link.svg").exists(), name != "thinned");
        assert!(step.join("capture.sigmf-data").exists());
        std::fs::remove_dir_all(&out).unwrap();
    }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_full_filesystem_is_refused_before_rf_and_a_tight_one_warned() {
    let dir = tempfile::tempdir().unwrap();
    let spec = write_spec(dir.path(), THREE_STEPS);
    let out = dir.path().join("run");
    let args = [
        "campaign",
        "run",
        spec.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
        "--allow-rf",
    ];
    let (code, _, err) = radbench_env(&args, &[("RADBENCH_TEST_FREE_BYTES", "1000000")]).await;
    assert_ne!(code, 0, "{err}");
    assert!(err.contains("1.0 MB free"), "{err}");
    assert!(
        err.contains("needs about") && err.contains("for its 3 steps"),
        "{err}"
    );
    // Refused before anything was created, connected or switched on.
    assert!(!out.exists(), "{err}");
    // Enough, but less than the margin to spare: a warning, and the run goes on.
    let (code, plan, _) = radbench_in(
        None,
        &[
            "campaign",
            "run",
            spec.to_str().unwrap(),
            "--dry-run",
            "--json",
        ],
    )
    .await;
    assert_eq!(code, 0);
    let plan: Value = serde_json::from_str(plan.trim()).unwrap();
    let tight = (plan["estimate_bytes"].as_u64().unwrap() * 2).to_string();
    let (code, _, err) = radbench_env(&args, &[("RADBENCH_TEST_FREE_BYTES", &tight)]).await;
    assert_eq!(code, 0, "{err}");
    assert!(
        err.contains("warning:") && err.contains("to spare"),
        "{err}"
    );
}
