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
