//! Detection on the realistic chain with the chain's response calibrated and corrected: the
//! measured point spread route of issue 21 ("use a measured point spread where a calibration
//! exists"). One calibration per waveform on a reference pillar, then seeded random scenes with
//! every impairment of the realistic bench, captured with `--calibration`.

use super::scenes::{random_pillars_within, realistic_scene, scene};
use super::support::radbench_in;
use radbench::rng::SplitMix64;
use serde_json::json;
use serde_json::Value;
use std::path::Path;

/// 6 scenes per waveform in CI; `RB_SCENES=75` for the figure in docs/calibration.md.
fn scenes_per_waveform() -> u64 {
    std::env::var("RB_SCENES")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(6)
}

async fn run(dir: &Path, args: &[&str]) -> Value {
    let (code, out, err) = radbench_in(Some(dir), args).await;
    assert_eq!(code, 0, "{args:?}: {err}");
    serde_json::from_str(&out).unwrap_or_else(|e| panic!("{e}: {out}"))
}

/// Every pillar found within 1 cm and nothing else; otherwise what was found, missing and false.
fn within_1_cm(pillars: &[(f64, f64)], targets: &Value) -> Option<String> {
    let found: Vec<f64> = targets
        .as_array()
        .unwrap()
        .iter()
        .map(|t| t["range_m"].as_f64().unwrap())
        .collect();
    let missing: Vec<f64> = pillars
        .iter()
        .map(|p| p.0)
        .filter(|r| !found.iter().any(|f| (f - r).abs() <= 0.01))
        .collect();
    let extra: Vec<f64> = found
        .iter()
        .copied()
        .filter(|f| !pillars.iter().any(|p| (f - p.0).abs() <= 0.01))
        .collect();
    (!missing.is_empty() || !extra.is_empty()).then(|| {
        format!("pillars {pillars:?}, found {found:?} (missing {missing:?}, false {extra:?})")
    })
}

fn write(dir: &Path, name: &str, scene: &Value) -> String {
    std::fs::write(dir.join(name), toml::to_string(scene).unwrap()).unwrap();
    name.to_string()
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn corrected_random_thesis_lab_scenes_every_pillar_within_1_cm_and_no_false_target() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let mut rng = SplitMix64::new(0xCA1);
    let mut reference = scene(&[(2.0, 0.5)], 25.0, 7);
    reference["chain"] = serde_json::json!({"preset": "thesis-lab"});
    let reference = write(d, "reference.toml", &reference);
    let mut failures = Vec::new();
    for waveform in ["msk-lfm", "ofdm"] {
        let cal = format!("{waveform}-response.toml");
        run(
            d,
            &[
                "calibrate",
                "response",
                "--reference-range",
                "2.0",
                "--scene",
                &reference,
                "--allow-rf",
                "--waveform",
                waveform,
                "--out",
                &cal,
                "--json",
            ],
        )
        .await;
        for k in 0..scenes_per_waveform() {
            let pillars = random_pillars_within(&mut rng, 3, 15.0);
            let s = realistic_scene(&pillars, &mut rng, 300 + k);
            let file = write(d, &format!("s{k}.toml"), &s);
            let out = format!("c-{waveform}-{k}");
            let c = run(
                d,
                &[
                    "capture",
                    "--allow-rf",
                    "--scene",
                    &file,
                    "--waveform",
                    waveform,
                    "--calibration",
                    &cal,
                    "--json",
                    "--out",
                    &out,
                ],
            )
            .await;
            if let Some(wrong) = within_1_cm(&pillars, &c["targets"]) {
                failures.push(format!("{waveform} scene {k}: {wrong}"));
            }
        }
    }
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}

/// A lab's IF cable: an echo 6-20 ns behind every path, -25 to -40 dB, the same for the
/// calibration and the captures (it is the bench's).
fn cable_chain(rng: &mut SplitMix64) -> Value {
    json!({
        "preset": "thesis-lab",
        "cable_echo_ns": 6.0 + 14.0 * rng.uniform(),
        "cable_echo_db": -25.0 - 15.0 * rng.uniform(),
        "cable_echo_phase_deg": 360.0 * rng.uniform(),
    })
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_cable_echo_and_a_1_m_reference_every_pillar_within_1_cm_no_false_target_any_window() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let mut rng = SplitMix64::new(0xCAB1E);
    let mut failures = Vec::new();
    for waveform in ["msk-lfm", "ofdm"] {
        let chain = cable_chain(&mut rng);
        let mut reference = scene(&[(1.0, 0.5)], 25.0, 7);
        reference["chain"] = chain.clone();
        reference["leakage"] =
            json!({"amplitude": 0.5 * 10f64.powf(-26.0 / 20.0), "delay_s": 0.2e-9});
        let reference = write(d, "reference.toml", &reference);
        let cal = format!("{waveform}-response.toml");
        run(
            d,
            &[
                "calibrate",
                "response",
                "--reference-range",
                "1.0",
                "--scene",
                &reference,
                "--allow-rf",
                "--waveform",
                waveform,
                "--out",
                &cal,
                "--json",
            ],
        )
        .await;
        for k in 0..scenes_per_waveform() {
            let pillars = random_pillars_within(&mut rng, 3, 15.0);
            let mut s = realistic_scene(&pillars, &mut rng, 500 + k);
            s["chain"] = chain.clone();
            let file = write(d, &format!("cable{k}.toml"), &s);
            let out = format!("cable-{waveform}-{k}");
            run(
                d,
                &[
                    "capture",
                    "--allow-rf",
                    "--scene",
                    &file,
                    "--waveform",
                    waveform,
                    "--calibration",
                    &cal,
                    "--json",
                    "--out",
                    &out,
                ],
            )
            .await;
            for window in ["rect", "taylor"] {
                let p = run(
                    d,
                    &[
                        "process",
                        &out,
                        "--window",
                        window,
                        "--json",
                        "--out",
                        &format!("{out}-{window}"),
                    ],
                )
                .await;
                let targets = &p["processed"][0]["summary"]["targets"];
                if let Some(wrong) = within_1_cm(&pillars, targets) {
                    failures.push(format!(
                        "{waveform} {window} scene {k} (cable {chain}): {wrong}"
                    ));
                }
            }
        }
    }
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}
