//! Random pillar scenes the detection tests share (seeded), as scene-file JSON for the mock lab.

use radbench::rng::SplitMix64;
use serde_json::json;

/// One resolution cell of the thesis' 1 GHz waveforms, metres.
pub const CELL_M: f64 = 0.149_896_229;

/// A scene of pillars (range, amplitude) on the mock lab's defaults (leakage present).
pub fn scene(pillars: &[(f64, f64)], snr_db: f64, seed: u64) -> serde_json::Value {
    let mut scene = serde_json::to_value(mock_lab::scene::Scene::default()).unwrap();
    scene["targets"] = pillars
        .iter()
        .map(|&(r, a)| json!({"range_m": r, "amplitude": a}))
        .collect();
    scene["snr_db"] = json!(snr_db);
    scene["seed"] = json!(seed);
    scene
}

/// 1 to `most` pillars at least two resolution cells apart within 0.3..8 m; the first is the
/// strongest (0.5), the others lie 0..`within_db` dB under it.
pub fn random_pillars_within(rng: &mut SplitMix64, most: u64, within_db: f64) -> Vec<(f64, f64)> {
    let n = 1 + (rng.next_u64() % most) as usize;
    let mut out: Vec<(f64, f64)> = Vec::new();
    while out.len() < n {
        let r = 0.3 + 7.7 * rng.uniform();
        if out.iter().all(|(o, _)| (o - r).abs() >= 2.0 * CELL_M) {
            let a = if out.is_empty() {
                0.5
            } else {
                0.5 * 10f64.powf(-rng.uniform() * within_db / 20.0)
            };
            out.push((r, a));
        }
    }
    out
}

/// A realistic bench: the `thesis-lab` chain, leakage at -26 dB, clutter near the horns and
/// beyond the window, I/Q imbalance up to 0.6 dB and 4 degrees, DC offset, residual phase noise up
/// to 2 kHz and a few ps of trigger jitter, all drawn per scene.
pub fn realistic_scene(
    pillars: &[(f64, f64)],
    rng: &mut SplitMix64,
    seed: u64,
) -> serde_json::Value {
    let mut s = scene(pillars, 25.0, seed);
    let mut draw = |lo: f64, hi: f64| lo + (hi - lo) * rng.uniform();
    s["chain"] = json!({"preset": "thesis-lab"});
    s["leakage"] = json!({"amplitude": 0.5 * 10f64.powf(-26.0 / 20.0), "delay_s": 0.2e-9});
    s["clutter"] = json!([
        {"range_m": draw(0.0, 0.05), "amplitude": draw(0.01, 0.05)},
        {"range_m": draw(11.0, 14.0), "amplitude": draw(0.05, 0.2)},
    ]);
    s["impairments"] = json!({
        "dc_offset_v": [draw(-0.005, 0.005), draw(-0.005, 0.005)],
        "iq_gain_db": draw(-0.6, 0.6),
        "iq_phase_deg": draw(-4.0, 4.0),
        "phase_noise_linewidth_hz": draw(0.0, 2000.0),
    });
    s["trigger_jitter_s"] = json!(draw(0.0, 5e-12));
    s
}
