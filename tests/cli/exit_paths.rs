//! Every exit path leaves the bench safe and never a partial file: SIGINT, SIGTERM and SIGHUP sent
//! to `radbench capture` while RF is on, while the scope's data is being fetched and while the
//! files are written, with the emulators' RF state read back afterwards; a stalled scope
//! switches RF off within the capture's deadline; and a module power-cycled during the capture
//! is an error (exit 3), not a capture without echo.

use std::path::{Path, PathBuf};
use std::process::Stdio;
use std::sync::atomic::Ordering;
use std::time::Duration;
use tokio::process::{Child, Command};

const BIN: &str = env!("CARGO_BIN_EXE_radbench");

use crate::support::{lab_bench_file as bench_file, start_lab as start};

fn capture(bench: &str, out: &Path, extra: &[&str]) -> Child {
    Command::new(BIN)
        .args(["capture", "--allow-rf", "--bench", bench])
        .arg("--out")
        .arg(out)
        .args(extra)
        .stdin(Stdio::null())
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .kill_on_drop(true)
        .spawn()
        .unwrap()
}

use crate::support::{signal, until};

async fn exit_code(child: Child) -> (i32, String) {
    let out = tokio::time::timeout(Duration::from_secs(60), child.wait_with_output())
        .await
        .expect("radbench ends within 60 s of the signal")
        .unwrap();
    (
        out.status.code().unwrap_or(-1),
        String::from_utf8_lossy(&out.stderr).into_owned(),
    )
}

/// Nothing half-written: no temporary file, and every file that is there is whole (the summary
/// parses and names files that exist).
fn no_partial_file(out: &Path) {
    let Ok(entries) = std::fs::read_dir(out) else {
        return;
    };
    for e in entries.filter_map(Result::ok) {
        let name = e.file_name().to_string_lossy().into_owned();
        assert!(!name.contains("tmp"), "a temporary file was left: {name}");
    }
    let summary = out.join("summary.json");
    if summary.exists() {
        let v: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(&summary).unwrap()).unwrap();
        for key in ["sigmf_meta", "sigmf_data", "profile_csv", "plot_png"] {
            let f = PathBuf::from(v["files"][key].as_str().unwrap());
            assert!(f.is_file(), "{key}: {}", f.display());
        }
    }
}

fn code_of(name: &str) -> i32 {
    match name {
        "INT" => 130,
        "TERM" => 143,
        "HUP" => 129,
        _ => unreachable!(),
    }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn each_signal_while_rf_is_on_leaves_the_bench_safe() {
    for name in ["TERM", "HUP", "INT"] {
        let lab = start().await;
        // No trigger reaches the scope: the capture waits with RF on until the signal.
        lab.bench.marker_cable.store(false, Ordering::Relaxed);
        let dir = tempfile::tempdir().unwrap();
        let bench = bench_file(dir.path(), &lab);
        let out = dir.path().join("out");
        let child = capture(&bench, &out, &["--wait", "60"]);
        until("RF on", Duration::from_secs(60), || {
            lab.bench.tx.front_end().rf_enabled && lab.bench.awg.playback().running
        })
        .await;
        signal(&child, name);
        let (code, err) = exit_code(child).await;
        assert_eq!(code, code_of(name), "SIG{name}: {err}");
        assert!(
            lab.bench.is_safe(),
            "SIG{name}: Tx off, outputs off, AWG stopped"
        );
        assert!(!lab.bench.rx.front_end().rf_enabled, "SIG{name}: Rx off");
        assert!(err.contains(&format!("SIG{name}")), "{err}");
        no_partial_file(&out);
    }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_signal_during_the_transfer_leaves_the_bench_safe() {
    let lab = start().await;
    // Every reply is slow: the fetch of the scope's channels is under way for seconds.
    let dir = tempfile::tempdir().unwrap();
    let bench = bench_file(dir.path(), &lab);
    let out = dir.path().join("out");
    let child = capture(&bench, &out, &[]);
    until("RF on", Duration::from_secs(60), || {
        lab.bench.tx.front_end().rf_enabled && lab.bench.awg.playback().running
    })
    .await;
    lab.scope_faults.set_reply_delay(Duration::from_millis(300));
    tokio::time::sleep(Duration::from_millis(400)).await;
    signal(&child, "TERM");
    let (code, err) = exit_code(child).await;
    lab.scope_faults.clear();
    assert_eq!(code, 143, "{err}");
    assert!(lab.bench.is_safe());
    no_partial_file(&out);
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_signal_while_the_files_are_written_finishes_them() {
    let lab = start().await;
    let dir = tempfile::tempdir().unwrap();
    let bench = bench_file(dir.path(), &lab);
    let out = dir.path().join("out");
    // 40 repetitions: tens of megabytes to write once RF is off again.
    let child = capture(&bench, &out, &["--repetitions", "40"]);
    until("RF on", Duration::from_secs(60), || {
        lab.bench.tx.front_end().rf_enabled
    })
    .await;
    until("RF off after the capture", Duration::from_secs(120), || {
        lab.bench.is_safe() && !lab.bench.rx.front_end().rf_enabled
    })
    .await;
    signal(&child, "TERM");
    let (code, err) = exit_code(child).await;
    assert!(lab.bench.is_safe());
    // Either the signal came while processing or writing (the files are finished, it says so,
    // exit 143) or after the process had already finished (exit 0): never half a file.
    assert!(code == 143 || code == 0, "{code}: {err}");
    if code == 143 {
        assert!(err.contains("files are written"), "{err}");
        assert!(out.join("summary.json").is_file());
    }
    no_partial_file(&out);
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_stalled_scope_gets_rf_off_by_the_deadline() {
    let lab = start().await;
    let dir = tempfile::tempdir().unwrap();
    let bench = bench_file(dir.path(), &lab);
    let out = dir.path().join("out");
    let child = capture(&bench, &out, &["--wait", "1"]);
    until("RF on", Duration::from_secs(60), || {
        lab.bench.tx.front_end().rf_enabled && lab.bench.awg.playback().running
    })
    .await;
    // The scope stops answering: every reply is swallowed from now on.
    lab.scope_faults.set_reply_delay(Duration::from_secs(3600));
    let started = std::time::Instant::now();
    let (code, err) = exit_code(child).await;
    let rf_on = started.elapsed();
    lab.scope_faults.clear();
    assert_eq!(code, 3, "{err}");
    // Bounded by the link's read timeout (10 s here) plus its clear, far inside the RF deadline.
    assert!(rf_on < Duration::from_secs(55), "RF stayed on {rf_on:?}");
    assert!(lab.bench.is_safe(), "{err}");
}

/// The Tx power-cycled while the scope records (its RF off from then on, as a module that lost
/// power for a moment): nothing in the capture fails, but the Tx read back after it answers as a
/// module at power-on does. `radbench capture` exits 3 naming the reset, writes no capture, and
/// leaves the bench safe.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_tx_power_cycled_during_the_capture_is_an_error_not_a_capture_without_echo() {
    let lab = start().await;
    let dir = tempfile::tempdir().unwrap();
    let bench = bench_file(dir.path(), &lab);
    let out = dir.path().join("out");
    let tx = lab.bench.tx.clone();
    lab.bench.at_next_trigger(move || tx.power_cycle());
    let (code, err) = exit_code(capture(&bench, &out, &[])).await;
    assert_eq!(code, 3, "{err}");
    assert!(
        err.contains(
            "tx: the module answers without the CRC-8 framing it was switched to, as at power-on"
        ) && err.contains("it was reset or lost power during the capture, which is not used"),
        "{err}"
    );
    assert!(!out.join("summary.json").exists(), "{err}");
    no_partial_file(&out);
    assert!(lab.bench.is_safe(), "{err}");
}
