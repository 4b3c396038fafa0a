//! EVM and MER of the decoded data on the mock lab: OFDM's MER is what the scene's SNR predicts
//! (within 0.5 dB), MSK-LFM's figures and both waveforms' link plots are written, and
//! `summary.json` carries them.

use serde_json::Value;
use std::path::Path;

/// One pillar (amplitude 1) at 1.5 m, no leakage, the ideal chain, `snr_db`.
fn scene(dir: &Path, snr_db: f64) -> String {
    let path = dir.join(format!("scene-{snr_db}.toml"));
    std::fs::write(
        &path,
        format!(
            "snr_db = {snr_db}\nseed = 3\n[[targets]]\nrange_m = 1.5\namplitude = 1.0\n\
             [leakage]\namplitude = 0.0\ndelay_s = 0.2e-9\n"
        ),
    )
    .unwrap();
    path.display().to_string()
}

async fn capture(dir: &Path, waveform: &str, scene: &str, out: &str) -> Value {
    let out = dir.join(out).display().to_string();
    let (code, stdout, err) = crate::support::radbench_in(
        None,
        &[
            "capture",
            "--allow-rf",
            "--json",
            "--waveform",
            waveform,
            "--scene",
            scene,
            "--out",
            &out,
        ],
    )
    .await;
    assert_eq!(code, 0, "{err}");
    let v: Value = serde_json::from_str(&stdout).unwrap();
    for key in ["link_svg", "link_png"] {
        let f = v["files"][key]
            .as_str()
            .unwrap_or_else(|| panic!("{key}: {v}"));
        assert!(Path::new(f).is_file(), "{f}");
    }
    let summary: Value = serde_json::from_str(
        &std::fs::read_to_string(Path::new(&out).join("summary.json")).unwrap(),
    )
    .unwrap();
    assert_eq!(summary["payload"]["mer_db"], v["payload"]["mer_db"]);
    v
}

/// The MER the scene predicts for OFDM: the SNR per complex sample at the capture rate
/// (80 GSa/s) of a unit-amplitude target, times the capture rate over the occupied band (128
/// subcarriers of 7.8125 MHz: 1 GHz), divided by 1 + 1/P for the channel estimated from P = 1
/// preamble symbol (its noise enters every equalised symbol).
fn predicted_ofdm_mer_db(snr_db: f64) -> f64 {
    snr_db + 10.0 * (80e9_f64 / 1e9).log10() - 10.0 * 2f64.log10()
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn ofdm_evm_matches_the_scenes_snr_and_msk_lfm_reports_its_own() {
    let tmp = tempfile::tempdir().unwrap();
    for snr_db in [0.0, 10.0] {
        let v = capture(
            tmp.path(),
            "ofdm",
            &scene(tmp.path(), snr_db),
            &format!("ofdm{snr_db}"),
        )
        .await;
        let p = &v["payload"];
        let mer = p["mer_db"].as_f64().unwrap();
        let predicted = predicted_ofdm_mer_db(snr_db);
        assert!(
            (mer - predicted).abs() < 0.5,
            "SNR {snr_db} dB: MER {mer:.2} dB, predicted {predicted:.2} dB"
        );
        let evm = p["evm_rms_pct"].as_f64().unwrap();
        assert!((evm - 100.0 * 10f64.powf(-mer / 20.0)).abs() < 1e-9 * evm.max(1.0));
        let p95 = p["evm_p95_pct"].as_f64().unwrap();
        // Gaussian error vectors: the 95th percentile is sqrt(ln 20) = 1.73 times the rms.
        assert!((p95 / evm - 1.731).abs() < 0.08, "{p95} / {evm}");
    }
    // MSK-LFM: EVM and MER of its (I, Q) symbol pairs; at 30 dB the matched filter's gain puts
    // the MER far above the OFDM's (the AWG's 8-bit codes limit it on the mock lab).
    let v = capture(tmp.path(), "msk-lfm", &scene(tmp.path(), 30.0), "msk").await;
    let p = &v["payload"];
    assert_eq!(p["bit_errors"], 0);
    let mer = p["mer_db"].as_f64().unwrap();
    assert!(mer > 40.0, "{v}");
    assert!(p["evm_rms_pct"].as_f64().unwrap() < 1.0);
}

/// MSK-LFM's MER from the scene's SNR: each soft value is a matched filter over one bit's
/// samples at the capture rate (80 GSa/s x 10 us / 128 bits = 6250), whose real part keeps half
/// of the complex noise: 2 x 6250 times the SNR per complex sample. The lab's own floor (the
/// AWG's 8-bit codes and the chain, about 51 dB, measured on a noiseless scene) adds its error
/// power to it.
fn predicted_msk_lfm_mer_db(snr_db: f64, floor_db: f64) -> f64 {
    let noise_db = snr_db + 10.0 * (2.0 * 80e9 * 10e-6 / 128.0_f64).log10();
    -10.0 * (10f64.powf(-noise_db / 10.0) + 10f64.powf(-floor_db / 10.0)).log10()
}

/// One MSK-LFM capture of a mock lab whose scene is `snr_db` (seeded), the scope at 0.5 V/div
/// so that noise 10 dB above the echo does not clip its ADC (the default 50 mV/div clips below
/// ~10 dB SNR); the capture's `payload`.
async fn msk_lfm_on_lab(dir: &Path, snr_db: f64) -> Value {
    let text = std::fs::read_to_string(scene(dir, snr_db)).unwrap();
    let lab = tokio::time::timeout(
        std::time::Duration::from_secs(10),
        mock_lab::lab::start(mock_lab::lab::LabOptions {
            scene: mock_lab::scene::Scene::from_toml(&text, "scene").unwrap(),
            ..mock_lab::lab::LabOptions::default()
        }),
    )
    .await
    .expect("lab starts")
    .expect("lab starts");
    use mock_lab::server::launch::Transport;
    let bench = lab.bench_toml(Transport::Hislip, Transport::Vicp).replacen(
        "[scope]\n",
        "[scope]\nvolts_per_div = 0.5\n",
        1,
    );
    let bench_path = dir.join(format!("bench-{snr_db}.toml"));
    std::fs::write(&bench_path, bench).unwrap();
    let out = dir.join(format!("msk-{snr_db}")).display().to_string();
    let (code, stdout, err) = crate::support::radbench_in(
        None,
        &[
            "capture",
            "--allow-rf",
            "--json",
            "--waveform",
            "msk-lfm",
            "--bench",
            bench_path.to_str().unwrap(),
            "--out",
            &out,
        ],
    )
    .await;
    assert_eq!(code, 0, "{err}");
    let v: Value = serde_json::from_str(&stdout).unwrap();
    assert_eq!(
        v["clipped_samples"]["fraction"].as_f64(),
        Some(0.0),
        "SNR {snr_db} dB: the scope clipped: {}",
        v["clipped_samples"]
    );
    v["payload"].clone()
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn msk_lfm_evm_matches_the_scenes_snr() {
    let tmp = tempfile::tempdir().unwrap();
    // The floor: the same lab and scope setting without noise to speak of.
    let floor = msk_lfm_on_lab(tmp.path(), 60.0).await["mer_db"]
        .as_f64()
        .unwrap();
    assert!((45.0..60.0).contains(&floor), "floor {floor:.2} dB");
    for snr_db in [-5.0, 0.0, 5.0] {
        let p = msk_lfm_on_lab(tmp.path(), snr_db).await;
        assert_eq!(p["bit_errors"], 0, "SNR {snr_db} dB: {p}");
        let mer = p["mer_db"].as_f64().unwrap();
        let predicted = predicted_msk_lfm_mer_db(snr_db, floor);
        assert!(
            (mer - predicted).abs() < 0.5,
            "SNR {snr_db} dB: MER {mer:.2} dB, predicted {predicted:.2} dB (floor {floor:.2})"
        );
        let evm = p["evm_rms_pct"].as_f64().unwrap();
        assert!((evm - 100.0 * 10f64.powf(-mer / 20.0)).abs() < 1e-9 * evm.max(1.0));
        let p95 = p["evm_p95_pct"].as_f64().unwrap();
        assert!(p95 > evm, "{p95} / {evm}");
    }
}
