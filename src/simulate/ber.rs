//! `radbench simulate ber`: Monte-Carlo BER against Eb/N0 (0..10 dB) for both waveforms, next to
//! theory (thesis-notes.md), with a 95 % Wilson interval on every measured point.
//!
//! The Monte-Carlo itself lives in `waveform::ber` (generate, AWGN at Eb/N0, demodulate, count);
//! this module chooses the budget, runs the grid and says how much each point can be trusted.

use super::SimError;
use crate::waveform::{measure_ber_msk_lfm, measure_ber_ofdm, BerBudget, BerPoint};
use crate::waveform::{MskLfm, MskLfmParams};
use crate::waveform::{Ofdm, OfdmParams};
use rayon::prelude::*;
use serde::Serialize;

/// Eb/N0 grid, dB.
pub(crate) const EB_N0_DB: [f64; 11] = [0.0, 1.0, 2.0, 3.0, 4.0, 5.0, 6.0, 7.0, 8.0, 9.0, 10.0];

/// One point of a BER curve (one element of the `"ber"` array of `simulate ber --json`).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct BerCurvePoint {
    pub waveform: &'static str,
    pub eb_n0_db: f64,
    pub bits: usize,
    pub bit_errors: usize,
    pub ber: f64,
    pub ber_theory: f64,
    /// 95 % Wilson score interval of the measured BER.
    pub ci95_low: f64,
    pub ci95_high: f64,
    pub theory_within_ci95: bool,
    /// (measured - theory) in binomial standard deviations of the theory at this bit count.
    pub deviation_sigma: f64,
}

/// 95 % Wilson score interval for `errors` out of `bits` (well-behaved at zero errors).
pub(crate) fn wilson95(errors: usize, bits: usize) -> (f64, f64) {
    let n = bits as f64;
    let p = errors as f64 / n;
    let z = 1.959_963_984_540_054_f64;
    let z2n = z * z / n;
    let centre = (p + z2n / 2.0) / (1.0 + z2n);
    let half = z / (1.0 + z2n) * (p * (1.0 - p) / n + z2n / (4.0 * n)).sqrt();
    ((centre - half).max(0.0), (centre + half).min(1.0))
}

/// `(errors/bits - theory)` over the binomial standard deviation `sqrt(theory (1 - theory) / bits)`.
pub(crate) fn deviation_sigma(errors: usize, bits: usize, theory: f64) -> f64 {
    let n = bits.max(1) as f64;
    let sd = (theory * (1.0 - theory) / n).sqrt().max(1e-300);
    (errors as f64 / n - theory) / sd
}

fn to_point(waveform: &'static str, p: BerPoint) -> BerCurvePoint {
    let (lo, hi) = wilson95(p.errors, p.bits);
    BerCurvePoint {
        waveform,
        eb_n0_db: p.ebn0_db,
        bits: p.bits,
        bit_errors: p.errors,
        ber: p.ber,
        ber_theory: p.theory,
        ci95_low: lo,
        ci95_high: hi,
        theory_within_ci95: p.theory >= lo && p.theory <= hi,
        deviation_sigma: deviation_sigma(p.errors, p.bits, p.theory),
    }
}

/// Both curves with the default waveforms (Tables 4.1/4.2). Each point sends at least `min_bits`
/// bits and goes on to 100 errors or 5 x `min_bits`, whichever comes first.
///
/// `progress(done, total)` is called after each point (from the worker threads).
pub fn run_curves(
    min_bits: usize,
    seed: u64,
    progress: &(dyn Fn(usize, usize) + Sync),
) -> Result<Vec<BerCurvePoint>, SimError> {
    let budget = BerBudget {
        min_bits,
        min_errors: 100,
        max_bits: min_bits.saturating_mul(5),
    };
    let msk = MskLfm::new(MskLfmParams::default())?;
    let ofdm = Ofdm::new(OfdmParams::default())?;
    let jobs: Vec<(bool, usize)> = (0..EB_N0_DB.len())
        .flat_map(|i| [(true, i), (false, i)])
        .collect();
    let done = std::sync::atomic::AtomicUsize::new(0);
    let total = jobs.len();
    let mut points = jobs
        .par_iter()
        .map(|&(is_msk, i)| {
            let ebn0 = EB_N0_DB[i];
            let point_seed = seed.wrapping_add(i as u64);
            let point = if is_msk {
                measure_ber_msk_lfm(&msk, ebn0, &budget, point_seed).map(|p| to_point("msk-lfm", p))
            } else {
                measure_ber_ofdm(&ofdm, ebn0, &budget, point_seed).map(|p| to_point("ofdm", p))
            };
            progress(
                done.fetch_add(1, std::sync::atomic::Ordering::Relaxed) + 1,
                total,
            );
            point
        })
        .collect::<Result<Vec<_>, _>>()?;
    points.sort_by(|a, b| {
        (a.waveform, a.eb_n0_db)
            .partial_cmp(&(b.waveform, b.eb_n0_db))
            .unwrap_or(std::cmp::Ordering::Equal)
    });
    Ok(points)
}

/// The curves as plot series, one per waveform, ascending Eb/N0.
pub fn plot_series(points: &[BerCurvePoint]) -> Vec<crate::storage::plot::BerSeries> {
    ["msk-lfm", "ofdm"]
        .iter()
        .map(|w| {
            let p: Vec<&BerCurvePoint> = points.iter().filter(|p| p.waveform == *w).collect();
            crate::storage::plot::BerSeries {
                label: w.to_uppercase(),
                eb_n0_db: p.iter().map(|p| p.eb_n0_db).collect(),
                ber: p.iter().map(|p| p.ber).collect(),
                ci: p.iter().map(|p| (p.ci95_low, p.ci95_high)).collect(),
                theory: p.iter().map(|p| p.ber_theory).collect(),
            }
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn wilson_interval_brackets_the_estimate_and_handles_zero() {
        let (lo, hi) = wilson95(100, 10_000);
        assert!(lo < 0.01 && hi > 0.01 && lo > 0.007 && hi < 0.013);
        let (lo0, hi0) = wilson95(0, 10_000);
        assert!(lo0 < 1e-12, "{lo0}");
        assert!(hi0 > 0.0 && hi0 < 5e-4);
    }

    #[test]
    fn deviation_counts_standard_deviations() {
        // theory 1e-2 on 10 000 bits: sd = sqrt(0.0099 / 1e4) = 9.95e-4; 120 errors is +2.01 sd.
        let z = deviation_sigma(120, 10_000, 0.01);
        assert!((z - 2.0101).abs() < 1e-3, "{z}");
        assert!(deviation_sigma(100, 10_000, 0.01).abs() < 1e-12);
    }
}
