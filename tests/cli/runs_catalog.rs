//! The run catalog (`radbench runs`, docs/catalog.md) end to end: an index is idempotent and a
//! SIGKILL in the middle of one loses nothing the next index does not restore; a campaign with
//! the catalog locked by another process or damaged completes with the same results, and the
//! next index fixes the catalog; queries give what walking the folders gives.

use crate::process_support::{output_within, Spawned};
use radbench::campaign::{Manifest, Results};
use std::path::{Path, PathBuf};
use std::process::{Command, Output};
use std::time::{Duration, Instant};

#[path = "../support/runs_archive.rs"]
mod runs_archive;

const BIN: &str = env!("CARGO_BIN_EXE_radbench");
/// Longest any one radbench invocation may take here.
const LIMIT: Duration = Duration::from_secs(120);

fn radbench(args: &[&str], cwd: &Path) -> Output {
    let out = output_within(
        Command::new(BIN)
            .args(args)
            .current_dir(cwd)
            .env_remove("RADBENCH_CATALOG"),
        LIMIT,
    );
    out
}

fn ok(args: &[&str], cwd: &Path) -> String {
    let out = radbench(args, cwd);
    assert!(
        out.status.success(),
        "radbench {args:?}: {}\n{}",
        String::from_utf8_lossy(&out.stderr),
        String::from_utf8_lossy(&out.stdout)
    );
    String::from_utf8(out.stdout).unwrap()
}

/// Every row of every table, as text, in a fixed order (the catalog's whole content).
fn dump(catalog: &Path) -> Vec<String> {
    let conn = rusqlite::Connection::open(catalog).unwrap();
    let mut rows = Vec::new();
    for table in [
        "runs",
        "run_metrics",
        "steps",
        "captures",
        "targets",
        "calibrations",
        "instruments",
        "assets",
    ] {
        let mut q = conn.prepare(&format!("SELECT * FROM {table}")).unwrap();
        let n = q.column_count();
        let mut table_rows: Vec<String> = q
            .query_map([], |r| {
                let mut line = format!("{table}:");
                for k in 0..n {
                    let v: rusqlite::types::Value = r.get(k)?;
                    line.push_str(&format!("{v:?}|"));
                }
                Ok(line)
            })
            .unwrap()
            .map(Result::unwrap)
            .collect();
        table_rows.sort();
        rows.extend(table_rows);
    }
    rows
}

fn count_runs(catalog: &Path) -> i64 {
    rusqlite::Connection::open(catalog)
        .and_then(|c| c.query_row("SELECT count(*) FROM runs", [], |r| r.get(0)))
        .unwrap_or(0)
}

#[test]
fn indexing_twice_gives_the_same_rows_as_indexing_once() {
    let tmp = tempfile::tempdir().unwrap();
    let archive = tmp.path().join("archive");
    runs_archive::write_archive(&archive, 40, 7);
    let catalog = tmp.path().join("catalog.sqlite");
    let c = catalog.to_str().unwrap();
    let a = archive.to_str().unwrap();
    let first = ok(&["runs", "--catalog", c, "index", a, "--json"], tmp.path());
    let report: serde_json::Value = serde_json::from_str(&first).unwrap();
    assert_eq!(report["runs_written"], 40, "{first}");
    let once = dump(&catalog);
    let second = ok(&["runs", "--catalog", c, "index", a, "--json"], tmp.path());
    let report: serde_json::Value = serde_json::from_str(&second).unwrap();
    assert_eq!(
        (&report["runs_written"], &report["runs_unchanged"]),
        (&0.into(), &40.into())
    );
    assert_eq!(dump(&catalog), once);
    // A run folder removed: its rows go; written back: the same rows as before.
    let moved = tmp.path().join("moved-away");
    std::fs::rename(archive.join("run-00003"), &moved).unwrap();
    ok(&["runs", "--catalog", c, "index", a], tmp.path());
    assert_eq!(count_runs(&catalog), 39);
    std::fs::rename(&moved, archive.join("run-00003")).unwrap();
    ok(&["runs", "--catalog", c, "index", a], tmp.path());
    assert_eq!(dump(&catalog), once);
}

#[test]
fn an_index_killed_midway_is_finished_by_the_next_one() {
    let tmp = tempfile::tempdir().unwrap();
    let archive = tmp.path().join("archive");
    runs_archive::write_archive(&archive, 600, 11);
    let a = archive.to_str().unwrap();
    let reference = tmp.path().join("reference.sqlite");
    ok(
        &["runs", "--catalog", reference.to_str().unwrap(), "index", a],
        tmp.path(),
    );
    let catalog = tmp.path().join("catalog.sqlite");
    let c = catalog.to_str().unwrap();
    let mut child = Spawned::new(
        Command::new(BIN)
            .args(["runs", "--catalog", c, "index", a])
            .current_dir(tmp.path())
            .stdout(std::process::Stdio::null())
            .stderr(std::process::Stdio::null()),
    );
    // Killed once some runs are committed (or, on a fast machine, whenever it got to).
    let deadline = Instant::now() + LIMIT;
    while count_runs(&catalog) == 0 && Instant::now() < deadline {
        if child.try_wait().unwrap().is_some() {
            break;
        }
        std::thread::sleep(Duration::from_millis(2));
    }
    let _ = child.kill();
    child.wait_within(LIMIT);
    let partial = count_runs(&catalog);
    assert!(partial <= 600, "{partial}");
    ok(&["runs", "--catalog", c, "index", a], tmp.path());
    assert_eq!(dump(&catalog), dump(&reference));
}

/// A campaign of the accuracy example into `runs/NAME` under `root`, its `results.json`.
fn campaign(root: &Path, name: &str) -> (Output, Vec<u8>) {
    let spec = Path::new(env!("CARGO_MANIFEST_DIR")).join("examples/accuracy.toml");
    let out = root.join("runs").join(name);
    let output = radbench(
        &[
            "campaign",
            "run",
            spec.to_str().unwrap(),
            "--allow-rf",
            "--out",
            out.to_str().unwrap(),
        ],
        root,
    );
    assert!(
        output.status.success(),
        "{}",
        String::from_utf8_lossy(&output.stderr)
    );
    let results = std::fs::read(out.join("results.json")).unwrap();
    (output, results)
}

#[test]
fn a_campaign_with_a_locked_or_damaged_catalog_completes_and_the_next_index_fixes_it() {
    let tmp = tempfile::tempdir().unwrap();
    let root = tmp.path();
    // Registered as it runs: the catalog beside the run folder holds it with no index.
    let (_, reference) = campaign(root, "reference");
    let catalog = root.join("runs/catalog.sqlite");
    assert_eq!(count_runs(&catalog), 1);

    // Locked: another process holds a write transaction open for the whole campaign.
    let holder = rusqlite::Connection::open(&catalog).unwrap();
    holder
        .execute_batch("BEGIN IMMEDIATE; DELETE FROM meta WHERE key = 'nothing';")
        .unwrap();
    let (output, results) = campaign(root, "locked");
    assert_eq!(
        results, reference,
        "the same results with the catalog locked"
    );
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert!(
        stderr.contains("run catalog") && stderr.contains("runs index"),
        "{stderr}"
    );
    holder.execute_batch("ROLLBACK").unwrap();
    drop(holder);
    assert_eq!(count_runs(&catalog), 1, "the locked run was not registered");

    // Damaged: not a database at all.
    std::fs::write(&catalog, vec![0x5a; 8192]).unwrap();
    for side in ["catalog.sqlite-wal", "catalog.sqlite-shm"] {
        let _ = std::fs::remove_file(root.join("runs").join(side));
    }
    let (output, results) = campaign(root, "damaged");
    assert_eq!(
        results, reference,
        "the same results with the catalog damaged"
    );
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert!(stderr.contains("runs index"), "{stderr}");

    // The next index sets the damaged file aside and holds all three runs.
    let report = ok(&["runs", "index", "--json"], root);
    let report: serde_json::Value = serde_json::from_str(&report).unwrap();
    assert_eq!(report["runs_written"], 3, "{report}");
    assert!(report["set_aside"].is_string(), "{report}");
    assert_eq!(count_runs(&catalog), 3);
    let listed = ok(&["runs", "list", "--json"], root);
    let listed: Vec<serde_json::Value> = serde_json::from_str(&listed).unwrap();
    assert!(
        listed.iter().all(|r| r["status"] == "complete"),
        "{listed:?}"
    );
}

#[test]
fn a_campaign_whose_catalog_cannot_be_written_completes_and_the_next_index_fixes_it() {
    let tmp = tempfile::tempdir().unwrap();
    let root = tmp.path();
    let (_, reference) = campaign(root, "reference");
    // A catalog nothing can be written to, as on a full or read-only disk: its folder is a
    // file (root may write anywhere else).
    let blocked = root.join("not-a-folder");
    std::fs::write(&blocked, b"").unwrap();
    let spec = Path::new(env!("CARGO_MANIFEST_DIR")).join("examples/accuracy.toml");
    let out = root.join("runs/unwritable");
    let output = output_within(
        Command::new(BIN)
            .args([
                "campaign",
                "run",
                spec.to_str().unwrap(),
                "--allow-rf",
                "--out",
            ])
            .arg(&out)
            .current_dir(root)
            .env("RADBENCH_CATALOG", blocked.join("catalog.sqlite")),
        LIMIT,
    );
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert!(output.status.success(), "{stderr}");
    assert_eq!(
        std::fs::read(out.join("results.json")).unwrap(),
        reference,
        "the same results with the catalog unwritable"
    );
    assert!(
        stderr.contains("run catalog") && stderr.contains("runs index"),
        "{stderr}"
    );
    // The next index of the runs folder holds both runs.
    ok(&["runs", "index"], root);
    assert_eq!(count_runs(&root.join("runs/catalog.sqlite")), 2);
}

/// A run folder, as the test reads it without the catalog.
struct Walked {
    run_id: String,
    manifest: Manifest,
    max_abs_error_m: Option<f64>,
}

fn walk(archive: &Path) -> Vec<Walked> {
    let mut dirs: Vec<PathBuf> = std::fs::read_dir(archive)
        .unwrap()
        .map(|e| e.unwrap().path())
        .collect();
    dirs.sort();
    dirs.iter()
        .map(|d| {
            let manifest = Manifest::load(d).unwrap();
            let results: Results =
                serde_json::from_slice(&std::fs::read(d.join("results.json")).unwrap()).unwrap();
            let max_abs_error_m = results
                .steps
                .iter()
                .flat_map(|s| s.algorithms.values())
                .filter_map(|a| a.error_m)
                .map(f64::abs)
                .reduce(f64::max);
            Walked {
                run_id: radbench::runs_db::run_id(&manifest),
                manifest,
                max_abs_error_m,
            }
        })
        .collect()
}

/// Which runs a query should give, from the folders.
type Keep = Box<dyn Fn(&Walked) -> bool>;

fn queried(catalog: &str, args: &[&str], cwd: &Path) -> Vec<String> {
    let mut all = vec!["runs", "--catalog", catalog, "query", "--json"];
    all.extend_from_slice(args);
    let text = ok(&all, cwd);
    let rows: Vec<serde_json::Value> = serde_json::from_str(&text).unwrap();
    let mut ids: Vec<String> = rows
        .iter()
        .map(|r| r["run_id"].as_str().unwrap().to_string())
        .collect();
    ids.sort();
    ids
}

fn expected(walked: &[Walked], keep: impl Fn(&Walked) -> bool) -> Vec<String> {
    let mut ids: Vec<String> = walked
        .iter()
        .filter(|w| keep(w))
        .map(|w| w.run_id.clone())
        .collect();
    ids.sort();
    ids
}

#[test]
fn queries_give_what_walking_the_folders_gives() {
    let tmp = tempfile::tempdir().unwrap();
    let archive = tmp.path().join("archive");
    runs_archive::write_archive(&archive, 120, 3);
    let catalog = tmp.path().join("catalog.sqlite");
    let c = catalog.to_str().unwrap();
    ok(
        &["runs", "--catalog", c, "index", archive.to_str().unwrap()],
        tmp.path(),
    );
    let walked = walk(&archive);
    let cwd = tmp.path();
    let scope_has = |w: &Walked, text: &str| {
        w.manifest
            .instruments
            .as_ref()
            .is_some_and(|i| i.scope.to_lowercase().contains(text))
    };
    let cases: Vec<(Vec<&str>, Keep)> = vec![
        (vec![], Box::new(|_| true)),
        (
            vec!["--kind", "accuracy"],
            Box::new(|w| w.manifest.plan.name == "accuracy"),
        ),
        (
            vec!["--kind", "bandwidth"],
            Box::new(|w| w.manifest.plan.name == "resolution"),
        ),
        (
            vec!["--since", "2026-03-01", "--until", "2026-06-15T12:00:00Z"],
            Box::new(|w| {
                w.manifest.created.as_str() >= "2026-03-01T00:00:00"
                    && w.manifest.created.as_str() < "2026-06-15T12:00:00"
            }),
        ),
        (
            vec!["--scope", "uxr"],
            Box::new(move |w| scope_has(w, "uxr")),
        ),
        (
            vec!["--calibration", "aa11"],
            Box::new(|w| {
                w.manifest
                    .calibration
                    .as_ref()
                    .is_some_and(|c| c.sha256.starts_with("aa11"))
            }),
        ),
        (
            vec!["--calibration", "none"],
            Box::new(|w| w.manifest.calibration.is_none()),
        ),
        (
            vec!["--status", "interrupted"],
            Box::new(|w| w.manifest.status.name() == "interrupted"),
        ),
        (
            vec!["--where", "max_abs_error_m < 1e-3"],
            Box::new(|w| w.max_abs_error_m.is_some_and(|e| e < 1e-3)),
        ),
        (
            vec![
                "--kind",
                "accuracy",
                "--scope",
                "LabMaster",
                "--where",
                "max_abs_error_m >= 2e-4 and steps = 4",
            ],
            Box::new(move |w| {
                w.manifest.plan.name == "accuracy"
                    && scope_has(w, "labmaster")
                    && w.max_abs_error_m.is_some_and(|e| e >= 2e-4)
                    && w.manifest
                        .steps
                        .iter()
                        .filter(|s| s.status == radbench::campaign::StepStatus::Done)
                        .count()
                        == 4
            }),
        ),
    ];
    for (args, keep) in cases {
        let want = expected(&walked, keep);
        assert_eq!(queried(c, &args, cwd), want, "runs query {args:?}");
    }
    // Most cases select something and not everything (the archive is varied enough to tell).
    assert!(expected(&walked, |w| w.max_abs_error_m.is_some_and(|e| e < 1e-3)).len() > 5);

    // CSV: a header and one line per run; trend: one point per run of the kind, oldest first.
    let csv = ok(
        &[
            "runs",
            "--catalog",
            c,
            "query",
            "--csv",
            "--kind",
            "accuracy",
        ],
        cwd,
    );
    let accuracy = expected(&walked, |w| w.manifest.plan.name == "accuracy").len();
    assert_eq!(csv.lines().count(), accuracy + 1, "{csv}");
    assert!(csv.lines().next().unwrap().contains("max_abs_error_m"));
    let plot = tmp.path().join("trend.svg");
    let trend = ok(
        &[
            "runs",
            "--catalog",
            c,
            "trend",
            "accuracy",
            "max_abs_error_m",
            "--json",
            "--plot",
            plot.to_str().unwrap(),
        ],
        cwd,
    );
    let points: Vec<serde_json::Value> = serde_json::from_str(&trend).unwrap();
    assert_eq!(points.len(), accuracy);
    let created: Vec<&str> = points
        .iter()
        .map(|p| p["created"].as_str().unwrap())
        .collect();
    assert!(created.windows(2).all(|w| w[0] <= w[1]));
    assert!(std::fs::read_to_string(&plot).unwrap().contains("<svg"));
    // A run shown by a prefix of its id.
    let one = &walked[0].run_id;
    let shown = ok(&["runs", "--catalog", c, "show", &one[..8], "--json"], cwd);
    let shown: serde_json::Value = serde_json::from_str(&shown).unwrap();
    assert_eq!(shown["run"]["run_id"], one.as_str());

    // Bad input names the field and what is allowed.
    for (args, field) in [
        (
            vec!["query", "--where", "max_abs_error_m < 1; DROP TABLE runs"],
            "--where",
        ),
        (vec!["query", "--since", "last week"], "--since"),
        (vec!["query", "--status", "done"], "--status"),
        (vec!["show", "ffffffffffffffff"], "RUN"),
    ] {
        let mut all = vec!["runs", "--catalog", c];
        all.extend_from_slice(&args);
        let out = radbench(&all, cwd);
        assert_eq!(out.status.code(), Some(2), "{args:?}");
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert!(stderr.contains(field), "{args:?}: {stderr}");
    }
    assert_eq!(count_runs(&catalog), 120, "nothing was dropped");
}

#[test]
fn capture_and_process_register_what_an_index_of_their_folders_gives() {
    let tmp = tempfile::tempdir().unwrap();
    let root = tmp.path();
    ok(&["capture", "--allow-rf", "--out", "runs/capture"], root);
    ok(
        &["process", "runs/capture", "--out", "runs/processed"],
        root,
    );
    let catalog = root.join("runs/catalog.sqlite");
    let registered = dump(&catalog);
    let listed = ok(&["runs", "captures", "--json"], root);
    let listed: Vec<serde_json::Value> = serde_json::from_str(&listed).unwrap();
    let mut origins: Vec<&str> = listed
        .iter()
        .map(|c| c["origin"].as_str().unwrap())
        .collect();
    origins.sort();
    assert_eq!(origins, ["capture", "process"], "{listed:?}");
    assert!(registered.iter().any(|r| r.starts_with("assets:")));
    // Rebuilt from the folders alone: the same rows.
    std::fs::remove_file(&catalog).unwrap();
    for side in ["catalog.sqlite-wal", "catalog.sqlite-shm"] {
        let _ = std::fs::remove_file(root.join("runs").join(side));
    }
    let report = ok(&["runs", "index", "--json"], root);
    assert!(report.contains("\"failed\":[]"), "{report}");
    assert_eq!(dump(&catalog), registered);
}
