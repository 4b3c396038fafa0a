//! Range profiles shared by simulations and bench captures: a labelled profile on a range axis,
//! the correlation profile of a transmitted signal, and the MUSIC pseudo-spectrum as a profile.

use super::correlate::CrossCorrelator;
use super::metrics::Axis;
use super::{DspError, C0};
use num_complex::Complex64;

const ZERO: Complex64 = Complex64 { re: 0.0, im: 0.0 };

/// Floor of the weighted filter's spectral division, relative to the mean in-band power: bins
/// this weak are not amplified into noise. At 1e-2 the MSK-LFM's data left enough of its
/// spectrum's dips in the filter to hold Dolph-Chebyshev at -46.8 dB instead of -50 (ideal
/// chain); at 1e-4 it reaches -49.1 dB for 0.3 dB more SNR lost (docs/capture.md).
const REGULARISATION: f64 = 1e-4;

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
    pub(crate) fn normalised_db(&self) -> Vec<f64> {
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
    /// What a unit echo peaks at (the transmit energy, or the weighted filter's gain).
    energy: f64,
}

impl CorrelationProfiler {
    /// A correlation profiler of `tx` for captures of up to `rx_len` samples, over the lags
    /// `0..lags` at `fs_hz`.
    ///
    /// # Errors
    ///
    /// Those of [`CrossCorrelator::new`].
    pub fn new(tx: &[Complex64], rx_len: usize, lags: usize, fs_hz: f64) -> Result<Self, DspError> {
        let last = (lags.max(1) - 1).min(rx_len.saturating_sub(1)) as isize;
        let correlator = CrossCorrelator::new(tx, rx_len, 0..=last)?;
        Ok(Self {
            out: vec![ZERO; correlator.output_len()],
            correlator,
            fs_hz,
            energy: tx.iter().map(|v| v.norm_sqr()).sum::<f64>().max(1e-300),
        })
    }

    /// Correlation against `filter` (a mismatched filter, e.g. [`weighted_filter`]) instead of `tx`
    /// itself; levels stay normalised so a unit echo of `tx` peaks at 1.
    pub(crate) fn with_filter(
        tx: &[Complex64],
        filter: &[Complex64],
        rx_len: usize,
        lags: usize,
        fs_hz: f64,
    ) -> Result<Self, DspError> {
        if filter.len() != tx.len() {
            return Err(DspError::Param(format!(
                "correlation filter of {} samples for a {}-sample transmit signal; give equal \
                 lengths",
                filter.len(),
                tx.len()
            )));
        }
        let last = (lags.max(1) - 1).min(rx_len.saturating_sub(1)) as isize;
        let correlator = CrossCorrelator::new(filter, rx_len, 0..=last)?;
        // A unit echo of tx peaks at |sum tx conj(filter)|.
        let gain = tx
            .iter()
            .zip(filter)
            .map(|(a, b)| a * b.conj())
            .sum::<Complex64>()
            .norm()
            .max(1e-300);
        Ok(Self {
            out: vec![ZERO; correlator.output_len()],
            correlator,
            fs_hz,
            energy: gain,
        })
    }

    /// The complex lags `r[l] / E` (E = transmit energy, so a unit echo peaks at magnitude 1), the
    /// input of `crate::dsp::detect`; valid until the next call. Same definition and lag order as
    /// [`CorrelationProfiler::profile`], whose amplitude is the magnitude of these values.
    ///
    /// # Errors
    ///
    /// [`DspError::Param`] when `rx` is longer than the `rx_len` given to `new`.
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

    /// The correlation magnitude profile of `rx`, normalised so a unit echo of `tx` peaks at 1.
    ///
    /// # Errors
    ///
    /// [`DspError::Param`] when `rx` is longer than the `rx_len` given to `new`.
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
pub(crate) fn music_profile(
    range_m: &[f64],
    pseudo_spectrum: &[f64],
    m: usize,
    p: usize,
) -> Profile {
    Profile {
        label: format!("MUSIC (M = {m}, p = {p})"),
        axis: Axis::from_samples(range_m),
        amplitude: pseudo_spectrum.iter().map(|v| v.max(0.0).sqrt()).collect(),
    }
}

/// A weighted (mismatched) filter for [`CorrelationProfiler::with_filter`]: across the occupied band
/// `band_hz = [low, high]` (zero outside it) the matched filter's spectrum is flattened and
/// multiplied by `window`, so an echo's correlation has the window's side-lobes, for a wider main
/// lobe and a small loss of SNR. `tx` is one period of a periodic signal.
pub(crate) fn weighted_filter(
    tx: &[Complex64],
    window: &super::window::Window,
    band_hz: [f64; 2],
    fs_hz: f64,
) -> Result<Vec<Complex64>, DspError> {
    let bandwidth_hz = band_hz[1] - band_hz[0];
    let centre_hz = 0.5 * (band_hz[0] + band_hz[1]);
    let n = tx.len();
    if n == 0 {
        return Err(DspError::Param(
            "weighted correlation: the transmit signal is empty".into(),
        ));
    }
    if !(bandwidth_hz.is_finite()
        && bandwidth_hz > 0.0
        && centre_hz.abs() + bandwidth_hz / 2.0 <= fs_hz / 2.0)
    {
        return Err(DspError::Param(format!(
            "weighted correlation: the band {} .. {} Hz must be above 0 wide and within the \
             Nyquist band of the sample rate {fs_hz} Sa/s",
            band_hz[0], band_hz[1]
        )));
    }
    let mut spec = tx.to_vec();
    super::plans::forward(n).process(&mut spec);
    // Bins inside the band, ascending frequency, get the window's coefficients; the transmit
    // spectrum's own ripple is divided out (regularised where it is weak) so the output spectrum
    // of an echo is the window itself and the side-lobes are the window's.
    let half = ((bandwidth_hz / 2.0) / fs_hz * n as f64).floor() as isize;
    let centre = (centre_hz / fs_hz * n as f64).round() as isize;
    let width = (2 * half + 1) as usize;
    let coeffs = window.coefficients(width)?;
    let in_band = |k: usize| {
        let f = if k <= n / 2 {
            k as isize
        } else {
            k as isize - n as isize
        } - centre;
        (f.abs() <= half).then_some((f + half) as usize)
    };
    let mean_power = (0..n)
        .filter_map(|k| in_band(k).map(|_| spec[k].norm_sqr()))
        .sum::<f64>()
        / width as f64;
    let floor = REGULARISATION * mean_power;
    for (k, v) in spec.iter_mut().enumerate() {
        *v = match in_band(k) {
            Some(i) => *v * (coeffs[i] / (v.norm_sqr() + floor)) * mean_power / n as f64,
            None => ZERO,
        };
    }
    super::plans::inverse(n).process(&mut spec);
    Ok(spec)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn an_empty_capture_is_a_parameter_error_not_an_overflow() {
        let tx = vec![Complex64::new(1.0, 0.0); 8];
        for lags in [0, 1, 5] {
            assert!(matches!(
                CorrelationProfiler::new(&tx, 0, lags, 16e9),
                Err(DspError::Param(_))
            ));
        }
        assert!(CorrelationProfiler::new(&tx, 16, 4, 16e9).is_ok());
    }
}
