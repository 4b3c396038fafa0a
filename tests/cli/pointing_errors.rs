//! Errors and warnings that point the right way (issue 39): a misspelt key or resource gets a
//! did-you-mean, a refused connection lists its possible causes instead of guessing one, the
//! advice "raise the timeout" names an option the command has, a stop after RF says what was
//! switched off, and a bench without a delay calibration says so in every output. Loopback only,
//! every wait bounded.

use crate::support::{lab_bench_file, radbench_in, start_lab};
use mock_lab::lab::Lab;
use serde_json::Value;
use std::path::Path;
use std::sync::atomic::Ordering;
use std::time::Duration;

const BIN: &str = env!("CARGO_BIN_EXE_radbench");
const LIMIT: Duration = Duration::from_secs(60);

/// A campaign of one step, target at 1 m.
const ONE_STEP: &str = "name = \"one-step\"\n[waveform]\nkind = \"msk-lfm\"\n\
    [sweep]\nparameter = \"position\"\nstart = 1.0\nstep = 0.1\ncount = 1\n";

fn safe(lab: &Lab) -> bool {
    lab.bench.is_safe() && !lab.bench.rx.front_end().rf_enabled
}

/// `lab`'s bench file with `from` replaced by `to`, as `dir/name`.
fn bench_with(dir: &Path, name: &str, lab: &Lab, from: &str, to: &str) -> String {
    let text = std::fs::read_to_string(lab_bench_file(dir, lab)).unwrap();
    assert!(text.contains(from), "{from} in {text}");
    let path = dir.join(name);
    std::fs::write(&path, text.replace(from, to)).unwrap();
    path.display().to_string()
}

fn scope_resource(lab: &Lab) -> String {
    use mock_lab::server::launch::Transport;
    lab.endpoint("scope", Transport::Vicp).unwrap().resource
}

async fn capture(dir: &Path, bench: &str, more: &[&str]) -> (i32, String, String) {
    let out = dir.join(format!("out-{}", more.join("-").replace(['/', ' '], "_")));
    let mut args = vec![
        "capture",
        "--allow-rf",
        "--bench",
        bench,
        "--out",
        out.to_str().unwrap(),
    ];
    args.extend_from_slice(more);
    radbench_in(Some(dir), &args).await
}

#[tokio::test]
async fn a_misspelt_hislip_resource_gets_a_did_you_mean_not_a_portmapper_error() {
    let dir = tempfile::tempdir().unwrap();
    let bench = dir.path().join("bench.toml");
    std::fs::write(
        &bench,
        "[awg]\nmodel = \"keysight-m8195a\"\nresource = \"TCPIP0::127.0.0.1::hislp0::INSTR\"\n\
         [scope]\nmodel = \"lecroy-labmaster10zi-a\"\nresource = \"VICP::127.0.0.1\"\n",
    )
    .unwrap();
    let (code, _, err) = capture(dir.path(), bench.to_str().unwrap(), &[]).await;
    assert_eq!(code, 2, "{err}");
    assert!(err.contains("line 3"), "{err}");
    assert!(err.contains("did you mean `hislip0` (HiSLIP)?"), "{err}");
    assert!(!err.contains(":111"), "{err}");
}

#[tokio::test]
async fn unknown_bench_and_spec_keys_name_the_nearest_allowed_key() {
    let dir = tempfile::tempdir().unwrap();
    let bench = dir.path().join("bench.toml");
    std::fs::write(
        &bench,
        "[awg]\nmodel = \"keysight-m8195a\"\nresorce = \"TCPIP::127.0.0.1::hislip0\"\n",
    )
    .unwrap();
    let (code, _, err) = radbench_in(
        Some(dir.path()),
        &["doctor", "--bench", bench.to_str().unwrap()],
    )
    .await;
    assert_eq!(code, 2, "{err}");
    assert!(err.contains("unknown field `resorce`"), "{err}");
    assert!(err.contains("did you mean `resource`?"), "{err}");

    let spec = dir.path().join("spec.toml");
    std::fs::write(
        &spec,
        "name = \"typo\"\nrepetitons = 2\n[waveform]\nkind = \"msk-lfm\"\n",
    )
    .unwrap();
    let (code, _, err) = radbench_in(
        Some(dir.path()),
        &["campaign", "run", spec.to_str().unwrap(), "--dry-run"],
    )
    .await;
    assert_eq!(code, 2, "{err}");
    assert!(err.contains("spec.toml:2: `repetitons`"), "{err}");
    assert!(err.contains("did you mean `repetitions`?"), "{err}");

    let scene = dir.path().join("scene.toml");
    std::fs::write(&scene, "snr_bd = 20.0\n").unwrap();
    let (code, _, err) = radbench_in(
        Some(dir.path()),
        &["capture", "--allow-rf", "--scene", scene.to_str().unwrap()],
    )
    .await;
    assert_eq!(code, 2, "{err}");
    assert!(err.contains("did you mean `snr_db`?"), "{err}");
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_refused_scope_connection_lists_the_causes_instead_of_guessing() {
    let lab = start_lab().await;
    let dir = tempfile::tempdir().unwrap();
    let closed = {
        let l = std::net::TcpListener::bind("127.0.0.1:0").unwrap();
        l.local_addr().unwrap().port()
    };
    let bench = bench_with(
        dir.path(),
        "refused.toml",
        &lab,
        &scope_resource(&lab),
        &format!("VICP::127.0.0.1,{closed}::INSTR"),
    );
    let (code, _, err) = capture(dir.path(), &bench, &[]).await;
    assert_eq!(code, 3, "{err}");
    assert!(err.contains("the connection was refused"), "{err}");
    assert!(
        err.contains("Possible causes: the instrument is off or still starting up"),
        "{err}"
    );
    assert!(err.contains("Remote must be TCPIP (VICP)"), "{err}");
    assert!(!err.contains("probably"), "{err}");
    assert!(safe(&lab));
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn something_else_on_the_vicp_port_is_named_once_and_as_not_vicp() {
    // A web server where the scope should be: its reply is not a VICP header.
    let server = tokio::net::TcpListener::bind("127.0.0.1:0").await.unwrap();
    let port = server.local_addr().unwrap().port();
    let answering = tokio::spawn(async move {
        use tokio::io::{AsyncReadExt, AsyncWriteExt};
        while let Ok((mut s, _)) = server.accept().await {
            tokio::spawn(async move {
                let mut buf = [0u8; 256];
                let _ = s.read(&mut buf).await;
                let _ = s.write_all(b"HTTP/1.1 400 Bad Request\r\n\r\n").await;
                let _ = s.read(&mut buf).await;
            });
        }
    });
    let lab = start_lab().await;
    let dir = tempfile::tempdir().unwrap();
    let bench = bench_with(
        dir.path(),
        "http.toml",
        &lab,
        &scope_resource(&lab),
        &format!("VICP::127.0.0.1,{port}::INSTR"),
    );
    let (code, _, err) = capture(dir.path(), &bench, &[]).await;
    answering.abort();
    assert_eq!(code, 3, "{err}");
    assert!(!err.contains("VICP: VICP:"), "{err}");
    assert_eq!(err.matches("bad header").count(), 1, "{err}");
    assert!(err.contains("what answered does not speak VICP"), "{err}");
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_hung_scope_advises_the_timeout_option_capture_takes() {
    let lab = start_lab().await;
    let dir = tempfile::tempdir().unwrap();
    let bench = lab_bench_file(dir.path(), &lab);
    lab.scope_faults.set_reply_delay(Duration::from_secs(3600));
    let (code, _, err) = capture(dir.path(), &bench, &["--timeout", "0.3"]).await;
    lab.scope_faults.clear();
    assert_eq!(code, 3, "{err}");
    // The catalog says 10 s; --timeout made it 300 ms, and the advice names the option.
    assert!(err.contains("after 300 ms"), "{err}");
    assert!(
        err.contains("raise the timeout (--timeout SECONDS)"),
        "{err}"
    );
    assert!(safe(&lab));

    std::fs::write(dir.path().join("spec.toml"), ONE_STEP).unwrap();
    for args in [
        vec!["capture", "--allow-rf", "--timeout", "0"],
        vec!["align", "--allow-rf", "--timeout", "-1"],
        vec![
            "campaign",
            "run",
            "spec.toml",
            "--allow-rf",
            "--timeout",
            "1e9",
        ],
    ] {
        let (code, _, err) = radbench_in(Some(dir.path()), &args).await;
        assert_eq!(code, 2, "{args:?}: {err}");
        assert!(
            err.contains("--timeout") && err.contains("allowed: a positive number of seconds"),
            "{args:?}: {err}"
        );
    }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_missing_marker_edge_confirms_what_was_switched_off() {
    let lab = start_lab().await;
    lab.bench.marker_cable.store(false, Ordering::Relaxed);
    let dir = tempfile::tempdir().unwrap();
    let bench = lab_bench_file(dir.path(), &lab);
    let (code, _, err) = capture(dir.path(), &bench, &["--wait", "0.5"]).await;
    assert_eq!(code, 3, "{err}");
    assert!(err.contains("no marker edge"), "{err}");
    assert!(
        err.contains(
            "RF was on and is off again, the bench is in its safe state (Tx RF off: done; Rx \
             off: done; AWG outputs off and :ABOR: done)"
        ),
        "{err}"
    );
    assert!(safe(&lab));
}

#[tokio::test]
async fn a_campaign_without_a_permit_does_not_speak_of_a_capture() {
    let dir = tempfile::tempdir().unwrap();
    let spec = dir.path().join("spec.toml");
    std::fs::write(&spec, ONE_STEP).unwrap();
    let (code, _, err) = radbench_in(
        Some(dir.path()),
        &["campaign", "run", spec.to_str().unwrap()],
    )
    .await;
    assert_eq!(code, 2, "{err}");
    assert!(err.contains("for this campaign's steps"), "{err}");
    assert!(!err.contains("capture"), "{err}");
}

#[tokio::test]
async fn capture_help_is_grouped_under_headings() {
    let (code, out, err) = radbench_in(None, &["capture", "--help"]).await;
    assert_eq!(code, 0, "{err}");
    let at = |heading: &str| {
        out.find(&format!("\n{heading}:\n"))
            .unwrap_or_else(|| panic!("heading {heading}: {out}"))
    };
    for heading in [
        "Waveform",
        "Processing",
        "Bench",
        "Built-in lab",
        "Live",
        "Output",
    ] {
        at(heading);
    }
    // Each option under its own heading.
    let under = |option: &str, heading: &str| {
        let k = out.find(&format!("  {option}")).expect(option);
        let before = [
            "Waveform",
            "Processing",
            "Bench",
            "Built-in lab",
            "Live",
            "Output",
        ]
        .into_iter()
        .filter(|h| at(h) < k)
        .max_by_key(|h| at(h));
        assert_eq!(before, Some(heading), "{option}: {out}");
    };
    under("--bandwidth", "Waveform");
    under("--window", "Processing");
    under("--timeout", "Bench");
    under("--awg-transport", "Built-in lab");
    under("--live", "Live");
    under("--out", "Output");
}

/// The warnings of a capture's `--json` line.
fn warnings(summary: &Value) -> Vec<String> {
    summary["warnings"]
        .as_array()
        .unwrap()
        .iter()
        .map(|w| w.as_str().unwrap().to_string())
        .collect()
}

fn uncalibrated(warnings: &[String]) -> bool {
    warnings.iter().any(|w| {
        w.starts_with("the bench is not calibrated")
            && w.contains("radbench calibrate --reference-range METRES --bench")
    })
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn an_uncalibrated_bench_says_so_in_every_output() {
    let lab = start_lab().await;
    let dir = tempfile::tempdir().unwrap();
    let bench = lab_bench_file(dir.path(), &lab);

    // capture --json, and its summary.json.
    let out = dir.path().join("json");
    let (code, stdout, err) = radbench_in(
        Some(dir.path()),
        &[
            "capture",
            "--allow-rf",
            "--bench",
            &bench,
            "--json",
            "--out",
            out.to_str().unwrap(),
        ],
    )
    .await;
    assert_eq!(code, 0, "{err}");
    let summary: Value = serde_json::from_str(&stdout).unwrap();
    assert!(uncalibrated(&warnings(&summary)), "{summary:#}");
    assert_eq!(summary["system_delay_s"], 0.0);
    let file: Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("summary.json")).unwrap()).unwrap();
    assert!(uncalibrated(&warnings(&file)), "{file:#}");
    assert!(
        err.contains("warning: the bench is not calibrated"),
        "{err}"
    );

    // The text report.
    let (code, stdout, err) = capture(dir.path(), &bench, &[]).await;
    assert_eq!(code, 0, "{err}");
    assert!(
        stdout.contains("warning: the bench is not calibrated"),
        "{stdout}"
    );

    // A campaign: its --json end, its reports, each step's summary.json.
    let spec = dir.path().join("spec.toml");
    std::fs::write(&spec, ONE_STEP).unwrap();
    let run = dir.path().join("run");
    let (code, stdout, err) = radbench_in(
        Some(dir.path()),
        &[
            "campaign",
            "run",
            spec.to_str().unwrap(),
            "--bench",
            &bench,
            "--allow-rf",
            "--json",
            "--out",
            run.to_str().unwrap(),
        ],
    )
    .await;
    assert_eq!(code, 0, "{err}");
    let done: Value = serde_json::from_str(stdout.lines().last().unwrap()).unwrap();
    assert_eq!(done["event"], "done", "{stdout}");
    assert!(uncalibrated(&warnings(&done)), "{done}");
    let md = std::fs::read_to_string(run.join("report.md")).unwrap();
    assert!(
        md.contains("**Warning:** the bench is not calibrated"),
        "{md}"
    );
    let html = std::fs::read_to_string(run.join("report.html")).unwrap();
    assert!(
        html.contains("<p class=\"warning\"><strong>Warning:</strong> the bench is not calibrated"),
        "report.html"
    );
    let step = std::fs::read_dir(&run)
        .unwrap()
        .filter_map(Result::ok)
        .map(|e| e.path().join("summary.json"))
        .find(|p| p.is_file())
        .expect("a step's summary.json");
    let step: Value = serde_json::from_str(&std::fs::read_to_string(step).unwrap()).unwrap();
    assert!(uncalibrated(&warnings(&step)), "{step:#}");

    // Calibrated, the same bench has nothing to warn of.
    let text = std::fs::read_to_string(&bench).unwrap();
    let calibrated = dir.path().join("calibrated.toml");
    std::fs::write(
        &calibrated,
        format!("{text}\n[calibration]\nsystem_delay_s = 2.5e-9\n"),
    )
    .unwrap();
    let out = dir.path().join("calibrated-out");
    let (code, stdout, err) = radbench_in(
        Some(dir.path()),
        &[
            "capture",
            "--allow-rf",
            "--bench",
            calibrated.to_str().unwrap(),
            "--json",
            "--out",
            out.to_str().unwrap(),
        ],
    )
    .await;
    assert_eq!(code, 0, "{err}");
    let summary: Value = serde_json::from_str(&stdout).unwrap();
    assert!(!uncalibrated(&warnings(&summary)), "{summary:#}");
    assert!(!err.contains("not calibrated"), "{err}");
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn the_live_page_warns_of_an_uncalibrated_bench() {
    use tokio::io::{AsyncBufReadExt, AsyncReadExt, AsyncWriteExt, BufReader};
    let lab = start_lab().await;
    // No trigger: the capture waits with RF on while the page is read.
    lab.bench.marker_cable.store(false, Ordering::Relaxed);
    let dir = tempfile::tempdir().unwrap();
    let bench = lab_bench_file(dir.path(), &lab);
    let out = dir.path().join("out");
    let mut child = tokio::process::Command::new(BIN)
        .args([
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
        ])
        .stdin(std::process::Stdio::null())
        .stdout(std::process::Stdio::piped())
        .stderr(std::process::Stdio::piped())
        .kill_on_drop(true)
        .spawn()
        .unwrap();
    let mut lines = BufReader::new(child.stdout.take().unwrap()).lines();
    let line = tokio::time::timeout(LIMIT, lines.next_line())
        .await
        .expect("the live event")
        .unwrap()
        .unwrap();
    let url: Value = serde_json::from_str(&line).unwrap();
    let url = url["url"].as_str().unwrap().to_string();
    let (addr, token) = url
        .trim_start_matches("http://")
        .split_once("/?token=")
        .unwrap();
    let request = |method: &str, target: String| {
        let (addr, method) = (addr.to_string(), method.to_string());
        async move {
            let mut s = tokio::net::TcpStream::connect(&addr).await.unwrap();
            let head =
                format!("{method} {target} HTTP/1.1\r\nHost: {addr}\r\nContent-Length: 0\r\n\r\n");
            s.write_all(head.as_bytes()).await.unwrap();
            let mut body = Vec::new();
            tokio::time::timeout(LIMIT, s.read_to_end(&mut body))
                .await
                .expect("an answer")
                .unwrap();
            String::from_utf8_lossy(&body).into_owned()
        }
    };
    let warned = |page: &str| page.contains("the bench is not calibrated");
    let poll = async {
        loop {
            let page = request("GET", format!("/state?token={token}")).await;
            if warned(&page) {
                return page;
            }
            tokio::time::sleep(Duration::from_millis(20)).await;
        }
    };
    let page = tokio::time::timeout(LIMIT, poll)
        .await
        .expect("the page shows the warning");
    assert!(page.contains("\"warning\""), "{page}");
    request("POST", format!("/stop?token={token}")).await;
    let end = tokio::time::timeout(LIMIT, child.wait())
        .await
        .expect("stopped")
        .unwrap();
    assert_eq!(end.code(), Some(130));
    assert!(safe(&lab));
}
