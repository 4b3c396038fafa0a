//! The residual floor: a calibration's residual profile keeps what the correction leaves near a
//! strong target from being a target, and a real weak one beside it is still found.

use super::*;
use crate::rng::SplitMix64;

/// Taylor-windowed OFDM spread, 256 subcarriers zero padded x4: cells of 3.75 cm at 1 GHz.
const STEP_M: f64 = 0.0375;

fn detector(floor: Option<ResidualFloor>) -> Detector {
    detector_with(floor, DetectOptions::default().method)
}

fn detector_with(floor: Option<ResidualFloor>, method: Method) -> Detector {
    let mut w = vec![0.0; 256];
    crate::dsp::window::Window::Taylor {
        nbar: 4,
        sll_db: -35.0,
    }
    .fill(&mut w)
    .unwrap();
    let lines = SpectralLines::ofdm(4, &w).unwrap();
    let psf = TabulatedPsf::from_lines(&lines, Some(1024)).unwrap();
    Detector::new(
        psf,
        DetectOptions {
            residual_floor: floor,
            method,
            ..DetectOptions::default()
        },
    )
    .unwrap()
}

/// A strong target at 7.5 m, its residue 1.4 m behind at `residue_db`, a real target 1 m behind
/// at -40 dB, seeded noise at -110 dB (so the weak target certifies the model too, and no chain
/// floor stands around it); the ranges found.
fn found(det: &mut Detector, residue_db: f64) -> Vec<f64> {
    let n = 1024;
    let x0 = 200.0;
    let parts = [
        (x0, 1.0),
        (x0 + 1.4 / STEP_M, 10f64.powf(residue_db / 20.0)),
        (x0 + 1.0 / STEP_M, 0.01),
    ];
    let mut z = vec![Complex64::new(0.0, 0.0); n];
    let mut g = vec![Complex64::new(0.0, 0.0); n];
    for (k, (x, a)) in parts.into_iter().enumerate() {
        det.psf().response(x, 0, &mut g);
        let a = Complex64::from_polar(a, 0.7 * k as f64);
        for (v, gv) in z.iter_mut().zip(&g) {
            *v += a * gv;
        }
    }
    SplitMix64::new(38).add_noise(&mut z, 1e-11);
    let axis = Axis {
        start: 0.0,
        step: STEP_M,
    };
    det.detect(&z, axis, 0.0..=30.0)
        .unwrap()
        .targets
        .iter()
        .map(|t| t.range_m)
        .collect()
}

/// A calibration's profile: -63 dB in the bin 1.40-1.45 m behind, -100 dB elsewhere.
fn profile() -> ResidualFloor {
    let mut behind = vec![-100.0; 60];
    behind[28] = -63.0;
    ResidualFloor::from_db(0.05, &behind, &[-100.0; 60]).unwrap()
}

#[test]
fn the_residue_is_a_target_without_the_floor_and_not_with_it_and_the_weak_pillar_stays() {
    let near = |r: &[f64], at: f64| r.iter().any(|x| (x - at).abs() < 0.01);
    let without = found(&mut detector(None), -61.0);
    assert!(
        near(&without, 7.5 + 1.4) && near(&without, 8.5) && near(&without, 7.5),
        "{without:?}"
    );
    let mut det = detector(Some(profile()));
    let with = found(&mut det, -61.0);
    assert_eq!(with.len(), 2, "{with:?}");
    assert!(near(&with, 7.5) && near(&with, 8.5), "{with:?}");
    // A real target 10 dB over the profile's margin at the residue's place is still one.
    let strong = found(&mut det, -47.0);
    assert!(near(&strong, 7.5 + 1.4), "{strong:?}");
}

/// CFAR masks what lies under a kept peak's side-lobe envelope; a residue over that envelope
/// but under the calibration's profile (its margin included) is masked too.
#[test]
fn cfar_masks_a_residue_under_the_profile_and_keeps_a_target_over_it() {
    let cfar = Method::Cfar { kind: CfarKind::Ca };
    let mut plain = detector_with(None, cfar);
    let envelope_db = 10.0 * plain.shape.envelope_at(1.4 / STEP_M).log10();
    // 20 dB over the envelope (CFAR's mask is the envelope plus 3 dB; its training cells hold
    // the strong target's side-lobes, which puts its own threshold about 13 dB over them).
    let residue_db = envelope_db + 20.0;
    let near = |r: &[f64], at: f64| r.iter().any(|x| (x - at).abs() < 0.01);
    let without = found(&mut plain, residue_db);
    assert!(near(&without, 7.5 + 1.4), "{envelope_db} dB: {without:?}");
    // The profile 3 dB under the residue: with the 6 dB margin it covers it.
    let mut behind = vec![-100.0; 60];
    behind[28] = residue_db - 3.0;
    let floor = ResidualFloor::from_db(0.05, &behind, &[-100.0; 60]).unwrap();
    let mut det = detector_with(Some(floor), cfar);
    let with = found(&mut det, residue_db);
    assert!(!near(&with, 7.5 + 1.4) && near(&with, 7.5), "{with:?}");
    // A target 10 dB over the profile's margin at that place is still one.
    let strong = found(&mut det, residue_db + 13.0);
    assert!(near(&strong, 7.5 + 1.4), "{strong:?}");
}

#[test]
fn the_floor_takes_the_largest_neighbouring_bin_and_is_zero_beyond_the_profile() {
    let f = profile();
    let lin = |db: f64| 10f64.powf(db / 10.0);
    assert!((f.at(1.42) - lin(-63.0)).abs() < 1e-12);
    assert!((f.at(1.47) - lin(-63.0)).abs() < 1e-12);
    assert!((f.at(1.37) - lin(-63.0)).abs() < 1e-12);
    assert!((f.at(1.52) - lin(-100.0)).abs() < 1e-15);
    assert!((f.at(-1.42) - lin(-100.0)).abs() < 1e-15);
    assert_eq!(f.at(3.1), 0.0);
    assert!((f.reach_m() - 3.0).abs() < 1e-12);
    assert!(ResidualFloor::from_db(0.0, &[], &[]).is_none());
    assert!(ResidualFloor::from_db(0.05, &[f64::NAN], &[]).is_none());
}
