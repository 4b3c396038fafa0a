//! How well the data symbols came through: error-vector magnitude (EVM, rms and a percentile)
//! and modulation error ratio (MER) of received symbols against the symbols that were sent
//! (data-aided: the transmitted bits are known, so no decision error biases the figures at low
//! SNR).
//!
//! With `s` the ideal symbols and `e = r - s` the error vectors:
//! `EVM_rms = sqrt(sum |e|^2 / sum |s|^2)`, each symbol's EVM `|e| / sqrt(mean |s|^2)`, and
//! `MER = 10 log10(sum |s|^2 / sum |e|^2)` dB, so `MER = -20 log10(EVM_rms)` with data-aided
//! references. For white noise of power `N` per symbol on symbols of power `S`, `MER = S / N`.

use num_complex::Complex64;
use serde::Serialize;

/// EVM and MER of one set of symbols.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub(crate) struct LinkQuality {
    /// RMS error-vector magnitude, percent of the ideal constellation's rms.
    pub(crate) evm_rms_pct: f64,
    /// The 95th percentile of the symbols' EVM, percent.
    pub(crate) evm_p95_pct: f64,
    /// Modulation error ratio, dB.
    pub(crate) mer_db: f64,
    /// Symbols counted.
    pub(crate) symbols: usize,
}

/// EVM and MER of `received` against `ideal` (pairs up to the shorter); `None` when there is no
/// symbol or the ideal constellation has no power.
pub(crate) fn link_quality(received: &[Complex64], ideal: &[Complex64]) -> Option<LinkQuality> {
    let n = received.len().min(ideal.len());
    if n == 0 {
        return None;
    }
    let signal: f64 = ideal[..n].iter().map(|s| s.norm_sqr()).sum();
    if !(signal > 0.0 && signal.is_finite()) {
        return None;
    }
    let mut errors: Vec<f64> = received[..n]
        .iter()
        .zip(&ideal[..n])
        .map(|(r, s)| (r - s).norm_sqr())
        .collect();
    let error: f64 = errors.iter().sum();
    if !error.is_finite() {
        return None;
    }
    let rms_s = (signal / n as f64).sqrt();
    errors.sort_by(f64::total_cmp);
    let k = ((0.95 * n as f64).ceil() as usize).clamp(1, n) - 1;
    Some(LinkQuality {
        evm_rms_pct: 100.0 * (error / signal).sqrt(),
        evm_p95_pct: 100.0 * errors[k].sqrt() / rms_s,
        mer_db: if error > 0.0 {
            10.0 * (signal / error).log10()
        } else {
            f64::INFINITY
        },
        symbols: n,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::rng::SplitMix64;

    #[test]
    fn mer_of_white_noise_is_the_symbol_snr() {
        let mut rng = SplitMix64::new(7);
        let sigma = 0.1; // per component: N = 0.02 on unit symbols, MER 16.99 dB
        let ideal: Vec<Complex64> = (0..200_000)
            .map(|k| Complex64::new(if k % 2 == 0 { 1.0 } else { -1.0 }, 0.0))
            .collect();
        let rx: Vec<Complex64> = ideal
            .iter()
            .map(|s| s + Complex64::new(sigma * rng.gaussian(), sigma * rng.gaussian()))
            .collect();
        let q = link_quality(&rx, &ideal).unwrap();
        assert!((q.mer_db - 16.99).abs() < 0.05, "{q:?}");
        assert!((q.evm_rms_pct - 14.14).abs() < 0.1, "{q:?}");
        // |e| / sigma is Rayleigh with scale 1: its 95th percentile is sqrt(2 ln 20) = 2.448.
        assert!((q.evm_p95_pct - 100.0 * 2.448 * sigma).abs() < 0.5, "{q:?}");
        assert_eq!(q.symbols, 200_000);
        assert!(link_quality(&[], &ideal).is_none());
        assert_eq!(link_quality(&ideal, &ideal).unwrap().evm_rms_pct, 0.0);
    }
}
