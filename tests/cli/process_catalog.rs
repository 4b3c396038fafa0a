//! `radbench process --from-catalog QUERY` (docs/catalog.md): outputs addressed by content, so a
//! rerun skips what is done, a run SIGKILLed midway then rerun gives the bytes of an
//! uninterrupted run, the outputs are registered back in the catalog, and a bad query is named.

use crate::process_support::{output_within, Spawned};
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::process::{Command, Output};
use std::time::{Duration, Instant};

const BIN: &str = env!("CARGO_BIN_EXE_radbench");
/// Longest any one radbench invocation may take here.
const LIMIT: Duration = Duration::from_secs(120);
/// Captures in the archive.
const CAPTURES: usize = 6;

fn radbench(args: &[&str], cwd: &Path) -> Output {
    output_within(
        Command::new(BIN)
            .args(args)
            .current_dir(cwd)
            .env_remove("RADBENCH_CATALOG"),
        LIMIT,
    )
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

/// An archive of simulated captures in `root/runs`, indexed (each capture registers itself).
fn archive(root: &Path) {
    for k in 0..CAPTURES {
        let out = format!("runs/c{k}");
        let seed = (k + 1).to_string();
        ok(
            &["capture", "--allow-rf", "--seed", &seed, "--out", &out],
            root,
        );
    }
    ok(&["runs", "index", "runs"], root);
}

/// Every file under `dir` (relative path -> bytes).
fn tree(dir: &Path) -> BTreeMap<PathBuf, Vec<u8>> {
    let mut out = BTreeMap::new();
    let mut stack = vec![dir.to_path_buf()];
    while let Some(d) = stack.pop() {
        for e in std::fs::read_dir(&d).unwrap() {
            let p = e.unwrap().path();
            if p.is_dir() {
                stack.push(p);
            } else {
                out.insert(
                    p.strip_prefix(dir).unwrap().to_path_buf(),
                    std::fs::read(&p).unwrap(),
                );
            }
        }
    }
    out
}

fn folders(dir: &Path) -> usize {
    std::fs::read_dir(dir)
        .map(|d| {
            d.filter_map(Result::ok)
                .filter(|e| !e.file_name().to_string_lossy().starts_with('.'))
                .count()
        })
        .unwrap_or(0)
}

fn processed_rows(root: &Path) -> i64 {
    rusqlite::Connection::open(root.join("runs/catalog.sqlite"))
        .and_then(|c| c.query_row("SELECT count(*) FROM processed", [], |r| r.get(0)))
        .unwrap()
}

#[test]
fn a_rerun_skips_a_killed_run_is_finished_bytewise_and_a_bad_query_is_named() {
    let tmp = tempfile::tempdir().unwrap();
    let root = tmp.path();
    archive(root);

    // Uninterrupted, then again: the second does nothing.
    let first = ok(
        &[
            "process",
            "--from-catalog",
            "all",
            "--jobs",
            "2",
            "--out",
            "whole",
        ],
        root,
    );
    assert!(
        first.contains(&format!("processed {CAPTURES}, skipped 0")),
        "{first}"
    );
    let again = ok(
        &[
            "process",
            "--from-catalog",
            "all",
            "--jobs",
            "2",
            "--out",
            "whole",
        ],
        root,
    );
    assert!(
        again.contains(&format!("processed 0, skipped {CAPTURES}")),
        "{again}"
    );
    let whole = tree(&root.join("whole"));
    assert_eq!(folders(&root.join("whole")), CAPTURES);
    // Registered once per output, however often the run is repeated.
    assert_eq!(processed_rows(root), CAPTURES as i64);

    // SIGKILLed once its first output is in place, then run again.
    let killed = root.join("killed");
    let mut child = Spawned::new(
        Command::new(BIN)
            .args(["process", "--from-catalog", "all", "--jobs", "1", "--out"])
            .arg(&killed)
            .current_dir(root)
            .env_remove("RADBENCH_CATALOG")
            .stdout(std::process::Stdio::null())
            .stderr(std::process::Stdio::null()),
    );
    let deadline = Instant::now() + LIMIT;
    while folders(&killed) == 0 && Instant::now() < deadline {
        if child.try_wait().unwrap().is_some() {
            break;
        }
        std::thread::sleep(Duration::from_millis(2));
    }
    let _ = child.kill();
    child.wait_within(LIMIT);
    let before = folders(&killed);
    assert!(before < CAPTURES, "the kill came after the end: {before}");
    let rerun = ok(
        &[
            "process",
            "--from-catalog",
            "all",
            "--jobs",
            "2",
            "--out",
            "killed",
        ],
        root,
    );
    assert!(
        rerun.contains(&format!(
            "processed {}, skipped {before}",
            CAPTURES - before
        )),
        "{rerun}"
    );
    // No half-written folder left, and the bytes of the uninterrupted run.
    assert_eq!(tree(&killed), whole);

    // A selection: the query language of `runs captures`.
    let one = ok(
        &[
            "process",
            "--from-catalog",
            "origin = capture and waveform = ofdm",
            "--out",
            "whole",
        ],
        root,
    );
    assert!(one.starts_with("0 captures"), "{one}");

    // A bad query: its term named, exit 2 (bad input), nothing written.
    for (query, named) in [
        ("wavefrm = ofdm", "wavefrm"),
        ("status = done", "done"),
        ("max_abs_error_m < small", "small"),
    ] {
        let out = radbench(&["process", "--from-catalog", query, "--out", "bad"], root);
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(2), "{query}: {err}");
        assert!(
            err.contains(named) && err.contains("query"),
            "{query}: {err}"
        );
        assert!(!root.join("bad").exists());
    }
}
