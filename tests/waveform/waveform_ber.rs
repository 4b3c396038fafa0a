//! Monte-Carlo BER against theory at 0-8 dB Eb/N0 for both waveforms.
//!
//! Bit counts are small where the BER is high and grow where it is low; the tolerance is 4.5
//! binomial standard deviations (the chance that a correct receiver fails one of the points is
//! below 1e-4 in all), so a receiver 1 dB off theory fails clearly at every point.

use radbench::waveform::{
    ber_msk_lfm_theory, ber_ofdm_theory, measure_ber_msk_lfm, measure_ber_ofdm, BerBudget, BerPoint,
};
use radbench::waveform::{MskLfm, MskLfmParams, PulseLength};
use radbench::waveform::{Ofdm, OfdmParams};

const BUDGET: BerBudget = BerBudget {
    min_bits: 20_000,
    min_errors: 300,
    max_bits: 400_000,
};

fn assert_matches_theory(p: &BerPoint, what: &str) {
    let tol = 4.5 * p.std_dev();
    assert!(
        (p.ber - p.theory).abs() <= tol,
        "{what} at {} dB: measured {} ({} errors in {} bits), theory {}, tolerance {tol}",
        p.ebn0_db,
        p.ber,
        p.errors,
        p.bits,
        p.theory
    );
}

#[test]
fn msk_lfm_ber_follows_theory() {
    // 16 samples per bit keeps the run short; the matched filter is exact at any sampling.
    let w = MskLfm::new(MskLfmParams {
        pulse: PulseLength::Samples(2048),
        bits_per_pulse: 128,
        ..Default::default()
    })
    .unwrap();
    for (i, db) in [0.0, 2.0, 4.0, 6.0, 8.0].into_iter().enumerate() {
        let p = measure_ber_msk_lfm(&w, db, &BUDGET, 100 + i as u64).unwrap();
        assert_eq!(p.theory, ber_msk_lfm_theory(db));
        assert_matches_theory(&p, "MSK-LFM");
    }
}

#[test]
fn msk_lfm_ber_with_thesis_pulse() {
    let w = MskLfm::new(MskLfmParams::default()).unwrap();
    let budget = BerBudget {
        min_bits: 3000,
        min_errors: 0,
        max_bits: 3000,
    };
    let p = measure_ber_msk_lfm(&w, 2.0, &budget, 3).unwrap();
    assert_matches_theory(&p, "MSK-LFM (thesis pulse)");
}

#[test]
fn ofdm_ber_follows_theory_with_cp_energy_counted() {
    let o = Ofdm::new(OfdmParams {
        oversampling: 2,
        symbols_per_frame: 9,
        ..Default::default()
    })
    .unwrap();
    for (i, db) in [0.0, 2.0, 4.0, 6.0, 8.0].into_iter().enumerate() {
        let p = measure_ber_ofdm(&o, db, &BUDGET, 200 + i as u64).unwrap();
        assert_eq!(p.theory, ber_ofdm_theory(db, 0.25));
        assert_matches_theory(&p, "OFDM");
    }
}

#[test]
fn ofdm_ber_with_thesis_oversampling() {
    let o = Ofdm::new(OfdmParams {
        symbols_per_frame: 20,
        ..Default::default()
    })
    .unwrap();
    let budget = BerBudget {
        min_bits: 4000,
        min_errors: 0,
        max_bits: 4000,
    };
    let p = measure_ber_ofdm(&o, 2.0, &budget, 4).unwrap();
    assert_matches_theory(&p, "OFDM (os 16)");
}
