//! Complex white Gaussian noise at a per-sample SNR (thesis-notes.md: per target of unit amplitude,
//! per complex sample at the rate of the capture).

use crate::rng::SplitMix64;
use num_complex::Complex64;

/// Noise power per complex sample for a unit-amplitude target at `snr_db`.
pub(crate) fn noise_variance(snr_db: f64) -> f64 {
    10f64.powf(-snr_db / 10.0)
}

/// Adds circular complex white noise so that a unit-amplitude echo has `snr_db` per sample.
/// `None` leaves the signal noise-free.
pub(crate) fn add_noise(signal: &mut [Complex64], snr_db: Option<f64>, rng: &mut SplitMix64) {
    if let Some(snr) = snr_db {
        rng.add_noise(signal, noise_variance(snr));
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn measured_snr_matches_the_request() {
        let mut rng = SplitMix64::new(3);
        let mut x = vec![Complex64::new(0.0, 0.0); 100_000];
        add_noise(&mut x, Some(10.0), &mut rng);
        let power = x.iter().map(|v| v.norm_sqr()).sum::<f64>() / x.len() as f64;
        assert!((10.0 * power.log10() + 10.0).abs() < 0.05, "power {power}");
    }

    #[test]
    fn none_is_noise_free() {
        let mut rng = SplitMix64::new(3);
        let mut x = vec![Complex64::new(1.0, 0.0); 10];
        add_noise(&mut x, None, &mut rng);
        assert!(x.iter().all(|v| *v == Complex64::new(1.0, 0.0)));
    }
}
