//! Ranging to a fraction of the carrier's wavelength: what a fitted echo's envelope and carrier
//! phase can tell of its range, and how sure each is (docs/metrology.md).
//!
//! A record's echo of delay `tau` is `a s(t - tau) exp(-j 2 pi f_c tau)`: the envelope `s` moves
//! with the scope's trigger (its sampling instants are late or early by the jitter), the carrier
//! phase does not (the record is already down-converted). A profile fitted with its point spread
//! gives both: the position (envelope) and the complex amplitude, whose phase is the carrier's at
//! the fitted position; an error `e` of that position turns it by `2 pi f_mean e` (the band's
//! centroid), which the uncertainty carries.

use num_complex::Complex64;
use std::f64::consts::PI;

/// What a profile's spectrum gives the range estimates: the band's centroid and its effective
/// RMS width.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct BandShape {
    /// Power-weighted mean baseband frequency of the profile's point spread, Hz.
    pub mean_hz: f64,
    /// Effective RMS bandwidth about that mean, Hz: the delay's Cramer-Rao bound is
    /// `1 / (2 pi B sqrt(2 SNR))` with the SNR per profile cell (the window's mismatch included).
    pub rms_hz: f64,
}

impl BandShape {
    /// From one period's echo spectrum `S_k conj(F_k)` (`cross`) and filter power `|F_k|^2`
    /// (`filter_power`) at bins `k` of `fs / n`. With a matched filter (`F = S`) this is the
    /// band's RMS width; with a weighted filter `F = S W`, the width a least-squares fit on the
    /// weighted profile reaches:
    /// `B^2 = (sum f^2 |S|^2 W)^2 sum |S|^2 W^2 / ((sum |S|^2 W)^2 sum f^2 |S|^2 W^2)`.
    pub(crate) fn of_spectrum(cross: &[Complex64], filter_power: &[f64], fs: f64) -> Option<Self> {
        let n = cross.len();
        if n == 0 || filter_power.len() != n {
            return None;
        }
        let freq = |k: usize| {
            let signed = if k <= n / 2 {
                k as f64
            } else {
                k as f64 - n as f64
            };
            signed * fs / n as f64
        };
        let s1: f64 = cross.iter().map(|c| c.re).sum();
        if s1 <= 0.0 {
            return None;
        }
        let mean = cross
            .iter()
            .enumerate()
            .map(|(k, c)| freq(k) * c.re)
            .sum::<f64>()
            / s1;
        let m2_cross: f64 = cross
            .iter()
            .enumerate()
            .map(|(k, c)| (freq(k) - mean).powi(2) * c.re)
            .sum();
        let p0: f64 = filter_power.iter().sum();
        let p2: f64 = filter_power
            .iter()
            .enumerate()
            .map(|(k, p)| (freq(k) - mean).powi(2) * p)
            .sum();
        let b2 = m2_cross * m2_cross * p0 / (s1 * s1 * p2);
        (b2.is_finite() && b2 > 0.0).then(|| BandShape {
            mean_hz: mean,
            rms_hz: b2.sqrt(),
        })
    }

    /// The envelope's standard uncertainty of range at `snr` (linear, per profile cell), m.
    pub(crate) fn envelope_std_m(&self, snr: f64) -> f64 {
        crate::physics::C0 / (4.0 * PI * self.rms_hz * (2.0 * snr).sqrt())
    }
}

/// The carrier phase's standard uncertainty at `snr` (linear, per profile cell), rad.
pub(crate) fn phase_std_rad(snr: f64) -> f64 {
    1.0 / (2.0 * snr).sqrt()
}

/// Metres of range per radian of the echo's carrier phase (`lambda / 4 pi`).
pub(crate) fn metres_per_radian(carrier_hz: f64) -> f64 {
    crate::physics::C0 / (4.0 * PI * carrier_hz)
}

/// `x` wrapped into `(-pi, pi]`.
pub(crate) fn wrap(x: f64) -> f64 {
    let w = (x + PI).rem_euclid(2.0 * PI) - PI;
    if w <= -PI {
        w + 2.0 * PI
    } else {
        w
    }
}

/// The envelope's uncertainty over which unwrapping is refused: a quarter of the half-wavelength
/// ambiguity (`lambda / 8`), about 2.6 sd from a wrong cycle.
pub(crate) fn unwrap_limit_m(carrier_hz: f64) -> f64 {
    crate::physics::C0 / carrier_hz / 8.0
}

/// A range from the carrier phase. `phase_rad` is the echo's phase relative to the anchor's (an
/// echo's phase falls by `4 pi / lambda` per metre of range), so the range is one of
/// `anchor_m - phase lambda / 4 pi + n lambda / 2`: the one nearest `rough_m`, the envelope's
/// range of standard uncertainty `rough_std_m`. `None` when the envelope cannot tell the cycle
/// (its uncertainty over [`unwrap_limit_m`]).
pub(crate) fn unwrap_range(
    anchor_m: f64,
    phase_rad: f64,
    rough_m: f64,
    rough_std_m: f64,
    carrier_hz: f64,
) -> Option<f64> {
    if !(rough_std_m.is_finite() && rough_std_m <= unwrap_limit_m(carrier_hz)) {
        return None;
    }
    let per_rad = metres_per_radian(carrier_hz);
    let fine = anchor_m - wrap(phase_rad) * per_rad;
    let half_lambda = 2.0 * PI * per_rad;
    let cycles = ((rough_m - fine) / half_lambda).round();
    Some(fine + cycles * half_lambda)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_flat_band_has_its_textbook_rms_width_and_centroid() {
        // 1 GHz flat from 0 to 1 GHz of a 4 GHz rate: B_rms = 1 GHz / sqrt(12).
        let n = 4000;
        let fs = 4e9;
        let cross: Vec<Complex64> = (0..n)
            .map(|k| Complex64::new(if k < 1000 { 1.0 } else { 0.0 }, 0.0))
            .collect();
        let power: Vec<f64> = cross.iter().map(|c| c.re).collect();
        let b = BandShape::of_spectrum(&cross, &power, fs).unwrap();
        assert!((b.mean_hz - 0.4995e9).abs() < 1e6, "{b:?}");
        assert!(
            (b.rms_hz / (1e9 / 12f64.sqrt()) - 1.0).abs() < 1e-3,
            "{b:?}"
        );
        // 68 dB per cell: about 23 um (the "about 20 um").
        let std = b.envelope_std_m(10f64.powf(6.8));
        assert!((20e-6..26e-6).contains(&std), "{std}");
    }

    #[test]
    fn unwrapping_takes_the_cycle_the_envelope_points_to_and_refuses_a_vague_envelope() {
        let fc = 80e9;
        let half = PI * 2.0 * metres_per_radian(fc);
        for true_m in [1.0, 1.000_037, 1.03, 1.0 + 0.26 * half, 1.0 + 0.49 * half] {
            let phase = -(true_m - 1.0) / metres_per_radian(fc);
            for rough_err in [-0.2e-3, 0.0, 0.3e-3] {
                let got = unwrap_range(1.0, phase, true_m + rough_err, 0.2e-3, fc).unwrap();
                assert!((got - true_m).abs() < 1e-9, "{true_m}: {got}");
            }
        }
        assert!(unwrap_range(1.0, 0.0, 1.0, 0.5e-3, fc).is_none());
        assert!((wrap(3.0 * PI) - PI).abs() < 1e-12 && wrap(-PI) == PI);
    }
}
