//! Range profiles shared by simulations and bench captures: a labelled profile on a range axis,
//! the correlation profile of a transmitted signal, and the MUSIC pseudo-spectrum as a profile.

use super::correlate::CrossCorrelator;
use super::metrics::Axis;
use super::{DspError, C0};
use num_complex::Complex64;

const ZERO: Complex64 = Complex64 { re: 0.0, im: 0.0 };

/// A range profile: linear amplitude on a uniform range axis (metres).
#[derive(Debug, Clone)]
pub struct Profile {
    pub label: String,
    pub axis: Axis,
    pub amplitude: Vec<f64>,
}

impl Profile {
    pub fn ranges(&self) -> Vec<f64> {
        (0..self.amplitude.len())
            .map(|i| self.axis.at(i as f64))
            .collect()
    }

    /// 20 log10 of the amplitude relative to the maximum.
    pub fn normalised_db(&self) -> Vec<f64> {
        let max = self
            .amplitude
            .iter()
            .cloned()
            .fold(0.0, f64::max)
            .max(1e-300);
        self.amplitude
            .iter()
            .map(|a| crate::dsp::metrics::amplitude_db(a / max))
            .collect()
    }
}

/// Correlation range profile: lags `0..lags` of `r[l] = sum rx[n] conj(tx[n - l])`, normalised by
/// the transmit energy so a unit echo peaks at 1.
pub struct CorrelationProfiler {
    correlator: CrossCorrelator,
    out: Vec<Complex64>,
    fs_hz: f64,
    energy: f64,
}

impl CorrelationProfiler {
    pub fn new(tx: &[Complex64], rx_len: usize, lags: usize, fs_hz: f64) -> Result<Self, DspError> {
        let last = (lags.max(1) - 1).min(rx_len - 1) as isize;
        let correlator = CrossCorrelator::new(tx, rx_len, 0..=last)?;
        Ok(Self {
            out: vec![ZERO; correlator.output_len()],
            correlator,
            fs_hz,
            energy: tx.iter().map(|v| v.norm_sqr()).sum::<f64>().max(1e-300),
        })
    }

    /// The complex lags `r[l] / E` (E = transmit energy, so a unit echo peaks at magnitude 1), the
    /// input of [`crate::dsp::detect`]; valid until the next call. Same definition and lag order as
    /// [`CorrelationProfiler::profile`], whose amplitude is the magnitude of these values.
    pub fn complex_profile(&mut self, rx: &[Complex64]) -> Result<&[Complex64], DspError> {
        self.correlator.correlate_into(rx, &mut self.out)?;
        let scale = 1.0 / self.energy;
        for v in &mut self.out {
            *v *= scale;
        }
        Ok(&self.out)
    }

    /// The range step of the lags, m: `C0 / (2 fs)`.
    pub fn axis(&self) -> Axis {
        Axis {
            start: 0.0,
            step: C0 / (2.0 * self.fs_hz),
        }
    }

    pub fn profile(&mut self, rx: &[Complex64]) -> Result<Profile, DspError> {
        self.correlator.correlate_into(rx, &mut self.out)?;
        Ok(Profile {
            label: "correlation".into(),
            axis: Axis {
                start: 0.0,
                step: C0 / (2.0 * self.fs_hz),
            },
            amplitude: self.out.iter().map(|v| v.norm() / self.energy).collect(),
        })
    }
}

/// MUSIC pseudo-spectrum as a profile: amplitude sqrt(P), so its dB scale is 10 log10 P.
pub fn music_profile(range_m: &[f64], pseudo_spectrum: &[f64], m: usize, p: usize) -> Profile {
    Profile {
        label: format!("MUSIC (M = {m}, p = {p})"),
        axis: Axis::from_samples(range_m),
        amplitude: pseudo_spectrum.iter().map(|v| v.max(0.0).sqrt()).collect(),
    }
}
