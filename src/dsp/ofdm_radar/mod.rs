//! OFDM radar (thesis 3.2.2): symbol framing, CP removal, FFT, spectral division
//! `I_div = I_rx / I_tx`, zero-padded IFFT over subcarriers, averaging over symbols, windows, and a
//! range-Doppler map ([`RangeDoppler`]) for moving targets.
//!
//! # Conventions (CONVENTIONS.md)
//! - Subcarrier `k = 0..N-1` sits at baseband `f_k = (k - N/2) df`, `df = B/N`, and is read from
//!   receiver FFT bin `(k - N/2) mod (N os)`. [`IDiv`] and every spectrum here are in this
//!   *ascending-frequency* order, symbol-major (`[symbol][k]`).
//! - Scaling: the transmitter's IFFT scale (`1/sqrt N`, unit mean power per sample) is undone, so a
//!   target of amplitude `a` at delay `tau` gives `I_div[s][k] = a exp(-j 2 pi (f_c + f_k) tau)`,
//!   whatever the oversampling.
//! - Range profile: `p[m] = sum_k w_k I_div[k] exp(+j 2 pi k m / K) / sum_k w_k`, K = zero_pad N,
//!   bin m at `R = m C0 / (2 K df)` from 0 to the unambiguous range `C0 / (2 df)` (19.2 m by
//!   default). Dividing by the window sum keeps a target of amplitude `a` at height `a` (windows
//!   only widen the lobe). Subcarriers go into the IFFT in ascending order *before* the zero padding
//!   (FFT order plus appended zeros is only right for whole-nanosecond delays: thesis-notes.md).
//! - Averaging over symbols ([`Averaging`]): coherent by default. For a static scene every symbol
//!   sees the same `I_div`, so averaging `I_div` before one IFFT lowers the noise floor by the
//!   number of symbols (10 log10 S dB) and costs one IFFT; averaging powers only smooths the noise
//!   floor (its mean stays) but is immune to Doppler phase rotation, so use it for moving targets
//!   you do not want to resolve in velocity (or use the range-Doppler map).

mod config;
mod doppler;
mod idiv;
mod numerology;

pub use config::{Averaging, FftPrecision, OfdmRadarConfig};
pub(crate) use doppler::VelocityEstimator;
pub use doppler::{RangeDoppler, RangeDopplerConfig, RangeDopplerMap};
pub use idiv::IDiv;
pub(crate) use numerology::{Fault as NumerologyFault, Numerology, Sizes};

use super::metrics::Axis;
use super::{DspError, C0};
use num_complex::{Complex32, Complex64};
use rustfft::{Fft, FftPlanner};
use std::sync::Arc;

/// A range profile: linear amplitude (a unit-amplitude target peaks at 1) against range in metres.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct RangeProfile {
    pub range_m: Vec<f64>,
    pub amplitude: Vec<f64>,
}

impl RangeProfile {
    pub fn new() -> Self {
        Self::default()
    }

    /// The uniform range axis (start 0, step one bin).
    pub fn axis(&self) -> Axis {
        Axis::from_samples(&self.range_m)
    }
}

/// The OFDM radar receiver: FFT plans, window and scratch are made once in [`OfdmRadar::new`];
/// processing allocates nothing once the output buffers have their size.
pub struct OfdmRadar {
    config: OfdmRadarConfig,
    symbol_fft: SymbolFft,
    ifft: Arc<dyn Fft<f64>>,
    ifft_buf: Vec<Complex64>,
    ifft_scratch: Vec<Complex64>,
    /// Window coefficients divided by their sum (so the profile keeps the target amplitude).
    weights: Vec<f64>,
    /// Coherent sum of I_div, or the sum of per-symbol powers.
    accumulator: Vec<Complex64>,
    power: Vec<f64>,
}

impl OfdmRadar {
    /// A receiver for `config`, with its FFTs planned and buffers allocated once.
    ///
    /// # Errors
    ///
    /// [`DspError::Param`] when a field of `config` or its window is out of range; the message names
    /// it.
    pub fn new(config: OfdmRadarConfig) -> Result<Self, DspError> {
        config.validate()?;
        let mut planner = FftPlanner::new();
        let ifft = planner.plan_fft_inverse(config.profile_len());
        let mut weights = config.window.coefficients(config.subcarriers)?;
        let sum: f64 = weights.iter().sum();
        for w in &mut weights {
            *w /= sum;
        }
        let zero = Complex64::default();
        Ok(Self {
            symbol_fft: SymbolFft::new(config.fft_precision, config.fft_len(), &mut planner),
            ifft_buf: vec![zero; config.profile_len()],
            ifft_scratch: vec![zero; ifft.get_inplace_scratch_len()],
            accumulator: vec![zero; config.subcarriers],
            power: vec![0.0; config.profile_len()],
            weights,
            ifft,
            config,
        })
    }

    pub fn config(&self) -> &OfdmRadarConfig {
        &self.config
    }

    /// The range axis of the profiles: bin m at `m * range_bin_m`.
    pub fn range_axis(&self) -> Axis {
        Axis {
            start: 0.0,
            step: self.config.range_bin_m(),
        }
    }

    /// Frames the received signal and fills `idiv` with `I_rx / I_tx`.
    ///
    /// `rx` is the received signal at `N os` samples per useful symbol; symbol `s` starts (with its
    /// CP) at sample `start + s * symbol_len`. `tx_symbols` is the transmitted symbol matrix
    /// (symbol-major, ascending frequency), which also gives the number of symbols.
    ///
    /// # Errors
    ///
    /// [`DspError::Param`] when `tx_symbols` is empty or not a whole number of symbols, `rx` is too
    /// short for them from `start`, or a transmitted subcarrier is zero or not finite.
    pub fn divide(
        &mut self,
        rx: &[Complex64],
        start: usize,
        tx_symbols: &[Complex64],
        idiv: &mut IDiv,
    ) -> Result<(), DspError> {
        let n = self.config.subcarriers;
        if tx_symbols.is_empty() || tx_symbols.len() % n != 0 {
            return Err(DspError::Param(format!(
                "OFDM radar: the transmitted symbol matrix has {} values; allowed: a whole, \
                 non-zero number of symbols of {n} subcarriers",
                tx_symbols.len()
            )));
        }
        let symbols = tx_symbols.len() / n;
        let sym_len = self.config.symbol_len();
        let needed = symbols
            .checked_mul(sym_len)
            .and_then(|n| n.checked_add(start))
            .unwrap_or(usize::MAX);
        if rx.len() < needed {
            return Err(DspError::Param(format!(
                "OFDM radar: {symbols} symbols of {sym_len} samples from start {start} need {needed} \
                 received samples but only {} were given; capture more or lower the start offset",
                rx.len()
            )));
        }
        if let Some(i) = tx_symbols
            .iter()
            .position(|x| !(x.norm_sqr() > 0.0 && x.norm_sqr().is_finite()))
        {
            return Err(DspError::Param(format!(
                "OFDM radar: transmitted symbol {} subcarrier {} is zero or not finite; spectral \
                 division needs every occupied subcarrier modulated",
                i / n,
                i % n
            )));
        }
        idiv.resize(symbols, n);
        let l = self.config.fft_len();
        let cp = self.config.cp_len();
        // Undo the transmitter's 1/sqrt(N) and the FFT's gain of L.
        let scale = (n as f64).sqrt() / l as f64;
        for s in 0..symbols {
            let begin = start + s * sym_len + cp;
            let out = &mut idiv.data[s * n..(s + 1) * n];
            self.symbol_fft.subcarriers(&rx[begin..begin + l], out);
            for (o, x) in out.iter_mut().zip(&tx_symbols[s * n..(s + 1) * n]) {
                *o *= x.conj() * (scale / x.norm_sqr());
            }
        }
        Ok(())
    }

    /// The averaged, windowed, zero-padded range profile of `idiv` into `out`.
    ///
    /// # Errors
    ///
    /// [`DspError::Param`] when `idiv` has no symbols or another number of subcarriers.
    pub fn profile(&mut self, idiv: &IDiv, out: &mut RangeProfile) -> Result<(), DspError> {
        let n = self.config.subcarriers;
        if idiv.subcarriers != n || idiv.symbols == 0 {
            return Err(DspError::Param(format!(
                "OFDM radar: I_div has {} symbols of {} subcarriers; this receiver needs at least one \
                 symbol of {n}",
                idiv.symbols, idiv.subcarriers
            )));
        }
        let k = self.config.profile_len();
        let step = self.config.range_bin_m();
        if out.range_m.len() != k {
            out.range_m.clear();
            out.range_m.extend((0..k).map(|m| m as f64 * step));
        }
        out.amplitude.resize(k, 0.0);
        let inv_s = 1.0 / idiv.symbols as f64;
        match self.config.averaging {
            Averaging::Coherent => {
                self.accumulator.fill(Complex64::default());
                for s in 0..idiv.symbols {
                    for (a, v) in self.accumulator.iter_mut().zip(idiv.symbol(s)) {
                        *a += v;
                    }
                }
                self.ifft_buf.fill(Complex64::default());
                for ((b, a), w) in self
                    .ifft_buf
                    .iter_mut()
                    .zip(&self.accumulator)
                    .zip(&self.weights)
                {
                    *b = a * (w * inv_s);
                }
                self.ifft
                    .process_with_scratch(&mut self.ifft_buf, &mut self.ifft_scratch);
                for (o, b) in out.amplitude.iter_mut().zip(&self.ifft_buf) {
                    *o = b.norm();
                }
            }
            Averaging::Power => {
                self.power.fill(0.0);
                for s in 0..idiv.symbols {
                    self.ifft_buf.fill(Complex64::default());
                    for ((b, v), w) in self
                        .ifft_buf
                        .iter_mut()
                        .zip(idiv.symbol(s))
                        .zip(&self.weights)
                    {
                        *b = v * w;
                    }
                    self.ifft
                        .process_with_scratch(&mut self.ifft_buf, &mut self.ifft_scratch);
                    for (p, b) in self.power.iter_mut().zip(&self.ifft_buf) {
                        *p += b.norm_sqr();
                    }
                }
                for (o, p) in out.amplitude.iter_mut().zip(&self.power) {
                    *o = (p * inv_s).sqrt();
                }
            }
        }
        Ok(())
    }

    /// The coherent (complex) range profile of `idiv` into `out` (resized to K values): the same
    /// windowed, zero-padded IFFT of the symbol-averaged `I_div` as [`OfdmRadar::profile`] with
    /// [`Averaging::Coherent`], before taking the magnitude. The input of `crate::dsp::detect`,
    /// whatever the configured averaging.
    ///
    /// # Errors
    ///
    /// [`DspError::Param`] when `idiv` has no symbols or another number of subcarriers.
    pub fn complex_profile(
        &mut self,
        idiv: &IDiv,
        out: &mut Vec<Complex64>,
    ) -> Result<(), DspError> {
        let n = self.config.subcarriers;
        if idiv.subcarriers != n || idiv.symbols == 0 {
            return Err(DspError::Param(format!(
                "OFDM radar: I_div has {} symbols of {} subcarriers; this receiver needs at least one \
                 symbol of {n}",
                idiv.symbols, idiv.subcarriers
            )));
        }
        self.accumulator.fill(Complex64::default());
        for s in 0..idiv.symbols {
            for (a, v) in self.accumulator.iter_mut().zip(idiv.symbol(s)) {
                *a += v;
            }
        }
        let inv_s = 1.0 / idiv.symbols as f64;
        out.clear();
        out.resize(self.config.profile_len(), Complex64::default());
        for ((b, a), w) in out.iter_mut().zip(&self.accumulator).zip(&self.weights) {
            *b = a * (w * inv_s);
        }
        self.ifft.process_with_scratch(out, &mut self.ifft_scratch);
        Ok(())
    }

    /// The window coefficients across subcarriers divided by their sum (ascending frequency): the
    /// spectral lines of this receiver's point spread (`crate::dsp::SpectralLines::ofdm`).
    pub fn normalised_window(&self) -> &[f64] {
        &self.weights
    }

    /// [`OfdmRadar::divide`] then [`OfdmRadar::profile`].
    ///
    /// # Errors
    ///
    /// Those of [`OfdmRadar::divide`] and [`OfdmRadar::profile`].
    pub fn process(
        &mut self,
        rx: &[Complex64],
        start: usize,
        tx_symbols: &[Complex64],
        idiv: &mut IDiv,
        out: &mut RangeProfile,
    ) -> Result<(), DspError> {
        self.divide(rx, start, tx_symbols, idiv)?;
        self.profile(idiv, out)
    }

    /// Band-limited peak refinement: the range within one bin of `range_guess_m` that maximises the
    /// profile evaluated exactly (a direct sum over subcarriers, no grid), with its amplitude. Uses
    /// the same window and averaging as [`OfdmRadar::profile`]. Exact for a single noise-free target;
    /// with interference from a neighbour it finds the maximum of the true continuous profile.
    ///
    /// # Errors
    ///
    /// [`DspError::Param`] when `idiv` has no symbols or another number of subcarriers.
    pub fn refine_peak(&self, idiv: &IDiv, range_guess_m: f64) -> Result<(f64, f64), DspError> {
        let n = self.config.subcarriers;
        if idiv.subcarriers != n || idiv.symbols == 0 {
            return Err(DspError::Param(format!(
                "OFDM radar: I_div has {} symbols of {} subcarriers; refine_peak needs at least one \
                 symbol of {n}",
                idiv.symbols, idiv.subcarriers
            )));
        }
        let df = self.config.subcarrier_spacing_hz();
        let inv_s = 1.0 / idiv.symbols as f64;
        let value_at = |range: f64| -> f64 {
            // exp(+j 2 pi k df tau), built by recursion over k.
            let tau = 2.0 * range / C0;
            let step = Complex64::from_polar(1.0, 2.0 * std::f64::consts::PI * df * tau);
            let sum_symbol = |row: &[Complex64]| {
                let mut ph = Complex64::new(1.0, 0.0);
                let mut acc = Complex64::default();
                for (v, w) in row.iter().zip(&self.weights) {
                    acc += v * ph * w;
                    ph *= step;
                }
                acc
            };
            match self.config.averaging {
                Averaging::Coherent => {
                    let mut acc = Complex64::default();
                    for s in 0..idiv.symbols {
                        acc += sum_symbol(idiv.symbol(s));
                    }
                    (acc * inv_s).norm()
                }
                Averaging::Power => {
                    let mut p = 0.0;
                    for s in 0..idiv.symbols {
                        p += sum_symbol(idiv.symbol(s)).norm_sqr();
                    }
                    (p * inv_s).sqrt()
                }
            }
        };
        let bin = self.config.range_bin_m();
        let x = golden_section_max(
            value_at,
            range_guess_m - bin,
            range_guess_m + bin,
            bin * 1e-7,
        );
        Ok((x, value_at(x)))
    }
}

/// The per-symbol FFT in the chosen precision, with its plan and buffers.
enum SymbolFft {
    Single {
        fft: Arc<dyn Fft<f32>>,
        buf: Vec<Complex32>,
        scratch: Vec<Complex32>,
    },
    Double {
        fft: Arc<dyn Fft<f64>>,
        buf: Vec<Complex64>,
        scratch: Vec<Complex64>,
    },
}

impl SymbolFft {
    fn new(precision: FftPrecision, len: usize, planner64: &mut FftPlanner<f64>) -> Self {
        match precision {
            FftPrecision::Single => {
                let fft = FftPlanner::<f32>::new().plan_fft_forward(len);
                let scratch = vec![Complex32::default(); fft.get_inplace_scratch_len()];
                Self::Single {
                    buf: vec![Complex32::default(); len],
                    scratch,
                    fft,
                }
            }
            FftPrecision::Double => {
                let fft = planner64.plan_fft_forward(len);
                let scratch = vec![Complex64::default(); fft.get_inplace_scratch_len()];
                Self::Double {
                    buf: vec![Complex64::default(); len],
                    scratch,
                    fft,
                }
            }
        }
    }

    /// FFT of one CP-stripped symbol (`len` samples); writes the `out.len()` = N occupied bins in
    /// ascending frequency: `k < N/2` are the negative frequencies at the top of the FFT,
    /// `k >= N/2` are bins 0, 1, ...
    fn subcarriers(&mut self, symbol: &[Complex64], out: &mut [Complex64]) {
        let n = out.len();
        let half = n / 2;
        match self {
            Self::Single { fft, buf, scratch } => {
                for (b, x) in buf.iter_mut().zip(symbol) {
                    *b = Complex32::new(x.re as f32, x.im as f32);
                }
                fft.process_with_scratch(buf, scratch);
                let l = buf.len();
                let bins = buf[l - half..].iter().chain(&buf[..n - half]);
                for (o, y) in out.iter_mut().zip(bins) {
                    *o = Complex64::new(f64::from(y.re), f64::from(y.im));
                }
            }
            Self::Double { fft, buf, scratch } => {
                buf.copy_from_slice(symbol);
                fft.process_with_scratch(buf, scratch);
                let l = buf.len();
                let bins = buf[l - half..].iter().chain(&buf[..n - half]);
                for (o, y) in out.iter_mut().zip(bins) {
                    *o = *y;
                }
            }
        }
    }
}

/// Maximises a unimodal `f` on `[a, b]` to within `tol`.
pub(crate) fn golden_section_max(f: impl Fn(f64) -> f64, mut a: f64, mut b: f64, tol: f64) -> f64 {
    let g = (5f64.sqrt() - 1.0) / 2.0;
    let mut c = b - g * (b - a);
    let mut d = a + g * (b - a);
    let (mut fc, mut fd) = (f(c), f(d));
    while (b - a).abs() > tol {
        if fc > fd {
            b = d;
            d = c;
            fd = fc;
            c = b - g * (b - a);
            fc = f(c);
        } else {
            a = c;
            c = d;
            fc = fd;
            d = a + g * (b - a);
            fd = f(d);
        }
    }
    0.5 * (a + b)
}
