//! The Infiniium UXR through the same door as the LeCroy: capture, `process` of its saved files
//! (SigMF only: no `.trc`), `doctor` on the built-in lab with `--scope-model keysight-uxr`; a
//! short campaign on a lab serving the UXR; the doctor's fixes in the UXR's own words; and the
//! exit path of a capture left waiting for a trigger with RF on.

use crate::support::{radbench_in, signal, until};
use mock_lab::lab::{Lab, LabOptions};
use mock_lab::server::launch::Transport;
use serde_json::Value;
use std::path::Path;
use std::process::Stdio;
use std::sync::atomic::Ordering;
use std::time::Duration;

async fn radbench(args: &[&str]) -> (i32, String, String) {
    radbench_in(None, args).await
}

fn ranges(v: &Value) -> Vec<f64> {
    v["targets"]
        .as_array()
        .unwrap()
        .iter()
        .map(|t| t["range_m"].as_f64().unwrap())
        .collect()
}

async fn uxr_lab() -> Lab {
    tokio::time::timeout(
        Duration::from_secs(10),
        mock_lab::lab::start(LabOptions {
            scope_model: "keysight-uxr".parse().unwrap(),
            ..LabOptions::default()
        }),
    )
    .await
    .expect("lab starts")
    .expect("lab starts")
}

/// The accuracy campaign in `run`: six steps, each within 1 mm of the truth, none missed.
fn every_step_within_a_millimetre(run: &Path) {
    let results: Value =
        serde_json::from_str(&std::fs::read_to_string(run.join("results.json")).unwrap()).unwrap();
    let steps = results["steps"].as_array().unwrap();
    assert_eq!(steps.len(), 6);
    for s in steps {
        let a = &s["algorithms"]["correlation"];
        let truth = a["truth_error_m"].as_f64().unwrap_or_else(|| panic!("{s}"));
        assert!(truth.abs() < 1e-3, "interpolated error {truth} m");
        assert_eq!(a["missed"], 0);
    }
}

/// `lab`'s bench file, calibrated with the simulated cables' nominal delay (as the built-in lab
/// is).
fn bench_file(dir: &Path, lab: &Lab, scope: Transport) -> String {
    let path = dir.join("bench.toml");
    let delay = mock_lab::scene::Scene::default().system_delay_s;
    let text = format!(
        "{}\n[calibration]\nsystem_delay_s = {delay:e}\n",
        lab.bench_toml(Transport::Hislip, scope)
    );
    std::fs::write(&path, text).unwrap();
    path.display().to_string()
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn capture_process_and_doctor_on_the_built_in_lab_with_the_uxr() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("cap");
    let (code, stdout, err) = radbench(&[
        "capture",
        "--allow-rf",
        "--scope-model",
        "keysight-uxr",
        "--json",
        "--out",
        out.to_str().unwrap(),
    ])
    .await;
    assert_eq!(code, 0, "{err}");
    let v: Value = serde_json::from_str(&stdout).unwrap();
    let truth = v["scene"]["targets"][0]["range_m"].as_f64().unwrap();
    let found = ranges(&v);
    assert_eq!(found.len(), 1, "{found:?}");
    assert!((found[0] - truth).abs() < 1e-3, "{found:?} vs {truth}");
    assert_eq!(v["payload"]["bit_errors"], 0, "{}", v["payload"]);
    // The UXR path saves the SigMF recording and no `.trc`.
    let names: Vec<String> = std::fs::read_dir(&out)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    assert!(
        names.iter().any(|n| n.ends_with(".sigmf-data")),
        "{names:?}"
    );
    assert!(!names.iter().any(|n| n.ends_with(".trc")), "{names:?}");
    let meta = std::fs::read_to_string(out.join("capture.sigmf-meta")).unwrap();
    assert!(meta.contains("UXR0334A"), "the recording names its scope");

    // `process` of the saved capture gives the same range.
    let again_dir = dir.path().join("again");
    let (code, stdout, err) = radbench(&[
        "process",
        out.to_str().unwrap(),
        "--out",
        again_dir.to_str().unwrap(),
        "--json",
    ])
    .await;
    assert_eq!(code, 0, "{err}");
    let doc: Value = serde_json::from_str(&stdout).unwrap();
    let again = &doc["processed"][0]["summary"];
    let re = ranges(again);
    assert_eq!(re.len(), 1, "{again}");
    assert!((re[0] - found[0]).abs() < 1e-6, "{re:?} vs {found:?}");

    // The doctor checks the UXR as it checks the LeCroy.
    let (code, stdout, err) =
        radbench(&["doctor", "--scope-model", "keysight-uxr", "--json"]).await;
    assert_eq!(code, 0, "{stdout} {err}");
    let report: Value = serde_json::from_str(&stdout).unwrap();
    assert_eq!(report["ok"], true, "{report}");
    let marker = report["checks"]
        .as_array()
        .unwrap()
        .iter()
        .find(|c| c["id"] == "marker")
        .unwrap();
    assert_eq!(marker["status"], "pass", "{marker}");

    // Repetitions go to the UXR's segmented memory: one acquisition, one segment per trigger.
    let seq = dir.path().join("seq");
    let (code, stdout, err) = radbench(&[
        "capture",
        "--allow-rf",
        "--scope-model",
        "keysight-uxr",
        "--repetitions",
        "3",
        "--json",
        "--out",
        seq.to_str().unwrap(),
    ])
    .await;
    assert_eq!(code, 0, "{err}");
    let v: Value = serde_json::from_str(&stdout).unwrap();
    assert_eq!(v["applied"]["scope"]["segments"], 3, "{}", v["applied"]);
    let found = ranges(&v);
    assert_eq!(found.len(), 1, "{found:?}");
    assert!((found[0] - truth).abs() < 1e-3, "{found:?} vs {truth}");

    // With --bench the scope comes from the bench file: the option is refused.
    let (code, _, err) = radbench(&[
        "capture",
        "--allow-rf",
        "--bench",
        "no-such.toml",
        "--scope-model",
        "keysight-uxr",
    ])
    .await;
    assert_eq!(code, 2, "{err}");
    assert!(err.contains("--scope-model"), "{err}");
}

/// The check `id` of a doctor's JSON report.
fn doctor_check<'a>(report: &'a Value, id: &str) -> &'a Value {
    report["checks"]
        .as_array()
        .unwrap()
        .iter()
        .find(|c| c["id"] == id)
        .unwrap_or_else(|| panic!("no check {id} in {report:#}"))
}

/// The doctor's fixes name the UXR's own settings: its external reference is the Infiniium's
/// command, and a UXR that does not answer is not sent to the LeCroy's remote menu (it serves
/// HiSLIP and VXI-11 side by side: there is no interface to choose).
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn the_doctor_gives_the_uxr_its_own_hints() {
    let lab = uxr_lab().await;
    let dir = tempfile::tempdir().unwrap();
    let bench = bench_file(dir.path(), &lab, Transport::Hislip);

    // The lab runs on internal references: the timebases warn, with the Infiniium's setting.
    let (code, stdout, err) = radbench(&["doctor", "--bench", &bench, "--json"]).await;
    assert_eq!(code, 0, "{stdout} {err}");
    let report: Value = serde_json::from_str(&stdout).unwrap();
    let timebases = doctor_check(&report, "timebases");
    assert_eq!(timebases["status"], "warn", "{timebases}");
    let fix = timebases["fix"].as_str().unwrap();
    assert!(
        fix.contains("(Infiniium :TIMebase:REFClock ON)") && !fix.contains("LeCroy"),
        "{timebases}"
    );

    // Nothing answers at the scope's port.
    let closed = {
        let l = std::net::TcpListener::bind("127.0.0.1:0").unwrap();
        l.local_addr().unwrap().port()
    };
    let scope = lab.endpoint("scope", Transport::Hislip).unwrap().resource;
    let text = std::fs::read_to_string(&bench).unwrap();
    assert!(text.contains(&scope), "{text}");
    let silent = dir.path().join("silent.toml");
    std::fs::write(
        &silent,
        text.replace(
            &scope,
            &format!("TCPIP::127.0.0.1::hislip0,{closed}::INSTR"),
        ),
    )
    .unwrap();
    let (code, stdout, err) =
        radbench(&["doctor", "--bench", silent.to_str().unwrap(), "--json"]).await;
    assert_eq!(code, 3, "{stdout} {err}");
    let report: Value = serde_json::from_str(&stdout).unwrap();
    let remote = doctor_check(&report, "scope.remote_interface");
    assert_eq!(remote["status"], "fail", "{remote}");
    let fix = remote["fix"].as_str().unwrap();
    assert!(
        fix.contains("Infiniium application is running") && !fix.contains("Utilities"),
        "{remote}"
    );
    // An Infiniium serves its interfaces side by side: no other one is tried, or named.
    let detail = remote["detail"].as_str().unwrap();
    assert!(
        detail.contains("does not answer over HiSLIP") && !detail.contains("neither"),
        "{remote}"
    );
    assert!(lab.bench.is_safe(), "nothing left on");
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_short_campaign_on_a_uxr_bench_measures_within_a_millimetre() {
    let lab = uxr_lab().await;
    let dir = tempfile::tempdir().unwrap();
    let bench = bench_file(dir.path(), &lab, Transport::Vxi11);
    let spec = Path::new(env!("CARGO_MANIFEST_DIR")).join("examples/accuracy.toml");
    let run = dir.path().join("run");
    let (code, _, err) = radbench(&[
        "campaign",
        "run",
        spec.to_str().unwrap(),
        "--bench",
        &bench,
        "--allow-rf",
        "--out",
        run.to_str().unwrap(),
    ])
    .await;
    assert_eq!(code, 0, "{err}");
    every_step_within_a_millimetre(&run);
    assert!(lab.bench.is_safe(), "Tx off, outputs off, AWG stopped");
}

/// The bench file `mock-lab serve --scope-model keysight-uxr` prints (VICP asked for the scope,
/// which a UXR does not serve) names the scope on a transport it serves, and the doctor passes
/// on it: it named no scope at all before.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn the_printed_bench_file_of_a_uxr_lab_names_the_scope_and_the_doctor_passes() {
    let lab = uxr_lab().await;
    let dir = tempfile::tempdir().unwrap();
    let bench = bench_file(dir.path(), &lab, Transport::Vicp);
    let text = std::fs::read_to_string(&bench).unwrap();
    let file: toml::Value = toml::from_str(&text).unwrap();
    let scope = file["scope"]["resource"].as_str().unwrap();
    assert!(scope.starts_with("TCPIP"), "{text}");
    let (code, out, err) = radbench(&["doctor", "--bench", &bench, "--json"]).await;
    assert_eq!(code, 0, "{out}\n{err}");
}

/// The built-in lab serves the UXR when the spec's `[bench]` says `scope_model`; the manifest
/// names it, and its plan keeps it for a resume.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_campaign_on_the_built_in_lab_uses_the_uxr_its_spec_names() {
    let dir = tempfile::tempdir().unwrap();
    let original = Path::new(env!("CARGO_MANIFEST_DIR")).join("examples/accuracy.toml");
    let text = std::fs::read_to_string(original).unwrap();
    let spec = dir.path().join("uxr.toml");
    std::fs::write(
        &spec,
        text.replacen("[bench]\n", "[bench]\nscope_model = \"keysight-uxr\"\n", 1),
    )
    .unwrap();
    let run = dir.path().join("run");
    let (code, _, err) = radbench(&[
        "campaign",
        "run",
        spec.to_str().unwrap(),
        "--allow-rf",
        "--out",
        run.to_str().unwrap(),
    ])
    .await;
    assert_eq!(code, 0, "{err}");
    every_step_within_a_millimetre(&run);
    let manifest = std::fs::read_to_string(run.join("manifest.toml")).unwrap();
    assert!(
        manifest.contains("scope_model = \"keysight-uxr\""),
        "{manifest}"
    );
    assert!(manifest.contains("UXR"), "the scope's identity: {manifest}");
    // A scope model is the built-in lab's: with a bench file it is refused by name.
    let (code, _, err) = radbench(&[
        "campaign",
        "run",
        spec.to_str().unwrap(),
        "--bench",
        spec.to_str().unwrap(),
        "--dry-run",
    ])
    .await;
    assert_eq!(code, 2, "{err}");
    assert!(err.contains("bench.scope_model"), "{err}");
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_signal_while_rf_is_on_leaves_the_bench_safe_with_the_uxr() {
    let lab = uxr_lab().await;
    // No trigger reaches the scope: the capture waits with RF on until the signal.
    lab.bench.marker_cable.store(false, Ordering::Relaxed);
    let dir = tempfile::tempdir().unwrap();
    let bench = bench_file(dir.path(), &lab, Transport::Hislip);
    let child = tokio::process::Command::new(env!("CARGO_BIN_EXE_radbench"))
        .args(["capture", "--allow-rf", "--wait", "60", "--bench", &bench])
        .arg("--out")
        .arg(dir.path().join("out"))
        .stdin(Stdio::null())
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .kill_on_drop(true)
        .spawn()
        .unwrap();
    until("RF on", Duration::from_secs(60), || {
        lab.bench.tx.front_end().rf_enabled && lab.bench.awg.playback().running
    })
    .await;
    signal(&child, "TERM");
    let out = tokio::time::timeout(Duration::from_secs(60), child.wait_with_output())
        .await
        .expect("radbench ends within 60 s of the signal")
        .unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(143), "{err}");
    assert!(lab.bench.is_safe(), "Tx off, outputs off, AWG stopped");
    assert!(!lab.bench.rx.front_end().rf_enabled, "Rx off");
}

/// `radbench calibrate` (the system delay) and `calibrate response` on the built-in lab serving
/// the UXR (`--scope-model keysight-uxr`, the option capture, align and doctor share): the delay
/// is the simulated cables', the exchanges are the Infiniium's, the response names the UXR; and
/// the option is refused beside a bench file.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn calibrate_and_calibrate_response_on_the_built_in_lab_with_the_uxr() {
    let dir = tempfile::tempdir().unwrap();
    let journal = dir.path().join("journal.jsonl");
    let (code, stdout, err) = radbench(&[
        "--trace-io",
        journal.to_str().unwrap(),
        "calibrate",
        "--reference-range",
        "1.0",
        "--scope-model",
        "keysight-uxr",
        "--allow-rf",
        "--json",
    ])
    .await;
    assert_eq!(code, 0, "{err}");
    let v: Value = serde_json::from_str(&stdout).unwrap();
    let delay = v["system_delay_s"].as_f64().unwrap();
    let nominal = mock_lab::scene::Scene::default().system_delay_s;
    assert!(
        (delay - nominal).abs() < 10e-12,
        "delay {delay} vs {nominal}"
    );
    let exchanges = std::fs::read_to_string(&journal).unwrap();
    assert!(
        exchanges.contains(":WAV"),
        "the Infiniium's waveform commands"
    );
    assert!(!exchanges.contains("VBS"), "no LeCroy automation command");

    // The response, on a pillar at 1 m of the thesis lab's chain.
    std::fs::write(
        dir.path().join("reference.toml"),
        "seed = 3\nsnr_db = 25.0\n[[targets]]\nrange_m = 1.0\namplitude = 0.5\n\
         [chain]\npreset = \"thesis-lab\"\n",
    )
    .unwrap();
    let out = dir.path().join("response.toml");
    let (code, _, err) = radbench(&[
        "calibrate",
        "response",
        "--reference-range",
        "1.0",
        "--scene",
        dir.path().join("reference.toml").to_str().unwrap(),
        "--scope-model",
        "keysight-uxr",
        "--allow-rf",
        "--out",
        out.to_str().unwrap(),
        "--json",
    ])
    .await;
    assert_eq!(code, 0, "{err}");
    let header = std::fs::read_to_string(&out).unwrap();
    assert!(header.contains("UXR0334A"), "{header}");
    assert!(dir.path().join("response.npy").exists());

    // Beside a bench file the file names the scope: refused as bad input.
    let lab = uxr_lab().await;
    let bench = bench_file(dir.path(), &lab, Transport::Hislip);
    for args in [
        &["calibrate", "--reference-range", "1.0"][..],
        &["calibrate", "response", "--reference-range", "1.0"][..],
    ] {
        let mut args = args.to_vec();
        args.extend([
            "--bench",
            &bench,
            "--scope-model",
            "keysight-uxr",
            "--allow-rf",
        ]);
        let (code, _, err) = radbench(&args).await;
        assert_eq!(code, 2, "{args:?}: {err}");
        assert!(
            err.contains("--scope-model applies to the built-in mock lab only"),
            "{err}"
        );
    }
}
