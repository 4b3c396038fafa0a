//! `radbench simulate run --scene FILE`: the built-in mock lab's capture of a scene, simulated
//! in-process, gives the detections `radbench capture --allow-rf --scene FILE` gives (impairments
//! and `[chain]` included), and on seeded random scenes of the realistic `thesis-lab` chain
//! every pillar within 1 cm and no false target.
//!
//! The random scenes are drawn as tests/cli/detect_capture.rs draws its realistic ones (its
//! helpers are private to that suite, so the few lines are repeated here).

use super::scenes::{random_pillars_within, realistic_scene, scene};
use crate::support::radbench_in;
use radbench::catalog::Catalog;
use radbench::driver::RfPermit;
use radbench::measure::Interrupt;
use radbench::measure::ProcessOptions;
use radbench::measure::{prepare, Rig};
use radbench::measure::{Bench, BenchSource, BuiltIn};
use radbench::rng::SplitMix64;
use radbench::waveform::WaveformKind;
use serde_json::{json, Value};
use std::path::Path;

const WAVEFORMS: [&str; 2] = ["msk-lfm", "ofdm"];

/// Writes `scene` as a scene file (TOML, checked by mock_lab's own reader) into `dir`.
fn scene_file(dir: &Path, name: &str, scene: &Value) -> String {
    let scene: mock_lab::scene::Scene = serde_json::from_value(scene.clone()).unwrap();
    let text = toml::to_string(&scene).unwrap();
    mock_lab::scene::Scene::from_toml(&text, name).expect("the scene file reads back");
    let path = dir.join(name);
    std::fs::write(&path, text).unwrap();
    path.to_str().unwrap().to_string()
}

/// Runs radbench with `args` and returns its JSON (the run must succeed).
async fn json_of(args: &[&str]) -> Value {
    let (code, out, err) = radbench_in(None, args).await;
    assert_eq!(code, 0, "radbench {args:?}: exit {code}: {err}");
    serde_json::from_str(&out)
        .unwrap_or_else(|e| panic!("radbench {args:?}: not JSON ({e}): {out}"))
}

/// `simulate run --scene FILE --waveform W --json`: its one scenario.
async fn simulated(scene: &str, waveform: &str, extra: &[&str]) -> Value {
    let mut args = vec![
        "simulate",
        "run",
        "--scene",
        scene,
        "--waveform",
        waveform,
        "--json",
    ];
    args.extend_from_slice(extra);
    json_of(&args).await["scenarios"][0].clone()
}

/// `(range_m, level_db)` of every detection of a `targets` array.
fn detections(targets: &Value) -> Vec<(f64, f64)> {
    targets
        .as_array()
        .expect("a targets array")
        .iter()
        .map(|t| {
            (
                t["range_m"].as_f64().unwrap(),
                t["level_db"].as_f64().unwrap(),
            )
        })
        .collect()
}

/// Every pillar found within 1 cm and nothing else.
fn every_pillar_and_nothing_else(found: &[f64], pillars: &[(f64, f64)], what: &str) {
    assert_eq!(
        found.len(),
        pillars.len(),
        "{what}: found {found:?} for pillars {pillars:?}"
    );
    for (r, _) in pillars {
        assert!(
            found.iter().any(|f| (f - r).abs() < 0.01),
            "{what}: pillar at {r} m not found within 10 mm: {found:?}"
        );
    }
}

/// The same scene and seed through the mock lab's instruments and through the simulation: the
/// same samples, so the same detections. The comparison allows 1e-9 m and 1e-9 dB (the
/// simulation reproduces the scope's words exactly; the margin is only for the JSON's decimal
/// round trip).
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn simulate_and_capture_of_an_impaired_thesis_lab_scene_detect_the_same_targets() {
    let dir = tempfile::tempdir().unwrap();
    // Two pillars (the 2.5574 m / 3.3452 m pair), clutter at both ends, stronger
    // leakage, every receiver impairment, on the realistic chain.
    let mut s = scene(&[(2.5574, 0.5), (3.3452, 0.1141)], 25.0, 21);
    s["chain"] = json!({"preset": "thesis-lab"});
    s["leakage"] = json!({"amplitude": 0.025, "delay_s": 0.2e-9});
    s["clutter"] = json!([
        {"range_m": 0.03, "amplitude": 0.03},
        {"range_m": 12.5, "amplitude": 0.1},
    ]);
    s["impairments"] = json!({
        "dc_offset_v": [0.003, -0.002],
        "iq_gain_db": 0.5,
        "iq_phase_deg": -3.5,
        "phase_noise_linewidth_hz": 1500.0,
    });
    s["trigger_jitter_s"] = json!(3e-12);
    let path = scene_file(dir.path(), "impaired.toml", &s);
    for waveform in WAVEFORMS {
        let out = dir.path().join(format!("capture-{waveform}"));
        let captured = json_of(&[
            "capture",
            "--allow-rf",
            "--scene",
            &path,
            "--waveform",
            waveform,
            "--seed",
            "4",
            "--out",
            out.to_str().unwrap(),
            "--json",
        ])
        .await;
        let sim = simulated(&path, waveform, &["--seed", "4"]).await;
        let (a, b) = (
            detections(&captured["targets"]),
            detections(&sim["targets"]),
        );
        assert_eq!(
            a.len(),
            b.len(),
            "{waveform}: capture {a:?}, simulate {b:?}"
        );
        assert!(!a.is_empty(), "{waveform}: nothing detected");
        for ((ra, la), (rb, lb)) in a.iter().zip(&b) {
            assert!(
                (ra - rb).abs() <= 1e-9 && (la - lb).abs() <= 1e-9,
                "{waveform}: capture {a:?}, simulate {b:?}"
            );
        }
        // The same samples: every figure of every detection, and the ADC's rails, agree.
        assert_eq!(captured["targets"], sim["targets"], "{waveform}");
        assert_eq!(
            captured["clipped_samples"], sim["clipped_samples"],
            "{waveform}"
        );
        assert_eq!(captured["width_3db_cm"], sim["width_3db_cm"], "{waveform}");
        assert_eq!(captured["sidelobe_db"], sim["sidelobe_db"], "{waveform}");
        assert_eq!(captured["warnings"], sim["warnings"], "{waveform}");
        let truth: Vec<f64> = captured["scene"]["targets"]
            .as_array()
            .unwrap()
            .iter()
            .map(|t| t["range_m"].as_f64().unwrap())
            .collect();
        assert_eq!(sim["targets_m"], json!(truth), "{waveform}");
        every_pillar_and_nothing_else(
            &sim["detected_m"]
                .as_array()
                .unwrap()
                .iter()
                .map(|v| v.as_f64().unwrap())
                .collect::<Vec<_>>(),
            &[(2.5574, 0.5), (3.3452, 0.1141)],
            &format!("{waveform} impaired scene"),
        );
    }
}

/// `--trials N`: trial k is the lab's k-th capture of the scene (its noise generator carries on
/// from one capture to the next), so consecutive captures on one lab detect what the trials do.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn trials_are_the_labs_consecutive_captures() {
    let dir = tempfile::tempdir().unwrap();
    let mut rng = SplitMix64::new(0x7A1);
    let s = realistic_scene(&[(1.7, 0.5), (2.6, 0.2)], &mut rng, 31);
    let path = scene_file(dir.path(), "trials.toml", &s);
    let sim = simulated(&path, "msk-lfm", &["--trials", "3"]).await;
    let trials: Vec<Vec<f64>> = serde_json::from_value(sim["trial_peaks_m"].clone()).unwrap();
    assert_eq!(trials.len(), 3);

    let scene: mock_lab::scene::Scene = serde_json::from_value(s).unwrap();
    let bench = Bench::open(BenchSource::BuiltIn(Box::new(BuiltIn {
        scene,
        ..BuiltIn::default()
    })))
    .await
    .unwrap();
    let catalog = Catalog::embedded().unwrap();
    let mut options = ProcessOptions::for_waveform(WaveformKind::MskLfm);
    options.system_delay_s = bench.file.system_delay_s();
    let request = crate::support::thesis_request(WaveformKind::MskLfm, options, false);
    let mut prepared = prepare(&bench, &catalog, &request).await.unwrap();
    let mut rig = Rig::connect(&bench, &catalog, None).await.unwrap();
    for (k, trial) in trials.iter().enumerate() {
        let m = tokio::time::timeout(
            std::time::Duration::from_secs(60),
            rig.measure(
                &bench,
                &mut prepared,
                1,
                &RfPermit::granted_by_user(),
                &Interrupt::never(),
            ),
        )
        .await
        .expect("a capture within 60 s")
        .unwrap();
        let captured: Vec<f64> = m
            .processing
            .processed
            .targets
            .iter()
            .map(|t| t.range_m)
            .collect();
        assert_eq!(&captured, trial, "capture {k}");
    }
}

/// The must-hold test, in simulation: seeded random scenes of 1-3 pillars within 15 dB
/// of the strongest on the realistic chain, every pillar within 1 cm and no false target, for
/// both waveforms (4 scenes each; detect_capture.rs runs 12 on the mock lab).
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn random_thesis_lab_scenes_in_simulate_every_pillar_and_no_false_target() {
    let dir = tempfile::tempdir().unwrap();
    let mut rng = SplitMix64::new(0x51_5CE7E);
    let mut failures = Vec::new();
    for k in 0..4u64 {
        let pillars = random_pillars_within(&mut rng, 3, 15.0);
        for waveform in WAVEFORMS {
            let s = realistic_scene(&pillars, &mut rng, 400 + k);
            let path = scene_file(dir.path(), &format!("random-{k}-{waveform}.toml"), &s);
            let sim = simulated(&path, waveform, &[]).await;
            let found: Vec<f64> = detections(&sim["targets"])
                .into_iter()
                .map(|(r, _)| r)
                .collect();
            let what = format!("{waveform} realistic scene {k}");
            if let Err(e) =
                std::panic::catch_unwind(|| every_pillar_and_nothing_else(&found, &pillars, &what))
            {
                failures.push(format!("{e:?}: {what}: found {found:?} for {pillars:?}"));
            }
        }
    }
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}

/// Unusable combinations and scene files are refused with the option or the field named,
/// exit code 2, before anything is simulated.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn scene_runs_refuse_bad_input_naming_it() {
    let dir = tempfile::tempdir().unwrap();
    let good = scene_file(dir.path(), "good.toml", &scene(&[(1.0, 0.5)], 30.0, 1));
    let bad = dir.path().join("bad.toml");
    std::fs::write(&bad, "snr_db = 30.0\n[[targets]]\nrange_m = -2.0\n").unwrap();
    let bad = bad.to_str().unwrap().to_string();
    let missing = dir.path().join("missing.toml");
    let missing = missing.to_str().unwrap().to_string();
    let cases: [(Vec<&str>, &str); 6] = [
        (vec!["--scene", &good, "--targets", "1"], "--targets"),
        (vec!["--scene", &good, "--snr-db", "20"], "--snr-db"),
        (
            vec!["--scene", &good, "--capture-rate", "80e9"],
            "--capture-rate",
        ),
        (vec!["--min-range", "0.5", "--targets", "1"], "--scene"),
        (vec!["--scene", &bad], "targets[0].range_m"),
        (vec!["--scene", &missing], "missing.toml"),
    ];
    for (args, named) in cases {
        let mut all = vec!["simulate", "run", "--waveform", "msk-lfm"];
        all.extend(args.iter().copied());
        let (code, _, err) = radbench_in(None, &all).await;
        assert_eq!(code, 2, "{args:?}: {err}");
        assert!(err.contains(named), "{args:?} should name {named}: {err}");
    }
    // A range window capture refuses is refused by capture's own check, by name.
    let (code, _, err) = radbench_in(
        None,
        &[
            "simulate",
            "run",
            "--waveform",
            "ofdm",
            "--scene",
            &good,
            "--min-range",
            "5",
            "--max-range",
            "1",
        ],
    )
    .await;
    assert_eq!(code, 2, "{err}");
    assert!(err.contains("--min-range"), "{err}");
}
