//! Seeded, portable randomness: SplitMix64 (thesis-notes.md) and Gaussian noise from it.
//!
//! Every random thing radbench does (PRBS bits, noise, Monte-Carlo trials) comes from a [`SplitMix64`]
//! with a seed the user can see and set, so every figure is reproducible bit for bit.

use num_complex::Complex64;

/// SplitMix64: tiny, portable, and identical to the reference in thesis-notes.md.
#[derive(Debug, Clone)]
pub struct SplitMix64 {
    state: u64,
    /// A spare normal deviate from the last Box-Muller pair.
    spare: Option<f64>,
}

impl SplitMix64 {
    pub fn new(seed: u64) -> Self {
        Self {
            state: seed,
            spare: None,
        }
    }

    pub fn next_u64(&mut self) -> u64 {
        self.state = self.state.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.state;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }

    /// `n` bits, taken least significant first from successive 64-bit words.
    pub fn bits(&mut self, n: usize) -> Vec<u8> {
        let mut out = Vec::with_capacity(n);
        while out.len() < n {
            let word = self.next_u64();
            let take = (n - out.len()).min(64);
            out.extend((0..take).map(|k| ((word >> k) & 1) as u8));
        }
        out
    }

    /// Uniform in [0, 1) with 53 random bits.
    pub fn uniform(&mut self) -> f64 {
        (self.next_u64() >> 11) as f64 * (1.0 / (1u64 << 53) as f64)
    }

    /// Standard normal deviate (Box-Muller).
    pub(crate) fn gaussian(&mut self) -> f64 {
        if let Some(z) = self.spare.take() {
            return z;
        }
        // 1 - u is in (0, 1], so the log is finite.
        let u1 = 1.0 - self.uniform();
        let u2 = self.uniform();
        let r = (-2.0 * u1.ln()).sqrt();
        let (s, c) = (2.0 * std::f64::consts::PI * u2).sin_cos();
        self.spare = Some(r * s);
        r * c
    }

    /// Circular complex Gaussian with total variance `variance` (half in I, half in Q).
    pub fn complex_gaussian(&mut self, variance: f64) -> Complex64 {
        let sigma = (variance / 2.0).sqrt();
        Complex64::new(sigma * self.gaussian(), sigma * self.gaussian())
    }

    /// Adds circular complex white noise of power `variance` per sample to `signal`.
    pub fn add_noise(&mut self, signal: &mut [Complex64], variance: f64) {
        for s in signal {
            *s += self.complex_gaussian(variance);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn splitmix_matches_reference_values() {
        // Reference: the first outputs of SplitMix64 seeded with 0.
        let mut r = SplitMix64::new(0);
        assert_eq!(r.next_u64(), 0xE220_A839_7B1D_CDAF);
        assert_eq!(r.next_u64(), 0x6E78_9E6A_A1B9_65F4);
    }

    #[test]
    fn gaussian_has_unit_variance() {
        let mut r = SplitMix64::new(7);
        let n = 200_000;
        let (mut s, mut s2) = (0.0, 0.0);
        for _ in 0..n {
            let g = r.gaussian();
            s += g;
            s2 += g * g;
        }
        let mean = s / n as f64;
        let var = s2 / n as f64 - mean * mean;
        assert!(mean.abs() < 0.01, "mean {mean}");
        assert!((var - 1.0).abs() < 0.02, "variance {var}");
    }
}
