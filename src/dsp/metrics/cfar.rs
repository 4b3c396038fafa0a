//! Cell-averaging CFAR detector for noisy power profiles.
//!
//! For each cell under test the noise power is the mean of `training` cells on each side, skipping
//! `guard` cells next to the cell (so a target's own main lobe does not raise its threshold). With
//! square-law (power) input and exponentially distributed noise (complex Gaussian noise), a threshold
//! `alpha * mean` with `alpha = n (pfa^(-1/n) - 1)` over `n` training cells gives the false-alarm
//! probability `pfa` exactly. Near the ends of the profile the window is one-sided (fewer training
//! cells) and `alpha` is recomputed for the cells actually used, so `pfa` holds everywhere.
//!
//! The thresholds come from the crate's one sliding-window CFAR (`super::threshold::LocalCfar`,
//! also behind `dsp::detect`), run here with adjacent training cells and nothing excluded.

use super::threshold::{CfarKind, LocalCfar};
use crate::dsp::DspError;

/// One detection: the strongest cell of a run of consecutive cells above threshold.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CfarDetection {
    pub index: usize,
    pub power: f64,
    pub threshold: f64,
}

/// A CA-CFAR detector; holds its scratch so repeated calls do not allocate.
#[derive(Debug, Clone)]
pub struct CaCfar {
    cfar: LocalCfar,
    exclude: Vec<bool>,
}

impl CaCfar {
    /// `guard` and `training` cells on each side of the cell under test; `pfa` in (0, 1).
    ///
    /// # Errors
    ///
    /// [`DspError::Param`] when `training` is 0 or `pfa` is not strictly between 0 and 1.
    pub fn new(guard: usize, training: usize, pfa: f64) -> Result<Self, DspError> {
        if training == 0 {
            return Err(DspError::Param(
                "CFAR: training = 0; allowed: at least 1 training cell per side (8-32 is typical)"
                    .into(),
            ));
        }
        if !(pfa > 0.0 && pfa < 1.0) {
            return Err(DspError::Param(format!(
                "CFAR: pfa = {pfa}; allowed: a false-alarm probability strictly between 0 and 1 \
                 (e.g. 1e-4)"
            )));
        }
        Ok(Self {
            cfar: LocalCfar::new(CfarKind::Ca, guard, training, 1, pfa)?,
            exclude: Vec::new(),
        })
    }

    /// Declares the profile oversampled `factor` times (the zero-padding factor of an OFDM
    /// profile): `factor` neighbouring cells count as one independent noise sample.
    ///
    /// # Errors
    ///
    /// [`DspError::Param`] when `factor` is 0.
    pub fn with_oversampling(mut self, factor: usize) -> Result<Self, DspError> {
        if factor == 0 {
            return Err(DspError::Param(
                "CFAR: oversampling = 0; allowed: 1 (independent cells) or the profile's                  zero-padding factor"
                    .into(),
            ));
        }
        self.cfar = self.cfar.with_cells_per_sample(factor);
        Ok(self)
    }

    /// The threshold multiplier for `n` training cells (counting `n / oversampling` independent
    /// samples, at least one).
    pub fn alpha(&self, n: usize) -> f64 {
        self.cfar.alpha_ca(n)
    }

    /// Writes the threshold of every cell of the power profile `power` into `thresholds` (same
    /// length) and returns the detections. A cell with no training cell at all (a profile shorter
    /// than the guard band) gets an infinite threshold.
    ///
    /// # Errors
    ///
    /// [`DspError::Param`] when `thresholds` and `power` differ in length.
    pub fn detect(
        &mut self,
        power: &[f64],
        thresholds: &mut [f64],
    ) -> Result<Vec<CfarDetection>, DspError> {
        let n = power.len();
        if thresholds.len() != n {
            return Err(DspError::Param(format!(
                "CFAR: thresholds has {} cells but the profile has {n}; give equal lengths",
                thresholds.len()
            )));
        }
        self.exclude.clear();
        self.exclude.resize(n, false);
        self.cfar.thresholds(power, &self.exclude, thresholds);
        let mut detections = Vec::new();
        let mut i = 0;
        while i < n {
            if power[i] > thresholds[i] {
                let mut best = i;
                while i < n && power[i] > thresholds[i] {
                    if power[i] > power[best] {
                        best = i;
                    }
                    i += 1;
                }
                detections.push(CfarDetection {
                    index: best,
                    power: power[best],
                    threshold: thresholds[best],
                });
            } else {
                i += 1;
            }
        }
        Ok(detections)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::rng::SplitMix64;

    #[test]
    fn false_alarm_rate_matches_pfa_on_noise() {
        let mut rng = SplitMix64::new(11);
        let power: Vec<f64> = (0..200_000)
            .map(|_| rng.complex_gaussian(1.0).norm_sqr())
            .collect();
        let mut cfar = CaCfar::new(2, 16, 1e-2).unwrap();
        let mut t = vec![0.0; power.len()];
        cfar.detect(&power, &mut t).unwrap();
        let exceed = power.iter().zip(&t).filter(|(p, t)| p > t).count();
        let rate = exceed as f64 / power.len() as f64;
        // 2000 expected; the binomial standard deviation is about 45.
        assert!((rate - 1e-2).abs() < 1e-3, "false-alarm rate {rate}");
    }

    #[test]
    fn finds_a_target_in_noise_once() {
        let mut rng = SplitMix64::new(3);
        let mut power: Vec<f64> = (0..1000)
            .map(|_| rng.complex_gaussian(1.0).norm_sqr())
            .collect();
        // A 20 dB target spread over three cells.
        power[499] += 30.0;
        power[500] += 100.0;
        power[501] += 30.0;
        let mut cfar = CaCfar::new(3, 16, 1e-4).unwrap();
        let mut t = vec![0.0; power.len()];
        let d = cfar.detect(&power, &mut t).unwrap();
        assert_eq!(d.len(), 1, "{d:?}");
        assert_eq!(d[0].index, 500);
    }

    /// The thresholds are those of the prefix-sum CA-CFAR this detector had before it called the
    /// shared sliding window (to rounding).
    #[test]
    fn thresholds_match_the_direct_formula() {
        let mut rng = SplitMix64::new(5);
        let power: Vec<f64> = (0..3000)
            .map(|_| rng.complex_gaussian(1.0).norm_sqr())
            .collect();
        for (guard, training, os) in [(2, 16, 1), (15, 40, 10), (0, 1, 1), (4000, 3, 1)] {
            let mut cfar = CaCfar::new(guard, training, 1e-3)
                .unwrap()
                .with_oversampling(os)
                .unwrap();
            let mut t = vec![0.0; power.len()];
            cfar.detect(&power, &mut t).unwrap();
            let n = power.len();
            for (i, &got) in t.iter().enumerate() {
                let left = i.saturating_sub(guard + training)..i.saturating_sub(guard);
                let right = (i + guard + 1).min(n)..(i + guard + training + 1).min(n);
                let cells = left.len() + right.len();
                let want = if cells == 0 {
                    f64::INFINITY
                } else {
                    let sum: f64 = power[left].iter().chain(&power[right]).sum();
                    let k = (cells as f64 / os as f64).max(1.0);
                    k * (1e-3f64.powf(-1.0 / k) - 1.0) * sum / cells as f64
                };
                assert!(
                    got == want || ((got - want) / want).abs() < 1e-12,
                    "guard {guard} training {training} cell {i}: {got} vs {want}"
                );
            }
        }
    }

    #[test]
    fn bad_parameters_are_errors() {
        assert!(CaCfar::new(2, 0, 1e-3).is_err());
        assert!(CaCfar::new(2, 8, 1.5).is_err());
        assert!(CaCfar::new(2, 8, 1e-3)
            .unwrap()
            .with_oversampling(0)
            .is_err());
        let mut c = CaCfar::new(2, 8, 1e-3).unwrap();
        assert!(c.detect(&[1.0; 4], &mut [0.0; 3]).is_err());
    }
}
