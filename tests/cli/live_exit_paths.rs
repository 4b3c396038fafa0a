//! `align`, `capture --repeat --live` and `campaign run --live` leave the bench as safe as
//! `capture` does (tests/cli/exit_paths.rs): a signal while RF is on, the live page's Stop, a
//! lost instrument, an unreachable AWG; a live view with a stalled browser connected changes
//! nothing of a campaign's outcome; an explicit `--listen` still needs the token (on loopback:
//! tests serve nowhere else). The panic path is tests/rig_panic_hook.rs. Loopback only,
//! every wait bounded, nothing timed.

use mock_lab::lab::Lab;
use std::path::Path;
use std::process::Stdio;
use std::sync::atomic::Ordering;
use std::time::Duration;
use tokio::io::{AsyncBufReadExt, AsyncReadExt, AsyncWriteExt, BufReader};
use tokio::net::TcpStream;
use tokio::process::{Child, Command};

const BIN: &str = env!("CARGO_BIN_EXE_radbench");
const LIMIT: Duration = Duration::from_secs(60);

use crate::support::{lab_bench_file as bench_file, start_lab as start};

fn spawn(args: &[&str]) -> Child {
    Command::new(BIN)
        .args(args)
        .stdin(Stdio::null())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .kill_on_drop(true)
        .spawn()
        .unwrap()
}

use crate::support::signal;

/// Polls `cond` until it holds, for at most [`LIMIT`].
async fn until(what: &str, cond: impl Fn() -> bool) {
    crate::support::until(what, LIMIT, cond).await
}

async fn finished(child: Child) -> (i32, String, String) {
    let out = tokio::time::timeout(LIMIT, child.wait_with_output())
        .await
        .expect("radbench ends within 60 s")
        .unwrap();
    (
        out.status.code().unwrap_or(-1),
        String::from_utf8_lossy(&out.stdout).into_owned(),
        String::from_utf8_lossy(&out.stderr).into_owned(),
    )
}

/// The live view's URL from the `{"event":"live"}` line (`--json`), and stdout given back for
/// the rest.
async fn live_url(child: &mut Child) -> (String, String) {
    let stdout = child.stdout.take().unwrap();
    let mut lines = BufReader::new(stdout).lines();
    let line = tokio::time::timeout(LIMIT, lines.next_line())
        .await
        .expect("the live event")
        .unwrap()
        .expect("a line");
    let v: serde_json::Value = serde_json::from_str(&line).unwrap();
    assert_eq!(v["event"], "live", "{line}");
    let url = v["url"].as_str().unwrap().to_string();
    // Keep reading stdout so the child never blocks on it.
    tokio::spawn(async move { while let Ok(Some(_)) = lines.next_line().await {} });
    let (addr, token) = url
        .trim_start_matches("http://")
        .split_once("/?token=")
        .unwrap();
    (addr.to_string(), token.to_string())
}

/// One request to the live view; the status code.
async fn http(addr: &str, method: &str, target: &str) -> u16 {
    let mut s = TcpStream::connect(addr).await.unwrap();
    let head = format!("{method} {target} HTTP/1.1\r\nHost: {addr}\r\nContent-Length: 0\r\n\r\n");
    s.write_all(head.as_bytes()).await.unwrap();
    let mut out = Vec::new();
    tokio::time::timeout(LIMIT, s.read_to_end(&mut out))
        .await
        .expect("an answer")
        .unwrap();
    String::from_utf8_lossy(&out)
        .split(' ')
        .nth(1)
        .and_then(|c| c.parse().ok())
        .unwrap_or(0)
}

fn rf_on(lab: &Lab) -> bool {
    lab.bench.tx.front_end().rf_enabled && lab.bench.awg.playback().running
}

fn safe(lab: &Lab) -> bool {
    lab.bench.is_safe() && !lab.bench.rx.front_end().rf_enabled
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn align_each_signal_while_rf_is_on_leaves_the_bench_safe() {
    for (name, code) in [("TERM", 143), ("HUP", 129), ("INT", 130)] {
        let lab = start().await;
        // No trigger reaches the scope: the capture waits with RF on until the signal.
        lab.bench.marker_cable.store(false, Ordering::Relaxed);
        let dir = tempfile::tempdir().unwrap();
        let bench = bench_file(dir.path(), &lab);
        let child = spawn(&[
            "align",
            "--allow-rf",
            "--bench",
            &bench,
            "--target-range",
            "1.0",
            "--wait",
            "60",
        ]);
        until("RF on", || rf_on(&lab)).await;
        signal(&child, name);
        let (got, _, err) = finished(child).await;
        assert_eq!(got, code, "SIG{name}: {err}");
        assert!(safe(&lab), "SIG{name}: Tx, Rx and outputs off, AWG stopped");
        assert!(err.contains(&format!("SIG{name}")), "{err}");
    }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn align_counts_its_captures_and_a_lost_scope_ends_it_safely() {
    let lab = start().await;
    let dir = tempfile::tempdir().unwrap();
    let bench = bench_file(dir.path(), &lab);
    let child = spawn(&[
        "align",
        "--allow-rf",
        "--bench",
        &bench,
        "--target-range",
        "1.0",
        "--count",
        "2",
        "--json",
    ]);
    let (code, out, err) = finished(child).await;
    assert_eq!(code, 0, "{err}");
    let lines: Vec<serde_json::Value> = out
        .lines()
        .map(|l| serde_json::from_str(l).unwrap())
        .collect();
    assert_eq!(lines.len(), 2, "one line per capture: {out}");
    for (k, v) in lines.iter().enumerate() {
        assert_eq!(v["capture"], k as u64 + 1);
        let d = v["distance_m"].as_f64().unwrap();
        let r = v["range_m"].as_f64().unwrap();
        assert!((r - 1.0 - d).abs() < 1e-12, "{v}");
    }
    assert!(safe(&lab));

    // The scope stops answering mid-capture: exit 3, RF off.
    let child = spawn(&["align", "--allow-rf", "--bench", &bench, "--wait", "1"]);
    until("RF on", || rf_on(&lab)).await;
    lab.scope_faults.set_reply_delay(Duration::from_secs(3600));
    let (code, _, err) = finished(child).await;
    lab.scope_faults.clear();
    assert_eq!(code, 3, "{err}");
    assert!(safe(&lab), "{err}");
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn the_live_pages_stop_is_ctrl_c_and_needs_the_token() {
    let lab = start().await;
    lab.bench.marker_cable.store(false, Ordering::Relaxed);
    let dir = tempfile::tempdir().unwrap();
    let bench = bench_file(dir.path(), &lab);
    let out = dir.path().join("out");
    let mut child = spawn(&[
        "capture",
        "--allow-rf",
        "--bench",
        &bench,
        "--out",
        out.to_str().unwrap(),
        "--repeat",
        "forever",
        "--wait",
        "60",
        "--json",
        "--live",
    ]);
    let (addr, token) = live_url(&mut child).await;
    until("RF on", || rf_on(&lab)).await;
    // A wrong or missing token: 403, and the capture goes on with RF on.
    assert_eq!(http(&addr, "POST", "/stop").await, 403);
    assert_eq!(http(&addr, "POST", "/stop?token=0").await, 403);
    assert!(child.try_wait().unwrap().is_none(), "still running");
    assert!(rf_on(&lab));
    assert_eq!(
        http(&addr, "POST", &format!("/stop?token={token}")).await,
        200
    );
    let (code, _, err) = finished(child).await;
    assert_eq!(code, 130, "Stop is Ctrl-C: {err}");
    assert!(safe(&lab), "{err}");
    assert!(err.contains("Stop pressed on the live page"), "{err}");
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_live_campaign_signalled_while_rf_is_on_is_safe_and_resumable() {
    let lab = start().await;
    lab.bench.marker_cable.store(false, Ordering::Relaxed);
    let dir = tempfile::tempdir().unwrap();
    let bench = bench_file(dir.path(), &lab);
    let out = dir.path().join("run");
    let spec = dir.path().join("spec.toml");
    std::fs::write(
        &spec,
        "name = \"live-exit\"\nwait_s = 60\n[waveform]\nkind = \"msk-lfm\"\n\
         [sweep]\nparameter = \"position\"\nstart = 1.0\nstep = -0.03\ncount = 3\n",
    )
    .unwrap();
    let mut child = spawn(&[
        "campaign",
        "run",
        spec.to_str().unwrap(),
        "--bench",
        &bench,
        "--allow-rf",
        "--out",
        out.to_str().unwrap(),
        "--json",
        "--live",
    ]);
    let _ = live_url(&mut child).await;
    until("RF on", || rf_on(&lab)).await;
    signal(&child, "TERM");
    let (code, _, err) = finished(child).await;
    assert_eq!(code, 143, "{err}");
    assert!(safe(&lab), "{err}");
    let manifest = std::fs::read_to_string(out.join("manifest.toml")).unwrap();
    assert!(manifest.contains("status = \"interrupted\""), "{manifest}");
    // Resumed with its live view, the marker cable back: it finishes.
    lab.bench.marker_cable.store(true, Ordering::Relaxed);
    let mut child = spawn(&[
        "campaign",
        "resume",
        out.to_str().unwrap(),
        "--allow-rf",
        "--json",
        "--live",
    ]);
    let _ = live_url(&mut child).await;
    let (code, _, err) = finished(child).await;
    assert_eq!(code, 0, "{err}");
    assert!(safe(&lab), "{err}");
    let manifest = std::fs::read_to_string(out.join("manifest.toml")).unwrap();
    assert!(manifest.contains("status = \"complete\""), "{manifest}");
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_lost_scope_ends_a_live_repeat_safely() {
    let lab = start().await;
    let dir = tempfile::tempdir().unwrap();
    let bench = bench_file(dir.path(), &lab);
    let out = dir.path().join("out");
    let mut child = spawn(&[
        "capture",
        "--allow-rf",
        "--bench",
        &bench,
        "--out",
        out.to_str().unwrap(),
        "--repeat",
        "forever",
        "--wait",
        "1",
        "--json",
        "--live",
    ]);
    let _ = live_url(&mut child).await;
    until("RF on", || rf_on(&lab)).await;
    // The scope stops answering: every reply is swallowed from now on.
    lab.scope_faults.set_reply_delay(Duration::from_secs(3600));
    let (code, _, err) = finished(child).await;
    lab.scope_faults.clear();
    assert_eq!(code, 3, "{err}");
    assert!(safe(&lab), "{err}");
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_stalled_browser_changes_nothing_of_a_campaign() {
    let dir = tempfile::tempdir().unwrap();
    let spec = Path::new(env!("CARGO_MANIFEST_DIR")).join("examples/accuracy.toml");
    let mut results = Vec::new();
    for stalled in [false, true] {
        let out = dir.path().join(format!("run-{stalled}"));
        let mut child = spawn(&[
            "campaign",
            "run",
            spec.to_str().unwrap(),
            "--allow-rf",
            "--out",
            out.to_str().unwrap(),
            "--json",
            "--live",
        ]);
        let (addr, token) = live_url(&mut child).await;
        let mut browser = None;
        if stalled {
            // Asks for the stream and never reads a byte of it, with a small receive buffer
            // (4 KiB asked; the kernel's minimum beside it) that fills after the first frame.
            let socket = tokio::net::TcpSocket::new_v4().unwrap();
            socket.set_recv_buffer_size(4096).unwrap();
            let mut s = socket.connect(addr.parse().unwrap()).await.unwrap();
            let head = format!("GET /events?token={token} HTTP/1.1\r\nHost: {addr}\r\n\r\n");
            s.write_all(head.as_bytes()).await.unwrap();
            browser = Some(s);
        }
        // Bounded: the campaign ends within LIMIT whatever the browser does.
        let (code, _, err) = finished(child).await;
        assert_eq!(code, 0, "{err}");
        drop(browser);
        // The live view's counters, on stderr at the end (how many frames a stalled browser
        // skips depends on the kernel's socket buffers: src/bin/radbench/live/tests.rs checks that part).
        let counters = err
            .lines()
            .find(|l| l.starts_with("live view closed: "))
            .unwrap_or_else(|| panic!("the counters: {err}"));
        let number = |after: &str| -> u64 {
            let k = counters.find(after).unwrap();
            counters[..k]
                .rsplit([' ', ','])
                .find(|w| !w.is_empty())
                .unwrap()
                .parse()
                .unwrap()
        };
        assert!(number(" frames published") > 0, "{counters}");
        assert!(number(" requests refused") == 0, "{counters}");
        let manifest = std::fs::read_to_string(out.join("manifest.toml")).unwrap();
        assert!(manifest.contains("status = \"complete\""), "{manifest}");
        let v: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(out.join("results.json")).unwrap())
                .unwrap();
        results.push(v["steps"].clone());
    }
    // The same steps, the same ranges (seeded noise): the browser changed nothing.
    assert_eq!(results[0], results[1]);
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn capture_repeat_writes_each_capture_and_ends_safe() {
    let lab = start().await;
    let dir = tempfile::tempdir().unwrap();
    let bench = bench_file(dir.path(), &lab);
    let out = dir.path().join("out");
    let child = spawn(&[
        "capture",
        "--allow-rf",
        "--bench",
        &bench,
        "--out",
        out.to_str().unwrap(),
        "--repeat",
        "2",
        "--json",
    ]);
    let (code, stdout, err) = finished(child).await;
    assert_eq!(code, 0, "{err}");
    let lines: Vec<serde_json::Value> = stdout
        .lines()
        .map(|l| serde_json::from_str(l).unwrap())
        .collect();
    assert_eq!(lines.len(), 2, "{stdout}");
    for (k, v) in lines.iter().enumerate() {
        assert_eq!(v["capture"], k as u64 + 1);
        let folder = out.join(format!("capture-{:04}", k + 1));
        assert!(folder.join("summary.json").is_file());
        assert!(folder.join("profile.csv").is_file());
    }
    assert!(safe(&lab));
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn live_options_are_checked() {
    let (code, _, err) = finished(spawn(&["capture", "--allow-rf", "--live"])).await;
    assert_eq!(code, 2, "{err}");
    assert!(err.contains("--live") && err.contains("--repeat"), "{err}");
    let (code, _, err) = finished(spawn(&["capture", "--allow-rf", "--repeat", "0"])).await;
    assert_eq!(code, 2, "{err}");
    assert!(err.contains("forever"), "{err}");
    let (code, _, err) = finished(spawn(&["align", "--allow-rf", "--target-range", "-1"])).await;
    assert_eq!(code, 2, "{err}");
    assert!(err.contains("--target-range"), "{err}");
    let (code, _, err) = finished(spawn(&["align", "--target-range", "1"])).await;
    assert_ne!(code, 0, "no permit, no RF: {err}");
    // A port in use.
    let held = std::net::TcpListener::bind("127.0.0.1:0").unwrap();
    let port = held.local_addr().unwrap().port().to_string();
    let (code, _, err) = finished(spawn(&[
        "align",
        "--allow-rf",
        "--live",
        "--port",
        &port,
        "--count",
        "1",
    ]))
    .await;
    assert_eq!(code, 2, "{err}");
    assert!(err.contains(&format!("--port {port}")), "{err}");
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn an_explicit_listen_address_still_needs_the_token() {
    let lab = start().await;
    lab.bench.marker_cable.store(false, Ordering::Relaxed);
    let dir = tempfile::tempdir().unwrap();
    let bench = bench_file(dir.path(), &lab);
    // An explicit --listen, on loopback: tests serve nowhere else (the warning for an address
    // beyond loopback is unit-tested in cli::live).
    let mut child = spawn(&[
        "align",
        "--allow-rf",
        "--bench",
        &bench,
        "--wait",
        "60",
        "--json",
        "--live",
        "--listen",
        "127.0.0.1",
    ]);
    let (addr, token) = live_url(&mut child).await;
    assert!(
        addr.starts_with("127.0.0.1:"),
        "the URL names loopback: {addr}"
    );
    assert_eq!(token.len(), 32, "{token}");
    until("RF on", || rf_on(&lab)).await;
    assert_eq!(http(&addr, "GET", "/").await, 403);
    assert_eq!(http(&addr, "GET", "/?token=").await, 403);
    assert_eq!(http(&addr, "GET", "/events").await, 403);
    assert_eq!(http(&addr, "POST", "/stop").await, 403);
    assert!(
        child.try_wait().unwrap().is_none(),
        "a refused Stop stops nothing"
    );
    assert!(rf_on(&lab));
    assert_eq!(http(&addr, "GET", &format!("/?token={token}")).await, 200);
    assert_eq!(
        http(&addr, "POST", &format!("/stop?token={token}")).await,
        200
    );
    let (code, _, err) = finished(child).await;
    assert_eq!(code, 130, "{err}");
    assert!(safe(&lab), "{err}");
    assert!(
        !err.contains("WARNING"),
        "loopback is not warned about: {err}"
    );
    assert!(err.contains("4 requests refused"), "{err}");
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn align_and_a_live_campaign_on_an_unreachable_awg_end_with_3_and_nothing_on() {
    let lab = start().await;
    let dir = tempfile::tempdir().unwrap();
    let bench = bench_file(dir.path(), &lab);
    // The AWG's port closed: a listener bound, then dropped.
    let closed = std::net::TcpListener::bind("127.0.0.1:0").unwrap();
    let port = closed.local_addr().unwrap().port();
    drop(closed);
    let text = std::fs::read_to_string(&bench).unwrap();
    let awg = lab
        .endpoint("awg", mock_lab::server::launch::Transport::Hislip)
        .unwrap()
        .resource;
    let broken = dir.path().join("broken.toml");
    std::fs::write(
        &broken,
        text.replace(&awg, &format!("TCPIP::127.0.0.1::hislip0,{port}::INSTR")),
    )
    .unwrap();
    let broken = broken.to_str().unwrap();
    let (code, _, err) = finished(spawn(&[
        "align",
        "--allow-rf",
        "--bench",
        broken,
        "--count",
        "1",
        "--live",
    ]))
    .await;
    assert_eq!(code, 3, "{err}");
    assert!(safe(&lab), "{err}");
    // A live campaign on the same bench file.
    let spec = Path::new(env!("CARGO_MANIFEST_DIR")).join("examples/accuracy.toml");
    let out = dir.path().join("run");
    let (code, _, err) = finished(spawn(&[
        "campaign",
        "run",
        spec.to_str().unwrap(),
        "--allow-rf",
        "--bench",
        broken,
        "--out",
        out.to_str().unwrap(),
        "--live",
    ]))
    .await;
    assert_eq!(code, 3, "{err}");
    assert!(safe(&lab), "{err}");
    assert!(!lab.bench.tx.front_end().rf_enabled);
}
