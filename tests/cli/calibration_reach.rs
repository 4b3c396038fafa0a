//! Calibration on the chains a real lab has (issue 38): the thesis-lab chain alone and with an IF
//! cable's echo 15 ns behind every path, the Tx->Rx leakage at -40 and -26 dB in the reference
//! and in the captures, the reference at 0.8, 1.0 and 2.5 m. For both waveforms, every window and
//! every correction: the one pillar within 0.5 mm, no other target, and each window's side-lobe
//! within 2 dB of its design and of what the same window gives on the ideal chain. (Before the
//! scene's alternating re-measure for references under 0.9 m, 2026-12-08, two of the 288 missed
//! the design by up to 0.4 dB: MSK-LFM with Dolph-Chebyshev, `rx`, on the 0.8 m reference, at
//! -47.86 and -47.61 dB; docs/calibration.md.)

use super::scenes::scene;
use super::support::radbench_in;
use serde_json::{json, Value};
use std::path::Path;

/// The pillar the captures measure, m.
const PILLAR_M: f64 = 2.3;

/// Each window and its designed peak side-lobe, dB.
const WINDOWS: [(&str, f64); 4] = [
    ("rect", -13.26),
    ("hann", -31.47),
    ("taylor", -35.0),
    ("chebyshev", -50.0),
];

fn chain(cable: bool) -> Value {
    if cable {
        json!({"preset": "thesis-lab", "cable_echo_ns": 15.0, "cable_echo_db": -30.0,
               "cable_echo_phase_deg": 40.0})
    } else {
        json!({"preset": "thesis-lab"})
    }
}

fn write_scene(dir: &Path, name: &str, range_m: f64, cable: bool, leak_db: f64, seed: u64) {
    let mut s = scene(&[(range_m, 0.5)], 25.0, seed);
    s["chain"] = chain(cable);
    write(dir, name, s, leak_db);
}

fn write(dir: &Path, name: &str, mut s: Value, leak_db: f64) {
    s["leakage"] = json!({"amplitude": 0.5 * 10f64.powf(leak_db / 20.0), "delay_s": 0.2e-9});
    std::fs::write(dir.join(name), toml::to_string(&s).unwrap()).unwrap();
}

async fn ok(dir: &Path, args: &[&str]) -> Value {
    let (code, out, err) = radbench_in(Some(dir), args).await;
    assert_eq!(code, 0, "{args:?}: {err}");
    serde_json::from_str(&out).unwrap_or_else(|e| panic!("{e}: {out}"))
}

/// Each window's side-lobe on the ideal chain, for `waveform` (in [`WINDOWS`]' order).
async fn ideal_sidelobes(waveform: &str) -> Vec<f64> {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let mut ideal = scene(&[(PILLAR_M, 0.5)], 25.0, 11);
    ideal["chain"] = json!({"preset": "ideal"});
    write(d, "ideal.toml", ideal, -40.0);
    ok(
        d,
        &[
            "capture",
            "--allow-rf",
            "--scene",
            "ideal.toml",
            "--waveform",
            waveform,
            "--json",
            "--out",
            "c",
        ],
    )
    .await;
    let mut out = Vec::new();
    for (window, designed_db) in WINDOWS {
        let p = ok(
            d,
            &[
                "process", "c", "--window", window, "--json", "--out", window,
            ],
        )
        .await;
        let psl = p["processed"][0]["summary"]["targets"][0]["sidelobe_db"]
            .as_f64()
            .unwrap_or_else(|| panic!("{waveform} {window} on the ideal chain: {p}"));
        assert!(
            (psl - designed_db).abs() <= 2.0,
            "{waveform} {window} on the ideal chain: {psl} dB, designed {designed_db} dB"
        );
        out.push(psl);
    }
    out
}

/// What is wrong with one processed capture's targets and side-lobe (empty when nothing): its
/// side-lobe against the window's on the ideal chain (`ideal_db`) and its design (`design_db`).
fn check(summary: &Value, ideal_db: f64, design_db: f64) -> Vec<String> {
    let mut wrong = Vec::new();
    let targets = summary["targets"].as_array().cloned().unwrap_or_default();
    let pillar = targets.iter().find(|t| {
        t["range_m"]
            .as_f64()
            .is_some_and(|r| (r - PILLAR_M).abs() <= 0.5e-3)
    });
    let level = |t: &Value| t["level_db"].as_f64().unwrap_or(0.0);
    let extra: Vec<(f64, f64)> = targets
        .iter()
        .filter(|t| !pillar.is_some_and(|p| std::ptr::eq(*t, p)))
        .map(|t| (t["range_m"].as_f64().unwrap_or(f64::NAN), level(t)))
        .collect();
    if pillar.is_none() || !extra.is_empty() {
        let ranges: Vec<f64> = targets
            .iter()
            .filter_map(|t| t["range_m"].as_f64())
            .collect();
        wrong.push(format!(
            "targets at {ranges:?} m (extra, with levels: {extra:?})"
        ));
    }
    let targets: Vec<Value> = pillar.into_iter().cloned().collect();
    match targets.first().and_then(|t| t["sidelobe_db"].as_f64()) {
        Some(psl) if (psl - ideal_db).abs() <= 2.0 && (psl - design_db).abs() <= 2.0 => {}
        psl => wrong.push(format!(
            "side-lobe {psl:?} dB ({:?}), {ideal_db:.2} dB on the ideal chain, {design_db} dB \
             designed",
            targets.first().map(|t| &t["sidelobe_note"])
        )),
    }
    wrong
}

/// Calibrates on a pillar at `reference_m`, captures the pillar at [`PILLAR_M`] with each
/// correction, processes each capture with each window; what went wrong, by name.
async fn one_case(
    dir: &Path,
    waveform: &str,
    ideal: &[f64],
    (cable, leak_db, reference_m): (bool, f64, f64),
) -> Vec<String> {
    let case = format!(
        "{waveform}, {} chain, leakage {leak_db} dB, reference at {reference_m} m",
        if cable { "cable-echo" } else { "thesis-lab" }
    );
    write_scene(dir, "reference.toml", reference_m, cable, leak_db, 7);
    write_scene(dir, "pillar.toml", PILLAR_M, cable, leak_db, 11);
    let r = reference_m.to_string();
    let cal = ok(
        dir,
        &[
            "calibrate",
            "response",
            "--reference-range",
            &r,
            "--scene",
            "reference.toml",
            "--allow-rf",
            "--waveform",
            waveform,
            "--out",
            "response.toml",
            "--json",
        ],
    )
    .await;
    let mut wrong = Vec::new();
    let header = std::fs::read_to_string(dir.join("response.toml")).unwrap();
    if cable && !header.contains("[[chain_echoes]]") {
        wrong.push(format!(
            "{case}: the cable's echo is not in the calibration: {cal}"
        ));
    }
    for correction in ["rx", "tx", "both"] {
        let out = format!("c-{correction}");
        ok(
            dir,
            &[
                "capture",
                "--allow-rf",
                "--scene",
                "pillar.toml",
                "--waveform",
                waveform,
                "--calibration",
                "response.toml",
                "--correction",
                correction,
                "--json",
                "--out",
                &out,
                "--force",
            ],
        )
        .await;
    }
    for (&(window, design_db), &ideal_db) in WINDOWS.iter().zip(ideal) {
        let out = format!("p-{window}");
        let _ = std::fs::remove_dir_all(dir.join(&out));
        let p = ok(
            dir,
            &[
                "process", "c-rx", "c-tx", "c-both", "--window", window, "--json", "--out", &out,
            ],
        )
        .await;
        for processed in p["processed"].as_array().unwrap() {
            for w in check(&processed["summary"], ideal_db, design_db) {
                wrong.push(format!(
                    "{case}, {} with {window}: {w}",
                    processed["source"]
                ));
            }
        }
    }
    wrong
}

async fn cases(waveform: &str) {
    let ideal = ideal_sidelobes(waveform).await;
    let mut wrong = Vec::new();
    for cable in [false, true] {
        for leak_db in [-40.0, -26.0] {
            for reference_m in [0.8, 1.0, 2.5] {
                let dir = tempfile::tempdir().unwrap();
                let case = (cable, leak_db, reference_m);
                wrong.extend(one_case(dir.path(), waveform, &ideal, case).await);
            }
        }
    }
    assert!(wrong.is_empty(), "{}", wrong.join("\n"));
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn every_window_and_correction_after_calibrating_a_real_chain_msk_lfm() {
    cases("msk-lfm").await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn every_window_and_correction_after_calibrating_a_real_chain_ofdm() {
    cases("ofdm").await;
}

/// A weak pillar 40 dB under a strong one, 1 m behind it, is still found once the chain is
/// corrected: what the correction knows of the chain does not hide real targets.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_pillar_40_db_under_a_strong_one_1_m_behind_is_found_after_correction() {
    for waveform in ["msk-lfm", "ofdm"] {
        let dir = tempfile::tempdir().unwrap();
        let d = dir.path();
        write_scene(d, "reference.toml", 1.0, true, -26.0, 7);
        let mut two = scene(&[(2.0, 0.5), (3.0, 0.005)], 25.0, 13);
        two["chain"] = chain(true);
        write(d, "two.toml", two, -26.0);
        ok(
            d,
            &[
                "calibrate",
                "response",
                "--reference-range",
                "1.0",
                "--scene",
                "reference.toml",
                "--allow-rf",
                "--waveform",
                waveform,
                "--out",
                "response.toml",
                "--json",
            ],
        )
        .await;
        // The default (rx, no window), and pre-distorted with a low side-lobe window, where
        // the calibration's residual profile sets the floor near the strong pillar.
        for (correction, window) in [("rx", "rect"), ("tx", "taylor")] {
            let out = format!("c-{correction}");
            let c = ok(
                d,
                &[
                    "capture",
                    "--allow-rf",
                    "--scene",
                    "two.toml",
                    "--waveform",
                    waveform,
                    "--calibration",
                    "response.toml",
                    "--correction",
                    correction,
                    "--window",
                    window,
                    "--json",
                    "--out",
                    &out,
                ],
            )
            .await;
            let found: Vec<f64> = c["targets"]
                .as_array()
                .unwrap()
                .iter()
                .map(|t| t["range_m"].as_f64().unwrap())
                .collect();
            assert!(
                found.len() == 2 && (found[0] - 2.0).abs() < 0.01 && (found[1] - 3.0).abs() < 0.01,
                "{waveform} {correction} {window}: {found:?}"
            );
        }
    }
}

/// Clutter beyond the range window, stronger than a weak pillar inside it (issue 38's "pull").
/// The detector cannot fit what lies beyond its profile, so that reflector's side-lobes stay in
/// the window; on the ideal spread they barely move a pillar, but on an uncorrected realistic
/// chain the reflector's side-lobes are the chain's, which the ideal spread does not describe,
/// and they pull the weak pillar. Corrected, the chain's side-lobes are the ideal ones again and
/// the pull is under 0.5 mm.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn clutter_beyond_the_window_pulls_a_weak_pillar_under_half_a_mm_on_the_ideal_and_the_corrected_chain(
) {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let mut reference = scene(&[(1.0, 0.5)], 25.0, 7);
    reference["chain"] = json!({"preset": "thesis-lab"});
    write(d, "reference.toml", reference, -26.0);
    ok(
        d,
        &[
            "calibrate",
            "response",
            "--reference-range",
            "1.0",
            "--scene",
            "reference.toml",
            "--allow-rf",
            "--band",
            "upper",
            "--out",
            "response.toml",
            "--json",
        ],
    )
    .await;
    let error_mm = |c: &Value, r: f64| {
        c["targets"]
            .as_array()
            .unwrap()
            .iter()
            .filter_map(|t| t["range_m"].as_f64())
            .find(|x| (x - r).abs() < 0.05)
            .map(|x| (x - r) * 1e3)
            .unwrap_or_else(|| panic!("the pillar at {r} m is missing: {c}"))
    };
    let (mut ideal, mut corrected) = (Vec::new(), Vec::new());
    for (k, weak_m) in [6.31, 8.137, 9.71].into_iter().enumerate() {
        for chain in ["ideal", "thesis-lab"] {
            let mut s = scene(&[(1.0, 0.5), (weak_m, 0.089)], 30.0, 3 + k as u64);
            s["chain"] = json!({ "preset": chain });
            s["clutter"] = json!([{"range_m": 12.6, "amplitude": 0.2}]);
            write(d, "scene.toml", s, -40.0);
            let mut args = vec![
                "capture",
                "--allow-rf",
                "--scene",
                "scene.toml",
                "--band",
                "upper",
                "--json",
                "--out",
                "c",
                "--force",
            ];
            if chain == "thesis-lab" {
                args.extend(["--calibration", "response.toml"]);
            }
            let c = ok(d, &args).await;
            let e = error_mm(&c, weak_m);
            if chain == "ideal" {
                ideal.push(e);
            } else {
                corrected.push(e);
            }
        }
    }
    assert!(
        ideal.iter().chain(&corrected).all(|e| e.abs() < 0.5),
        "errors on the ideal chain {ideal:?} mm, on the corrected thesis-lab chain \
         {corrected:?} mm"
    );
}

/// Captures `pillar.toml` with MSK-LFM, corrected with `calibration` as `correction`, and
/// `more` arguments, into `out`.
async fn capture_pillar(d: &Path, calibration: &str, correction: &str, more: &[&str], out: &str) {
    let mut args = vec![
        "capture",
        "--allow-rf",
        "--scene",
        "pillar.toml",
        "--waveform",
        "msk-lfm",
        "--calibration",
        calibration,
        "--correction",
        correction,
        "--json",
        "--out",
        out,
    ];
    args.extend_from_slice(more);
    ok(d, &args).await;
}

/// The reference (1.0 m) and the pillar's scenes on a chain whose response steps by `db` and
/// `deg` between 100 and 120 MHz, leakage at -40 dB; the response calibrated on the reference
/// with MSK-LFM into `response.toml`: its report.
async fn calibrate_on_a_stepped_chain(d: &Path, db: f64, deg: f64) -> Value {
    for (name, range_m, seed) in [("reference.toml", 1.0, 7), ("pillar.toml", PILLAR_M, 11)] {
        let mut s = scene(&[(range_m, 0.5)], 25.0, seed);
        s["chain"] = json!({"preset": "thesis-lab", "response": [
            [-5e8, 0.0, 0.0], [1e8, 0.0, 0.0], [1.2e8, db, deg], [5e8, db, deg]]});
        write(d, name, s, -40.0);
    }
    ok(
        d,
        &[
            "calibrate",
            "response",
            "--reference-range",
            "1.0",
            "--scene",
            "reference.toml",
            "--allow-rf",
            "--waveform",
            "msk-lfm",
            "--out",
            "response.toml",
            "--json",
        ],
    )
    .await
}

/// The calibration's residual profile (`[[residual]]`, issue 38): what the correction leaves on
/// the reference, per window. A chain whose response steps by 0.3 dB and 3 degrees within 20 MHz
/// (a filter's edge, a switched band) has an impulse response longer than any gate: the fit
/// leaves its tails, 55-65 dB under the reference, on both sides. MSK-LFM corrected on receive
/// (`rx`) with the Taylor window, with a calibration whose header lacks the profile (as written
/// before it existed), reports those tails as targets; with the profile the detector's floor
/// follows them and it does not. (The thesis-lab chain alone no longer leaves a residue to test
/// this on: the least-squares fit took the one 1.4 m behind that pre-distortion showed.)
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn the_residual_profile_keeps_the_fits_residue_from_being_a_target() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    calibrate_on_a_stepped_chain(d, -0.3, 3.0).await;
    let header = std::fs::read_to_string(d.join("response.toml")).unwrap();
    let parsed: toml::Table = toml::from_str(&header).unwrap();
    let profiles = parsed["residual"].as_array().unwrap();
    let windows: Vec<&str> = profiles
        .iter()
        .map(|r| r["window"].as_str().unwrap())
        .collect();
    assert_eq!(windows, ["rect", "hann", "taylor", "chebyshev"]);
    // Taylor's profile holds the tails' level, behind and ahead.
    let taylor = &profiles[2];
    for side in ["behind_db", "ahead_db"] {
        let level = taylor[side]
            .as_array()
            .unwrap()
            .iter()
            .map(|v| v.as_float().unwrap())
            .fold(f64::MIN, f64::max);
        assert!((-66.0..=-50.0).contains(&level), "{side}: {taylor:?}");
    }
    let mut old = parsed.clone();
    old.remove("residual");
    std::fs::write(d.join("old.toml"), toml::to_string(&old).unwrap()).unwrap();
    let mut found = Vec::new();
    for cal in ["old.toml", "response.toml"] {
        let out = format!("c-{cal}");
        capture_pillar(d, cal, "rx", &["--window", "taylor"], &out).await;
        let s: Value = serde_json::from_str(
            &std::fs::read_to_string(d.join(&out).join("summary.json")).unwrap(),
        )
        .unwrap();
        let t: Vec<(f64, f64)> = s["targets"]
            .as_array()
            .unwrap()
            .iter()
            .map(|t| {
                (
                    t["range_m"].as_f64().unwrap(),
                    t["level_db"].as_f64().unwrap(),
                )
            })
            .collect();
        found.push(t);
    }
    let (without, with) = (&found[0], &found[1]);
    let pillar = |t: &[(f64, f64)]| t.iter().any(|(r, _)| (r - PILLAR_M).abs() <= 0.5e-3);
    assert!(
        pillar(without) && without.len() > 1,
        "without the profile the fit's residue is a target: {without:?}"
    );
    assert!(
        pillar(with) && with.len() == 1,
        "with the profile: {with:?}; Taylor's: {taylor:?}"
    );
}

/// A chain whose response steps by 1 dB and 10 degrees within 20 MHz has a tail beyond the
/// gate as strong as the leakage: with the reference at 1.0 m the leakage (6.5 ns ahead of it,
/// just beyond the fit's reach) sums with that tail below the echo search's floor, is not found,
/// and the least-squares fit takes it for the chain's. Every corrected capture then showed the
/// leakage's image 1.0 m ahead of the pillar (-39.6 dB, Taylor, `rx`; before 2026-12-07). The
/// calibration says so and its residual profile covers that place: only the pillar is reported,
/// with every window and every correction.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_leakage_the_chains_tail_hides_leaves_no_image_ahead_of_the_pillar() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let cal = calibrate_on_a_stepped_chain(d, 1.0, 10.0).await;
    let unseen = &cal["figures"]["leakage_unseen_db"];
    assert!(unseen.as_f64().is_some_and(|db| db > -60.0), "{cal}");
    assert_only_the_pillar(d).await;
}

/// The pillar captured with `response.toml` and each correction, processed with every window:
/// the pillar alone, within 0.5 mm, in each.
async fn assert_only_the_pillar(d: &Path) {
    let mut found = Vec::new();
    for correction in ["rx", "tx", "both"] {
        capture_pillar(
            d,
            "response.toml",
            correction,
            &[],
            &format!("c-{correction}"),
        )
        .await;
    }
    for (window, _) in WINDOWS {
        let p = ok(
            d,
            &[
                "process", "c-rx", "c-tx", "c-both", "--window", window, "--json", "--out", window,
            ],
        )
        .await;
        for processed in p["processed"].as_array().unwrap() {
            let targets: Vec<f64> = processed["summary"]["targets"]
                .as_array()
                .unwrap()
                .iter()
                .map(|t| t["range_m"].as_f64().unwrap())
                .collect();
            if targets.len() != 1 || (targets[0] - PILLAR_M).abs() > 0.5e-3 {
                found.push(format!("{window} {}: {targets:?}", processed["source"]));
            }
        }
    }
    assert!(found.is_empty(), "{}", found.join("\n"));
}

/// A chain whose response steps by 0.5 dB and 5 degrees within 20 MHz has a tail beyond the
/// gate 50-55 dB under the reference, on both sides. Where the reference's leakage stands (0.95
/// m ahead of it at 1.0 m) the calibration divided that tail out with the leakage, so its
/// residual profile read 5-10 dB low there, and every corrected capture showed the tail 1.0 m
/// ahead of the pillar, 46 dB under it, as a target (7 of the 36 combinations of correction and
/// window, 2026-12-07). The profile now takes such a place's level from beside it.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_chains_tail_where_the_reference_had_its_leakage_is_not_a_target() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    calibrate_on_a_stepped_chain(d, -0.5, 5.0).await;
    assert_only_the_pillar(d).await;
}

/// A calibration file written before `[[chain_echoes]]`, `[[scene_echoes]]` and `[[residual]]`
/// existed (the fresh file with those tables taken out of its header, as the older writer left
/// it: the echoes folded into its table all the same) still loads and corrects: the pillar on
/// the cable-echo chain within 0.5 mm, no detection taken for a chain echo (the file names
/// none).
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_calibration_written_before_its_echo_lists_still_loads_and_corrects() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    write_scene(d, "reference.toml", 1.0, true, -40.0, 7);
    write_scene(d, "pillar.toml", PILLAR_M, true, -40.0, 11);
    ok(
        d,
        &[
            "calibrate",
            "response",
            "--reference-range",
            "1.0",
            "--scene",
            "reference.toml",
            "--allow-rf",
            "--out",
            "response.toml",
            "--json",
        ],
    )
    .await;
    let header = std::fs::read_to_string(d.join("response.toml")).unwrap();
    assert!(header.contains("[[chain_echoes]]"), "{header}");
    let mut old: toml::Table = toml::from_str(&header).unwrap();
    assert!(old.remove("chain_echoes").is_some());
    old.remove("scene_echoes");
    assert!(old.remove("residual").is_some(), "{header}");
    let old = toml::to_string(&old).unwrap();
    assert!(!old.contains("chain_echoes") && !old.contains("scene_echoes"));
    assert!(!old.contains("residual"));
    // The table beside the header is the fresh one's (its name and hash are in the header).
    std::fs::write(d.join("response.toml"), old).unwrap();
    let c = ok(
        d,
        &[
            "capture",
            "--allow-rf",
            "--scene",
            "pillar.toml",
            "--calibration",
            "response.toml",
            "--correction",
            "rx",
            "--json",
            "--out",
            "c",
        ],
    )
    .await;
    let ranges: Vec<f64> = c["targets"]
        .as_array()
        .unwrap()
        .iter()
        .filter_map(|t| t["range_m"].as_f64())
        .collect();
    assert!(
        ranges.iter().any(|r| (r - PILLAR_M).abs() <= 0.5e-3),
        "{ranges:?}: {c}"
    );
    let flagged = c["chain_echoes"].as_array().map_or(0, Vec::len);
    assert_eq!(flagged, 0, "{c}");
}
