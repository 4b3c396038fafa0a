//! Metrics on real OFDM profiles: CA-CFAR on a noisy profile, and resolution of two targets with
//! the rule of thesis-notes.md against separation.

use crate::dsp_support;

use dsp_support::*;
use radbench::dsp::{resolve_targets, CaCfar, Interpolation};
use radbench::dsp::{IDiv, OfdmRadar, OfdmRadarConfig, RangeProfile};
use radbench::rng::SplitMix64;

fn profile(seed: u64, symbols: usize, targets: &[Target], snr_db: Option<f64>) -> RangeProfile {
    let mut rng = SplitMix64::new(seed);
    let tx = qpsk(&mut rng, symbols, N);
    let rx = received_signal(&mut rng, &tx, FC_PHYSICAL, targets, snr_db);
    let mut radar = OfdmRadar::new(OfdmRadarConfig::default()).unwrap();
    let (mut idiv, mut p) = (IDiv::new(), RangeProfile::new());
    radar.process(&rx, 0, &tx, &mut idiv, &mut p).unwrap();
    p
}

#[test]
fn cfar_finds_a_weak_target_and_nothing_else() {
    // -20 dB per sample at 16 GSa/s: the 16x oversampling and 128 subcarriers x 4 symbols of
    // coherent integration lift the target about 19 dB above the profile's noise floor.
    for seed in 0..4 {
        let p = profile(
            40 + seed,
            4,
            &[Target {
                range: 5.0,
                amp: 1.0,
                velocity: 0.0,
            }],
            Some(-20.0),
        );
        let power: Vec<f64> = p.amplitude.iter().map(|a| a * a).collect();
        // Guard beyond the first null (10 bins at zero-padding 10); 10 cells per independent sample.
        let mut cfar = CaCfar::new(15, 40, 1e-4)
            .unwrap()
            .with_oversampling(10)
            .unwrap();
        let mut threshold = vec![0.0; power.len()];
        let detections = cfar.detect(&power, &mut threshold).unwrap();
        assert_eq!(detections.len(), 1, "seed {seed}: {detections:?}");
        let r = p.range_m[detections[0].index];
        // At about 19 dB the range noise is about 1 cm rms.
        assert!((r - 5.0).abs() < 0.03, "seed {seed}: detection at {r} m");
    }
}

#[test]
fn cfar_without_the_oversampling_correction_false_alarms_on_a_zero_padded_profile() {
    let mut alarms = [0usize; 2];
    for seed in 0..8 {
        let p = profile(70 + seed, 1, &[], Some(0.0));
        let power: Vec<f64> = p.amplitude.iter().map(|a| a * a).collect();
        let mut t = vec![0.0; power.len()];
        for (slot, factor) in [1usize, 10].into_iter().enumerate() {
            let mut cfar = CaCfar::new(15, 40, 1e-3)
                .unwrap()
                .with_oversampling(factor)
                .unwrap();
            alarms[slot] += cfar.detect(&power, &mut t).unwrap().len();
        }
    }
    // About 128 independent cells per profile x 8 profiles x 1e-3: ~1 false alarm expected.
    assert!(alarms[1] <= 4, "corrected: {alarms:?}");
    assert!(
        alarms[0] > alarms[1],
        "uncorrected should false-alarm more: {alarms:?}"
    );
}

#[test]
fn resolution_improves_with_separation() {
    // Physical 80 GHz carrier: equal targets 30 cm apart (2.3 resolution cells) always resolve;
    // 5 cm apart never do.
    let base = 2.0;
    for (sep, expect) in [(0.30, true), (0.05, false)] {
        let targets = [target(base), target(base + sep)];
        let p = profile(1, 2, &targets, None);
        let r = resolve_targets(
            p.axis(),
            &p.amplitude,
            &[base, base + sep],
            3.0,
            Interpolation::ParabolicDb,
        );
        assert_eq!(r.resolved, expect, "separation {sep}: {r:?}");
        if expect {
            for (got, want) in r.peaks.iter().zip([base, base + sep]) {
                // Each lobe's skirt pulls the other peak outwards by about 1.6 cm.
                assert!((got.unwrap() - want).abs() < 0.02, "{r:?}");
            }
        }
    }
}
