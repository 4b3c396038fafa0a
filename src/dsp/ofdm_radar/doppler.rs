//! Range-Doppler map: a range IFFT per symbol, then an FFT across symbols (slow time) per range bin.
//!
//! A target at range `R0 + v t` rotates the phase of its `I_div` entries by
//! `-2 pi f_c (2 v T) / C0` from one symbol to the next (`T` the symbol period with CP; the
//! Doppler shift inside one symbol is neglected, fine while `2 v f_c / C0 << df`). The map's
//! velocity axis is the *range rate*: positive = receding (range growing), ascending, with
//! `Q` bins spanning `[-v_max, v_max)`, `v_max = C0 / (4 f_c T)`, resolution `C0 / (2 f_c T Q)`.
//! With the thesis' defaults (80 GHz, 160 ns, 100 symbols) that is +-5.86 km/s in steps of 0.117
//! km/s: OFDM symbols are short, so Doppler resolution needs many symbols.
//!
//! Scaling: both windows are divided by their sums, so a stationary target of amplitude `a` shows
//! `a` at its cell.

use super::config::OfdmRadarConfig;
use super::idiv::IDiv;
use crate::dsp::Window;
use crate::dsp::{DspError, C0};
use num_complex::Complex64;
use rustfft::{Fft, FftPlanner};
use std::sync::Arc;

/// Parameters of the slow-time (Doppler) processing.
#[derive(Debug, Clone, PartialEq)]
pub struct RangeDopplerConfig {
    /// RF carrier, Hz (80e9 on the bench): sets the velocity scale.
    pub carrier_hz: f64,
    /// Slow-time sample period, s; `None` = one symbol with its CP ([`OfdmRadarConfig::symbol_period_s`]).
    pub symbol_period_s: Option<f64>,
    /// Doppler FFT length Q (zero-padded beyond the number of symbols); `None` = the number of symbols.
    pub doppler_bins: Option<usize>,
    /// Window across symbols (rectangular).
    pub doppler_window: Window,
}

impl Default for RangeDopplerConfig {
    fn default() -> Self {
        Self {
            carrier_hz: 80e9,
            symbol_period_s: None,
            doppler_bins: None,
            doppler_window: Window::Rectangular,
        }
    }
}

/// A range-Doppler map: `amplitude[m * velocity_mps.len() + q]` for range bin m, velocity bin q.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct RangeDopplerMap {
    pub range_m: Vec<f64>,
    pub velocity_mps: Vec<f64>,
    pub amplitude: Vec<f64>,
}

impl RangeDopplerMap {
    /// The amplitude at range bin `m`, velocity bin `q`.
    pub fn at(&self, m: usize, q: usize) -> f64 {
        self.amplitude[m * self.velocity_mps.len() + q]
    }

    /// (range bin, velocity bin, amplitude) of the strongest cell.
    pub fn strongest(&self) -> Option<(usize, usize, f64)> {
        let q = self.velocity_mps.len();
        let (i, a) = self
            .amplitude
            .iter()
            .enumerate()
            .max_by(|a, b| a.1.total_cmp(b.1))?;
        Some((i / q, i % q, *a))
    }
}

/// Range-Doppler processor for a fixed number of symbols; plans and the K x Q scratch matrix are
/// made once.
pub struct RangeDoppler {
    symbols: usize,
    subcarriers: usize,
    bins: usize,
    range_ifft: Arc<dyn Fft<f64>>,
    doppler_fft: Arc<dyn Fft<f64>>,
    range_weights: Vec<f64>,
    doppler_weights: Vec<f64>,
    column: Vec<Complex64>,
    scratch: Vec<Complex64>,
    matrix: Vec<Complex64>,
    range_m: Vec<f64>,
    velocity_mps: Vec<f64>,
}

impl RangeDoppler {
    /// A processor for `symbols` symbols of the receiver described by `radar` (its subcarriers,
    /// zero padding and subcarrier window are used).
    ///
    /// # Errors
    ///
    /// [`DspError::Param`] when `radar` or the Doppler window is invalid, `symbols` is below 2, the
    /// carrier or symbol period is not positive and finite, or `doppler_bins` is below `symbols`.
    pub fn new(
        radar: &OfdmRadarConfig,
        symbols: usize,
        config: &RangeDopplerConfig,
    ) -> Result<Self, DspError> {
        radar.validate()?;
        config.doppler_window.validate()?;
        if symbols < 2 {
            return Err(DspError::Param(format!(
                "range-Doppler: {symbols} symbols; allowed: at least 2 (velocity needs slow time)"
            )));
        }
        if !(config.carrier_hz.is_finite() && config.carrier_hz > 0.0) {
            return Err(DspError::Param(format!(
                "range-Doppler: carrier_hz = {}; allowed: a positive frequency (80e9 on the bench)",
                config.carrier_hz
            )));
        }
        let period = config
            .symbol_period_s
            .unwrap_or_else(|| radar.symbol_period_s());
        if !(period.is_finite() && period > 0.0) {
            return Err(DspError::Param(format!(
                "range-Doppler: symbol_period_s = {period}; allowed: a positive duration"
            )));
        }
        let bins = config.doppler_bins.unwrap_or(symbols);
        if bins < symbols {
            return Err(DspError::Param(format!(
                "range-Doppler: doppler_bins = {bins}; allowed: at least the number of symbols \
                 ({symbols})"
            )));
        }
        let k = radar.profile_len();
        let mut planner = FftPlanner::new();
        let range_ifft = planner.plan_fft_inverse(k);
        let doppler_fft = planner.plan_fft_forward(bins);
        let normalised = |w: Vec<f64>| {
            let s: f64 = w.iter().sum();
            w.into_iter().map(|x| x / s).collect::<Vec<_>>()
        };
        let range_weights = normalised(radar.window.coefficients(radar.subcarriers)?);
        let doppler_weights = normalised(config.doppler_window.coefficients(symbols)?);
        let scratch_len = range_ifft
            .get_inplace_scratch_len()
            .max(doppler_fft.get_inplace_scratch_len());
        let step_v = C0 / (2.0 * config.carrier_hz * period * bins as f64);
        let half = (bins / 2) as f64;
        let zero = Complex64::default();
        Ok(Self {
            symbols,
            subcarriers: radar.subcarriers,
            bins,
            range_ifft,
            doppler_fft,
            range_weights,
            doppler_weights,
            column: vec![zero; k],
            scratch: vec![zero; scratch_len],
            matrix: vec![zero; k * bins],
            range_m: (0..k).map(|m| m as f64 * radar.range_bin_m()).collect(),
            velocity_mps: (0..bins).map(|j| (j as f64 - half) * step_v).collect(),
        })
    }

    /// Computes the map of `idiv` (exactly the symbol count given to [`RangeDoppler::new`]).
    ///
    /// # Errors
    ///
    /// [`DspError::Param`] when `idiv` does not have the symbol and subcarrier counts this processor
    /// was made for.
    pub fn process(&mut self, idiv: &IDiv, out: &mut RangeDopplerMap) -> Result<(), DspError> {
        if idiv.symbols() != self.symbols || idiv.subcarriers() != self.subcarriers {
            return Err(DspError::Param(format!(
                "range-Doppler: I_div has {} symbols of {} subcarriers; this processor was made for \
                 {} of {}",
                idiv.symbols(),
                idiv.subcarriers(),
                self.symbols,
                self.subcarriers
            )));
        }
        let q = self.bins;
        self.matrix.fill(Complex64::default());
        for s in 0..self.symbols {
            self.column.fill(Complex64::default());
            let ws = self.doppler_weights[s];
            for ((c, v), w) in self
                .column
                .iter_mut()
                .zip(idiv.symbol(s))
                .zip(&self.range_weights)
            {
                *c = v * (w * ws);
            }
            self.range_ifft
                .process_with_scratch(&mut self.column, &mut self.scratch);
            for (m, c) in self.column.iter().enumerate() {
                self.matrix[m * q + s] = *c;
            }
        }
        self.doppler_fft
            .process_with_scratch(&mut self.matrix, &mut self.scratch);
        out.range_m.clone_from(&self.range_m);
        out.velocity_mps.clone_from(&self.velocity_mps);
        out.amplitude.resize(self.matrix.len(), 0.0);
        // Velocity bin j (ascending range rate) holds Doppler frequency index (Q/2 - j) mod Q:
        // a receding target's phase turns backwards.
        let half = q / 2;
        for (row_in, row_out) in self
            .matrix
            .chunks_exact(q)
            .zip(out.amplitude.chunks_exact_mut(q))
        {
            for (j, o) in row_out.iter_mut().enumerate() {
                *o = row_in[(half + q - j) % q].norm();
            }
        }
        Ok(())
    }
}

/// Radial velocity of one target from the slow time of its own range: the profile value at the
/// target's (fractional) range bin, symbol by symbol, through a zero-padded FFT across symbols,
/// peak interpolated. Much cheaper than a whole [`RangeDopplerMap`] (one FFT per target); the
/// velocity follows the map's convention (range rate, positive = receding).
pub(crate) struct VelocityEstimator {
    symbols: usize,
    fft: Arc<dyn Fft<f64>>,
    buf: Vec<Complex64>,
    scratch: Vec<Complex64>,
    period_s: f64,
    carrier_hz: f64,
}

impl VelocityEstimator {
    /// For `symbols` symbols of `period_s` each (CP included) at carrier `carrier_hz`; the
    /// slow-time FFT is zero-padded to at least 8 points per symbol.
    pub(crate) fn new(symbols: usize, period_s: f64, carrier_hz: f64) -> Result<Self, DspError> {
        if symbols < 2 {
            return Err(DspError::Param(format!(
                "velocity: {symbols} symbols; allowed: at least 2 (velocity needs slow time)"
            )));
        }
        if !(period_s.is_finite() && period_s > 0.0 && carrier_hz.is_finite() && carrier_hz > 0.0) {
            return Err(DspError::Param(format!(
                "velocity: symbol period {period_s} s, carrier {carrier_hz} Hz; allowed: positive"
            )));
        }
        let q = (8 * symbols).next_power_of_two();
        let fft = FftPlanner::new().plan_fft_forward(q);
        let zero = Complex64::default();
        Ok(Self {
            symbols,
            scratch: vec![zero; fft.get_inplace_scratch_len()],
            fft,
            buf: vec![zero; q],
            period_s,
            carrier_hz,
        })
    }

    /// The Doppler resolution of the frame, m/s: `C0 / (2 f_c S T)`.
    pub(crate) fn resolution_mps(&self) -> f64 {
        C0 / (2.0 * self.carrier_hz * self.symbols as f64 * self.period_s)
    }

    /// The range rate of the target at fractional bin `x` of a `k_len`-point range IFFT of
    /// `idiv` weighted by `weights` (one per subcarrier), m/s.
    pub(crate) fn estimate(
        &mut self,
        idiv: &IDiv,
        weights: &[f64],
        x: f64,
        k_len: usize,
    ) -> Result<f64, DspError> {
        let n = idiv.subcarriers();
        if idiv.symbols() != self.symbols || weights.len() != n || k_len < n {
            return Err(DspError::Param(format!(
                "velocity: I_div has {} symbols of {n} subcarriers ({} weights, {k_len}-point \
                 IFFT); this estimator was made for {} symbols",
                idiv.symbols(),
                weights.len(),
                self.symbols
            )));
        }
        // The range-IFFT kernel at x, once for all symbols.
        let kernel: Vec<Complex64> = (0..n)
            .map(|k| {
                Complex64::from_polar(
                    weights[k],
                    2.0 * std::f64::consts::PI * k as f64 * x / k_len as f64,
                )
            })
            .collect();
        self.buf.fill(Complex64::default());
        for s in 0..self.symbols {
            self.buf[s] = idiv.symbol(s).iter().zip(&kernel).map(|(a, b)| a * b).sum();
        }
        self.fft
            .process_with_scratch(&mut self.buf, &mut self.scratch);
        let q = self.buf.len();
        let mag = |j: usize| self.buf[j % q].norm().max(1e-300).ln();
        let (peak, _) = self
            .buf
            .iter()
            .enumerate()
            .max_by(|a, b| a.1.norm_sqr().total_cmp(&b.1.norm_sqr()))
            .expect("at least one bin");
        let (l, c, r) = (mag(peak + q - 1), mag(peak), mag(peak + 1));
        let den = l - 2.0 * c + r;
        let delta = if den < 0.0 { 0.5 * (l - r) / den } else { 0.0 };
        let signed = if peak <= q / 2 {
            peak as f64
        } else {
            peak as f64 - q as f64
        } + delta;
        let doppler_hz = signed / (q as f64 * self.period_s);
        // A receding target's phase turns backwards: range rate = -f_D c0 / (2 f_c).
        Ok(-doppler_hz * C0 / (2.0 * self.carrier_hz))
    }
}
