//! `radbench doctor` on the mock lab: it passes on a healthy bench, and with the scope on its
//! other remote interface, a closed port, a Gotmic line in the wrong CRC mode or the marker cable
//! unplugged it names the fault and the fix; in every case the I/O journal shows that nothing
//! that radiates was sent (no I or Q output on, no front end enabled) and the bench ends safe.
//! Ctrl-C while an instrument is being opened and during the marker check ends it with 130, the
//! journal showing the same.

use mock_lab::lab::{self, Lab, LabOptions};
use mock_lab::server::launch::Transport;
use serde_json::Value;
use std::path::Path;
use std::sync::atomic::Ordering;
use std::time::Duration;
use tokio::io::{AsyncBufReadExt, AsyncWriteExt, BufReader};

async fn start() -> Lab {
    tokio::time::timeout(Duration::from_secs(10), lab::start(LabOptions::default()))
        .await
        .expect("lab starts")
        .expect("lab starts")
}

/// The lab's bench file with a fresh calibration (as `radbench calibrate` writes it).
fn write_bench(dir: &Path, name: &str, lab: &Lab, awg_resource: Option<&str>) -> String {
    let mut text = lab.bench_toml(Transport::Hislip, Transport::Vicp);
    if let Some(r) = awg_resource {
        let current = lab.endpoint("awg", Transport::Hislip).unwrap().resource;
        text = text.replace(&current, r);
    }
    let now = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .unwrap()
        .as_secs();
    // 1970-based stamp of today: the civil date from the day number.
    let days = (now / 86_400) as i64;
    let (y, m, d) = civil(days);
    text += &format!(
        "\n[calibration]\nsystem_delay_s = 2.5e-9\nreference_range_m = 1.0\nmeasured_at = \
         \"{y:04}-{m:02}-{d:02}T00:00:00.000Z\"\n"
    );
    let path = dir.join(name);
    std::fs::write(&path, text).unwrap();
    path.display().to_string()
}

fn civil(z: i64) -> (i64, u32, u32) {
    let z = z + 719_468;
    let era = z.div_euclid(146_097);
    let doe = z - era * 146_097;
    let yoe = (doe - doe / 1460 + doe / 36_524 - doe / 146_096) / 365;
    let doy = doe - (365 * yoe + yoe / 4 - yoe / 100);
    let mp = (5 * doy + 2) / 153;
    let d = (doy - (153 * mp + 2) / 5 + 1) as u32;
    let m = if mp < 10 { mp + 3 } else { mp - 9 } as u32;
    (yoe + era * 400 + i64::from(m <= 2), m, d)
}

async fn control(lab: &Lab, request: &str) -> Value {
    let stream = tokio::net::TcpStream::connect(lab.control).await.unwrap();
    let (rd, mut wr) = stream.into_split();
    wr.write_all(format!("{request}\n").as_bytes())
        .await
        .unwrap();
    let mut line = String::new();
    tokio::time::timeout(
        Duration::from_secs(10),
        BufReader::new(rd).read_line(&mut line),
    )
    .await
    .unwrap()
    .unwrap();
    serde_json::from_str(&line).unwrap()
}

/// Runs the doctor: (exit code, its JSON report, stderr), and checks the journal: nothing that
/// radiates was sent, and the bench is safe afterwards.
async fn doctor(lab: &Lab, bench: &str, dir: &Path) -> (i32, Value, String) {
    let journal = dir.join("io.jsonl");
    let _ = std::fs::remove_file(&journal);
    let journal_arg = journal.display().to_string();
    let (code, out, err) = crate::support::radbench_in(
        None,
        &[
            "doctor",
            "--bench",
            bench,
            "--json",
            "--trace-io",
            &journal_arg,
        ],
    )
    .await;
    let report: Value =
        serde_json::from_str(&out).unwrap_or_else(|e| panic!("not JSON ({e}): {out}\n{err}"));
    nothing_radiated(lab, &journal);
    (code, report, err)
}

/// The journal shows nothing that radiates (no I or Q output on, no Gotmic CONTROL write but
/// 0), and the bench is safe.
fn nothing_radiated(lab: &Lab, journal: &Path) {
    assert!(
        radiated_nothing(lab, journal) > 0,
        "the journal records the exchanges"
    );
}

/// [`nothing_radiated`] without asking for any exchange (a doctor stopped as it connects may
/// not have written yet); returns the writes seen.
fn radiated_nothing(lab: &Lab, journal: &Path) -> usize {
    let text = std::fs::read_to_string(journal).unwrap();
    let mut writes = 0;
    for line in text.lines() {
        let entry: Value = serde_json::from_str(line).unwrap();
        if entry["direction"] != "write" {
            continue;
        }
        writes += 1;
        let sent = entry["text"].as_str().unwrap_or("").trim().to_string();
        let who = entry["instrument"].as_str().unwrap_or("");
        let upper = sent.to_ascii_uppercase();
        assert!(
            !(upper.starts_with(":OUTP1 ON") || upper.starts_with(":OUTP2 ON")),
            "the doctor switched an I/Q output on: {sent}"
        );
        if who == "tx" || who == "rx" {
            // CONTROL is register 02: only ever written 0 (off).
            if let Some(value) = upper.strip_prefix("W 02 ") {
                let value = value.split('*').next().unwrap();
                assert_eq!(
                    u16::from_str_radix(value, 16).unwrap(),
                    0,
                    "{who} enabled: {sent}"
                );
            }
        }
    }
    assert!(lab.bench.is_safe(), "the bench ends safe");
    assert!(!lab.bench.tx.front_end().rf_enabled);
    assert!(!lab.bench.rx.front_end().rf_enabled);
    writes
}

fn check<'a>(report: &'a Value, id: &str) -> &'a Value {
    report["checks"]
        .as_array()
        .unwrap()
        .iter()
        .find(|c| c["id"] == id)
        .unwrap_or_else(|| panic!("no check {id} in {report:#}"))
}

fn failed(report: &Value) -> Vec<String> {
    report["checks"]
        .as_array()
        .unwrap()
        .iter()
        .filter(|c| c["status"] == "fail")
        .map(|c| c["id"].as_str().unwrap().to_string())
        .collect()
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn doctor_passes_on_the_mock_lab_and_names_each_fault_with_its_fix() {
    let dir = tempfile::tempdir().unwrap();
    let lab = start().await;
    let bench = write_bench(dir.path(), "bench.toml", &lab, None);

    // Healthy: every check holds, exit 0; the marker was seen with the Tx off.
    let (code, report, err) = doctor(&lab, &bench, dir.path()).await;
    assert_eq!(code, 0, "{report:#}\n{err}");
    assert_eq!(report["ok"], true);
    assert!(failed(&report).is_empty(), "{report:#}");
    for id in [
        "awg.identity",
        "scope.remote_interface",
        "tx.crc_mode",
        "rx.lo_lock",
        "tx.interlock",
        "tx.temperature",
        "marker",
        "calibration.delay",
        "safe_state",
    ] {
        assert_eq!(check(&report, id)["status"], "pass", "{id}: {report:#}");
    }
    assert!(["pass", "warn"].contains(&check(&report, "timebases")["status"].as_str().unwrap()));

    // The marker cable unplugged: the marker check fails and says what to look at.
    lab.bench.marker_cable.store(false, Ordering::SeqCst);
    let (code, report, _) = doctor(&lab, &bench, dir.path()).await;
    lab.bench.marker_cable.store(true, Ordering::SeqCst);
    assert_eq!(code, 3, "{report:#}");
    assert_eq!(failed(&report), ["marker"], "{report:#}");
    let marker = check(&report, "marker");
    assert!(
        marker["detail"]
            .as_str()
            .unwrap()
            .contains("no marker edge"),
        "{marker}"
    );
    assert!(
        marker["fix"].as_str().unwrap().contains("cable"),
        "{marker}"
    );

    // A Gotmic line whose CRC mode is fixed off: named, with the fix.
    lab.bench.tx.set_crc_fixed(Some(false));
    let (code, report, _) = doctor(&lab, &bench, dir.path()).await;
    lab.bench.tx.set_crc_fixed(None);
    assert_eq!(code, 3);
    assert_eq!(failed(&report), ["tx.crc_mode"], "{report:#}");
    let crc = check(&report, "tx.crc_mode");
    assert!(
        crc["detail"].as_str().unwrap().contains("CRC mode"),
        "{crc}"
    );
    assert!(crc["fix"].as_str().unwrap().contains("CRC"), "{crc}");

    // The scope set to its other remote interface: the VICP/VXI-11 trap, named.
    let v = control(&lab, r#"{"cmd":"scope_remote","interface":"vxi11"}"#).await;
    assert_eq!(v["ok"], true, "{v}");
    let (code, report, _) = doctor(&lab, &bench, dir.path()).await;
    let v = control(&lab, r#"{"cmd":"scope_remote","interface":"vicp"}"#).await;
    assert_eq!(v["ok"], true, "{v}");
    assert_eq!(code, 3);
    assert!(
        failed(&report).contains(&"scope.remote_interface".to_string()),
        "{report:#}"
    );
    let remote = check(&report, "scope.remote_interface");
    assert!(
        remote["detail"].as_str().unwrap().contains("LXI (VXI-11)"),
        "{remote}"
    );
    assert!(
        remote["fix"]
            .as_str()
            .unwrap()
            .contains("Remote to TCPIP (VICP)"),
        "{remote}"
    );

    // A closed port: nothing listens where the AWG should be.
    let closed = {
        let l = std::net::TcpListener::bind("127.0.0.1:0").unwrap();
        l.local_addr().unwrap().port()
    };
    let resource = format!("TCPIP::127.0.0.1::{closed}::SOCKET");
    let bench_closed = write_bench(dir.path(), "closed.toml", &lab, Some(&resource));
    let (code, report, _) = doctor(&lab, &bench_closed, dir.path()).await;
    assert_eq!(code, 3);
    let reach = check(&report, "awg.reachable");
    assert_eq!(reach["status"], "fail", "{report:#}");
    assert!(
        reach["detail"]
            .as_str()
            .unwrap()
            .contains(&closed.to_string()),
        "{reach}"
    );
    assert!(
        reach["fix"].as_str().unwrap().contains("resource string"),
        "{reach}"
    );
    assert_eq!(check(&report, "marker")["status"], "skip");

    // And healthy again.
    let (code, _, _) = doctor(&lab, &bench, dir.path()).await;
    assert_eq!(code, 0);
}

/// `radbench doctor` with the I/O journal, killable, its stderr piped.
fn spawn_doctor(bench: &str, journal: &Path) -> tokio::process::Child {
    tokio::process::Command::new(env!("CARGO_BIN_EXE_radbench"))
        .args(["doctor", "--bench", bench, "--trace-io"])
        .arg(journal)
        .stdin(std::process::Stdio::null())
        .stdout(std::process::Stdio::null())
        .stderr(std::process::Stdio::piped())
        .kill_on_drop(true)
        .spawn()
        .unwrap()
}

async fn ended(child: tokio::process::Child) -> (i32, String) {
    let out = tokio::time::timeout(Duration::from_secs(60), child.wait_with_output())
        .await
        .expect("the doctor ends within 60 s of the signal")
        .unwrap();
    (
        out.status.code().unwrap_or(-1),
        String::from_utf8_lossy(&out.stderr).into_owned(),
    )
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn ctrl_c_while_an_instrument_is_opened_ends_the_doctor_with_130() {
    let lab = start().await;
    let dir = tempfile::tempdir().unwrap();
    // The scope's resource is a port that accepts and never answers: the doctor waits there.
    let silent = tokio::net::TcpListener::bind("127.0.0.1:0").await.unwrap();
    let port = silent.local_addr().unwrap().port();
    let bench = write_bench(dir.path(), "bench.toml", &lab, None);
    let text = std::fs::read_to_string(&bench).unwrap();
    let scope = lab.endpoint("scope", Transport::Vicp).unwrap().resource;
    std::fs::write(
        &bench,
        text.replace(&scope, &format!("VICP::127.0.0.1,{port}::INSTR")),
    )
    .unwrap();
    let journal = dir.path().join("io.jsonl");
    let child = spawn_doctor(&bench, &journal);
    // Its first connection to the scope: the doctor is running (its signal handlers are in).
    let (held, _) = tokio::time::timeout(Duration::from_secs(60), silent.accept())
        .await
        .expect("the doctor reaches the scope")
        .unwrap();
    crate::support::signal(&child, "INT");
    let (code, err) = ended(child).await;
    drop(held);
    assert_eq!(code, 130, "{err}");
    assert!(
        err.contains("SIGINT") && err.contains("nothing is switched on"),
        "{err}"
    );
    // The instruments open side by side: on a busy machine the signal can come before any of
    // them has been written to.
    radiated_nothing(&lab, &journal);
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn ctrl_c_during_the_marker_check_leaves_the_bench_safe() {
    let lab = start().await;
    // No marker edge reaches the scope: the check waits on its trigger with the AWG running.
    lab.bench.marker_cable.store(false, Ordering::SeqCst);
    let dir = tempfile::tempdir().unwrap();
    let bench = write_bench(dir.path(), "bench.toml", &lab, None);
    let journal = dir.path().join("io.jsonl");
    let child = spawn_doctor(&bench, &journal);
    crate::support::until("the AWG playing", Duration::from_secs(60), || {
        lab.bench.awg.playback().running
    })
    .await;
    // From now on the scope answers nothing: the check cannot end before the signal.
    lab.scope_faults.set_reply_delay(Duration::from_secs(3600));
    crate::support::signal(&child, "INT");
    let (code, err) = ended(child).await;
    lab.scope_faults.clear();
    assert_eq!(code, 130, "{err}");
    assert!(err.contains("SIGINT"), "{err}");
    assert!(!lab.bench.awg.playback().running, "AWG stopped");
    nothing_radiated(&lab, &journal);
}

/// A lab's shared 10 MHz stays shared: with `[awg] reference_clock_hz` a capture locks the AWG to
/// its REF IN and never switches it back to internal; a bad value names the field.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_capture_keeps_the_awg_on_the_bench_file_s_external_reference() {
    let lab = start().await;
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let bench = write_bench(d, "bench.toml", &lab, None);
    let text = std::fs::read_to_string(&bench).unwrap();
    let with_ref = text.replacen("[awg]\n", "[awg]\nreference_clock_hz = 10e6\n", 1);
    assert_ne!(with_ref, text, "the bench file has an [awg] table");
    std::fs::write(&bench, &with_ref).unwrap();
    let journal = d.join("io.jsonl");
    let (code, _, err) = super::support::radbench_in(
        Some(d),
        &[
            "--trace-io",
            journal.to_str().unwrap(),
            "capture",
            "--bench",
            &bench,
            "--allow-rf",
            "--json",
        ],
    )
    .await;
    assert_eq!(code, 0, "{err}");
    let sent = std::fs::read_to_string(&journal).unwrap();
    assert!(
        sent.contains(":ROSC:SOUR EXT"),
        "the external reference chosen"
    );
    assert!(
        !sent.contains(":ROSC:SOUR INT"),
        "never switched back to internal"
    );
    let bad = with_ref.replace("reference_clock_hz = 10e6", "reference_clock_hz = 5");
    std::fs::write(&bench, bad).unwrap();
    let (code, _, err) =
        super::support::radbench_in(Some(d), &["capture", "--bench", &bench, "--allow-rf"]).await;
    assert_eq!(code, 2, "{err}");
    assert!(
        err.contains("reference_clock_hz = 5") && err.contains("10e6"),
        "{err}"
    );
}
