//! `radbench capture` and `radbench calibrate` end to end: the radbench binary against a mock lab
//! over real loopback sockets, as a user would run them.

use mock_lab::emulator::lecroy::RemoteInterface;
use mock_lab::lab::{self, Lab, LabOptions};
use mock_lab::scene::{Scene, Target};
use mock_lab::server::launch::Transport;
use serde_json::Value;
use std::path::Path;
use std::process::Stdio;
use std::time::Duration;
use tokio::process::Command;

const BIN: &str = env!("CARGO_BIN_EXE_radbench");

fn scene(targets: &[(f64, f64)], snr_db: f64) -> Scene {
    Scene {
        targets: targets
            .iter()
            .map(|&(range_m, amplitude)| Target {
                range_m,
                amplitude,
                velocity_mps: 0.0,
            })
            .collect(),
        snr_db,
        // Not the default: calibration must find it.
        system_delay_s: 3.1e-9,
        ..Scene::default()
    }
}

async fn start(scene: Scene, scope: Transport) -> Lab {
    let options = LabOptions {
        scene,
        scope_remote: if scope == Transport::Vicp {
            RemoteInterface::Vicp
        } else {
            RemoteInterface::Vxi11
        },
        ..LabOptions::default()
    };
    tokio::time::timeout(Duration::from_secs(10), lab::start(options))
        .await
        .expect("lab starts")
        .expect("lab starts")
}

async fn radbench(args: &[&str]) -> (i32, String, String) {
    crate::support::radbench_in(None, args).await
}

async fn capture_json(args: &[&str]) -> Value {
    let mut all = vec!["capture", "--allow-rf", "--json"];
    all.extend_from_slice(args);
    let (code, out, err) = radbench(&all).await;
    assert_eq!(code, 0, "radbench {all:?} failed: {err}");
    serde_json::from_str(&out).unwrap_or_else(|e| panic!("not JSON ({e}): {out}"))
}

fn ranges(v: &Value) -> Vec<f64> {
    v["targets"]
        .as_array()
        .unwrap()
        .iter()
        .map(|t| t["range_m"].as_f64().unwrap())
        .collect()
}

fn write_bench(dir: &Path, lab: &Lab, awg: Transport, scope: Transport) -> String {
    let path = dir.join("bench.toml");
    std::fs::write(&path, lab.bench_toml(awg, scope)).unwrap();
    path.display().to_string()
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn calibrated_target_within_1mm_over_every_transport_and_waveform() {
    for (awg, scope) in [
        (Transport::Raw, Transport::Vicp),
        (Transport::Hislip, Transport::Vxi11),
    ] {
        let lab = start(scene(&[(1.0, 0.5)], 30.0), scope).await;
        let dir = tempfile::tempdir().unwrap();
        let bench = write_bench(dir.path(), &lab, awg, scope);
        let (code, out, err) = radbench(&[
            "calibrate",
            "--reference-range",
            "1.0",
            "--bench",
            &bench,
            "--allow-rf",
            "--json",
        ])
        .await;
        assert_eq!(code, 0, "calibrate over {awg:?}/{scope:?}: {err}");
        let cal: Value = serde_json::from_str(&out).unwrap();
        let delay = cal["system_delay_s"].as_f64().unwrap();
        assert!((delay - 3.1e-9).abs() < 10e-12, "delay {delay}");
        assert!(std::fs::read_to_string(&bench)
            .unwrap()
            .contains("[calibration]"));

        // Move the target and measure it.
        let reply = lab
            .bench
            .scene
            .apply(r#"{"cmd":"move","target":0,"range_m":1.7234}"#);
        assert_eq!(reply["ok"], true);
        for waveform in ["msk-lfm", "ofdm"] {
            let out_dir = dir.path().join(waveform);
            let v = capture_json(&[
                "--bench",
                &bench,
                "--waveform",
                waveform,
                "--out",
                out_dir.to_str().unwrap(),
            ])
            .await;
            let found = ranges(&v);
            assert_eq!(
                found.len(),
                1,
                "{waveform} over {awg:?}/{scope:?}: {found:?}"
            );
            let error_mm = (found[0] - 1.7234) * 1e3;
            assert!(
                error_mm.abs() < 1.0,
                "{waveform} over {awg:?}/{scope:?}: error {error_mm} mm"
            );
            assert_eq!(v["scene"]["targets"][0]["range_m"], 1.7234);
            // The processing is recorded, with the calibration it used, in both records.
            assert_eq!(v["processing"]["system_delay_s"], cal["system_delay_s"]);
            assert_eq!(v["processing"]["zero_pad"], 10);
            let meta: Value = serde_json::from_str(
                &std::fs::read_to_string(v["files"]["sigmf_meta"].as_str().unwrap()).unwrap(),
            )
            .unwrap();
            assert_eq!(meta["global"]["radbench:processing"], v["processing"]);
            for key in [
                "sigmf_meta",
                "sigmf_data",
                "profile_npy",
                "profile_csv",
                "plot_svg",
                "plot_png",
            ] {
                let f = v["files"][key].as_str().unwrap();
                assert!(Path::new(f).is_file(), "{key}: {f}");
            }
        }
    }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn two_targets_30_cm_apart_and_music_at_6_cm() {
    let dir = tempfile::tempdir().unwrap();
    let scene_file = dir.path().join("scene.toml");
    std::fs::write(
        &scene_file,
        "snr_db = 40.0\n[[targets]]\nrange_m = 1.0\n[[targets]]\nrange_m = 1.3\n",
    )
    .unwrap();
    let s = scene_file.to_str().unwrap();
    let out = dir.path().join("a");
    let v = capture_json(&["--scene", s, "--out", out.to_str().unwrap()]).await;
    let found = ranges(&v);
    assert_eq!(found.len(), 2, "{found:?}");
    assert!(
        (found[0] - 1.0).abs() < 0.03 && (found[1] - 1.3).abs() < 0.03,
        "{found:?}"
    );

    std::fs::write(
        &scene_file,
        "snr_db = 40.0\n[[targets]]\nrange_m = 1.0\n[[targets]]\nrange_m = 1.06\n",
    )
    .unwrap();
    let out = dir.path().join("b");
    let v = capture_json(&[
        "--scene",
        s,
        "--waveform",
        "ofdm",
        "--algorithm",
        "music",
        "--out",
        out.to_str().unwrap(),
    ])
    .await;
    let found = ranges(&v);
    assert_eq!(found.len(), 2, "{found:?}");
    assert!(
        (found[0] - 1.0).abs() < 0.005 && (found[1] - 1.06).abs() < 0.005,
        "{found:?}"
    );
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn payload_round_trips_on_both_waveforms() {
    let dir = tempfile::tempdir().unwrap();
    for waveform in ["msk-lfm", "ofdm"] {
        let out = dir.path().join(waveform);
        let v = capture_json(&[
            "--waveform",
            waveform,
            "--payload",
            "joint radar-comms at 80 GHz",
            "--out",
            out.to_str().unwrap(),
        ])
        .await;
        assert_eq!(
            v["payload"]["text"], "joint radar-comms at 80 GHz",
            "{waveform}"
        );
        assert_eq!(v["payload"]["bit_errors"], 0, "{waveform}");
    }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn transmitter_off_finds_no_target_and_says_why() {
    let dir = tempfile::tempdir().unwrap();
    let v = capture_json(&["--tx-off", "--out", dir.path().to_str().unwrap()]).await;
    assert!(ranges(&v).is_empty(), "{v}");
    let warning = v["warnings"][0].as_str().unwrap();
    assert!(
        warning.contains("noise") && warning.contains("transmitter"),
        "{warning}"
    );
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn bad_input_exits_2_and_names_the_field() {
    let (code, _, err) = radbench(&["capture"]).await;
    assert_eq!(code, 2, "{err}");
    assert!(err.contains("--allow-rf"), "{err}");
    let dir = tempfile::tempdir().unwrap();
    let bench = dir.path().join("bench.toml");
    std::fs::write(&bench, "[awg]\nmodel = \"keysight-m8195a\"\nresource = \"TCPIP::x\"\n[scope]\nmodel = \"x\"\nresource = \"VICP::h\"\n").unwrap();
    let (code, _, err) =
        radbench(&["capture", "--allow-rf", "--bench", bench.to_str().unwrap()]).await;
    assert_eq!(code, 2, "{err}");
    assert!(err.contains("[awg] resource"), "{err}");
    let (code, _, err) = radbench(&[
        "capture",
        "--allow-rf",
        "--waveform",
        "msk-lfm",
        "--algorithm",
        "music",
    ])
    .await;
    assert_eq!(code, 2, "{err}");
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn interrupted_capture_leaves_the_bench_safe() {
    let lab = start(scene(&[(1.0, 0.5)], 30.0), Transport::Vicp).await;
    // No trigger ever reaches the scope: the capture waits until interrupted.
    lab.bench
        .marker_cable
        .store(false, std::sync::atomic::Ordering::Relaxed);
    let dir = tempfile::tempdir().unwrap();
    let bench = write_bench(dir.path(), &lab, Transport::Hislip, Transport::Vicp);
    let mut child = Command::new(BIN)
        .args(["capture", "--allow-rf", "--wait", "60", "--bench", &bench])
        .arg("--out")
        .arg(dir.path().join("out"))
        .stdin(Stdio::null())
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .kill_on_drop(true)
        .spawn()
        .unwrap();
    // Wait (bounded) until the transmitter radiates and the AWG runs: the capture is half-way.
    let half_way = async {
        loop {
            if lab.bench.tx.front_end().rf_enabled && lab.bench.awg.playback().running {
                return;
            }
            tokio::time::sleep(Duration::from_millis(20)).await;
        }
    };
    tokio::time::timeout(Duration::from_secs(60), half_way)
        .await
        .expect("the capture switches RF on");
    assert!(!lab.bench.is_safe());
    let pid = child.id().unwrap().to_string();
    let signal = Command::new("kill")
        .args(["-INT", &pid])
        .kill_on_drop(true)
        .status();
    let status = tokio::time::timeout(Duration::from_secs(30), signal)
        .await
        .expect("kill ends within 30 s")
        .unwrap();
    assert!(status.success());
    let status = tokio::time::timeout(Duration::from_secs(30), child.wait())
        .await
        .expect("radbench stops within 30 s of Ctrl-C")
        .unwrap();
    assert_eq!(status.code(), Some(130));
    assert!(lab.bench.is_safe(), "Tx off, outputs off, AWG stopped");
    assert!(!lab.bench.rx.front_end().rf_enabled);
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn background_subtraction_leaves_only_what_changed() {
    let lab = start(scene(&[(1.0, 0.5)], 30.0), Transport::Vicp).await;
    let dir = tempfile::tempdir().unwrap();
    let bench = write_bench(dir.path(), &lab, Transport::Raw, Transport::Vicp);
    let empty = dir.path().join("empty");
    let v = capture_json(&["--bench", &bench, "--out", empty.to_str().unwrap()]).await;
    // Uncalibrated, the Tx -> Rx leakage (0.2 ns + the 3.1 ns system delay) is an echo at
    // 0.495 m, inside the default range window: it is reported, as the real echo it is.
    let offset = 3.1e-9 * 299_792_458.0 / 2.0;
    let found = ranges(&v);
    assert_eq!(found.len(), 2, "{found:?}");
    assert!((found[0] - (0.03 + offset)).abs() < 0.01, "{found:?}");
    assert!((found[1] - (1.0 + offset)).abs() < 0.01, "{found:?}");
    let reply = lab
        .bench
        .scene
        .apply(r#"{"cmd":"add","target":{"range_m":2.2,"amplitude":0.3}}"#);
    assert_eq!(reply["ok"], true);
    let background = v["files"]["sigmf_meta"].as_str().unwrap().to_string();
    let out = dir.path().join("with");
    let v = capture_json(&[
        "--bench",
        &bench,
        "--background",
        &background,
        "--out",
        out.to_str().unwrap(),
    ])
    .await;
    let found = ranges(&v);
    // Uncalibrated: ranges carry the system delay (3.1 ns = 0.465 m).
    assert_eq!(found.len(), 1, "only the new target remains: {found:?}");
    assert!((found[0] - (2.2 + offset)).abs() < 0.01, "{found:?}");
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn the_chain_floor_keeps_a_thesis_lab_echo_in_its_pillar_and_can_be_turned_off() {
    let dir = tempfile::tempdir().unwrap();
    let scene_file = dir.path().join("scene.toml");
    std::fs::write(
        &scene_file,
        "snr_db = 30.0\n[[targets]]\nrange_m = 2.0\n[chain]\npreset = \"thesis-lab\"\n",
    )
    .unwrap();
    let s = scene_file.to_str().unwrap();
    let out = dir.path().join("a");
    let v = capture_json(&["--scene", s, "--out", out.to_str().unwrap()]).await;
    assert_eq!(ranges(&v).len(), 1, "{}", v["targets"]);
    assert_eq!(v["processing"]["chain_floor_db"], -17.0);
    // Off: the chain's echo 1.43 ns behind the pillar (+0.21 m) is reported as a target.
    let out = dir.path().join("b");
    let v = capture_json(&[
        "--scene",
        s,
        "--chain-floor-db",
        "-200",
        "--out",
        out.to_str().unwrap(),
    ])
    .await;
    let found = ranges(&v);
    assert!(
        found.len() >= 2 && found.iter().any(|r| (r - 2.21).abs() < 0.02),
        "{found:?}"
    );
    // `process` takes it too, and a floor above 0 dB is refused by name.
    let (code, _, err) =
        radbench(&["process", out.to_str().unwrap(), "--chain-floor-db", "3"]).await;
    assert_eq!(code, 2, "{err}");
    assert!(err.contains("chain_floor_db"), "{err}");
}

/// A simulated target beyond `--max-range` is not searched, and the capture says so.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_scene_target_outside_the_range_window_is_named() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    std::fs::write(
        d.join("far.toml"),
        "snr_db = 30.0\n[[targets]]\nrange_m = 1.0\namplitude = 0.3\n\
         [[targets]]\nrange_m = 9.0\namplitude = 0.3\n",
    )
    .unwrap();
    let (code, out, err) = crate::support::radbench_in(
        Some(d),
        &[
            "capture",
            "--allow-rf",
            "--scene",
            "far.toml",
            "--max-range",
            "5",
            "--json",
        ],
    )
    .await;
    assert_eq!(code, 0, "{err}");
    let s: serde_json::Value = serde_json::from_str(&out).unwrap();
    let warnings = s["warnings"].to_string();
    assert!(
        warnings.contains("9.000 m outside the range window"),
        "{warnings}"
    );
}

/// An OFDM target at 300 m/s: its velocity is on the console, and the failed decoding is a
/// warning that names it (was only a BER of 0.5 in the output).
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_fast_target_that_spoils_the_data_is_named() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    std::fs::write(
        d.join("moving.toml"),
        "snr_db = 30.0\n[[targets]]\nrange_m = 1.0\namplitude = 0.5\nvelocity_mps = 300.0\n",
    )
    .unwrap();
    let (code, out, err) = crate::support::radbench_in(
        Some(d),
        &[
            "capture",
            "--allow-rf",
            "--scene",
            "moving.toml",
            "--waveform",
            "ofdm",
        ],
    )
    .await;
    assert_eq!(code, 0, "{err}");
    assert!(out.contains("+300.0 m/s"), "{out}");
    assert!(
        out.contains("warning: the data did not decode") && out.contains("moves at +300.0 m/s"),
        "{out}"
    );
}

/// A background file whose trigger offset is 1e300 s (damaged or edited) is refused by its key
/// (exit 2), before anything radiates; it used to be accepted.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_background_with_an_absurd_trigger_offset_is_refused() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let (code, _, err) = crate::support::radbench_in(
        Some(d),
        &["capture", "--allow-rf", "--tx-off", "--out", "bg"],
    )
    .await;
    assert_eq!(code, 0, "{err}");
    let meta_path = d.join("bg/capture.sigmf-meta");
    let mut meta: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&meta_path).unwrap()).unwrap();
    let global = &mut meta["global"];
    if global["radbench:repetitions"].is_array() {
        global["radbench:repetitions"][0]["trigger_offset_s"] = serde_json::json!(1e300);
    }
    global["radbench:trigger_offset_s"] = serde_json::json!(1e300);
    std::fs::write(&meta_path, meta.to_string()).unwrap();
    let (code, _, err) = crate::support::radbench_in(
        Some(d),
        &[
            "capture",
            "--allow-rf",
            "--background",
            "bg/capture.sigmf-meta",
            "--out",
            "c",
        ],
    )
    .await;
    assert_eq!(code, 2, "{err}");
    assert!(
        err.contains("trigger_offset_s") && err.contains("1e300"),
        "{err}"
    );
}
