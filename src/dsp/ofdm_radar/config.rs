//! The receiver's parameters, checked once in `OfdmRadarConfig::validate` (the numerology it
//! shares with the waveform's generator in `numerology.rs`).

use super::numerology::{Fault, Numerology};
use crate::dsp::Window;
use crate::dsp::{DspError, C0};

/// How the per-symbol profiles are combined.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Averaging {
    /// Average `I_div` over symbols, then one IFFT (complex, coherent): best SNR for static targets.
    #[default]
    Coherent,
    /// One IFFT per symbol, average `|p|^2`, report the RMS amplitude: robust to Doppler.
    Power,
}

/// Arithmetic of the per-symbol receive FFT, the receiver's dominant cost (one `N os`-point FFT
/// per symbol). Everything after it (division, averaging, range IFFT, MUSIC) is double precision.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum FftPrecision {
    /// Single precision, about twice as fast. Its rounding sits about 130 dB under the signal
    /// (relative error ~1e-7 per bin), far below the quantisation noise of the scope's 8-bit
    /// (about 50 dB) or 12-bit ADC, so profiles and ranges do not change measurably
    /// (tests/dsp/dsp_ofdm_radar.rs compares both).
    #[default]
    Single,
    /// Double precision, for synthetic noise-free studies that look below -130 dB.
    Double,
}

/// Parameters of the OFDM radar receiver.
#[derive(Debug, Clone, PartialEq)]
pub struct OfdmRadarConfig {
    /// Occupied subcarriers N (128).
    pub subcarriers: usize,
    /// Oversampling factor: the useful symbol is `N * oversampling` samples (16).
    pub oversampling: usize,
    /// Cyclic prefix as a fraction of the useful symbol (0.25); `cp_fraction * N * os` must be whole.
    pub cp_fraction: f64,
    /// Occupied bandwidth B = N df, Hz (1e9).
    pub bandwidth_hz: f64,
    /// Zero-padding factor of the range IFFT: K = zero_pad * N points (10).
    pub zero_pad: usize,
    /// Window across subcarriers (rectangular).
    pub window: Window,
    /// Averaging over symbols (coherent).
    pub averaging: Averaging,
    /// Precision of the per-symbol FFT (single).
    pub fft_precision: FftPrecision,
}

impl Default for OfdmRadarConfig {
    fn default() -> Self {
        Self {
            subcarriers: 128,
            oversampling: 16,
            cp_fraction: 0.25,
            bandwidth_hz: 1e9,
            zero_pad: 10,
            window: Window::Rectangular,
            averaging: Averaging::Coherent,
            fft_precision: FftPrecision::Single,
        }
    }
}

impl OfdmRadarConfig {
    /// Samples of the useful part of a symbol (N os).
    pub fn fft_len(&self) -> usize {
        self.subcarriers * self.oversampling
    }

    /// Samples of the cyclic prefix.
    pub fn cp_len(&self) -> usize {
        (self.cp_fraction * self.fft_len() as f64).round() as usize
    }

    /// Samples per symbol, CP included.
    pub fn symbol_len(&self) -> usize {
        self.fft_len() + self.cp_len()
    }

    /// Subcarrier spacing df = B / N, Hz.
    pub(crate) fn subcarrier_spacing_hz(&self) -> f64 {
        self.bandwidth_hz / self.subcarriers as f64
    }

    /// Sample rate of the received signal, B os.
    pub fn sample_rate_hz(&self) -> f64 {
        self.bandwidth_hz * self.oversampling as f64
    }

    /// Duration of one symbol with its CP, s (the slow-time sample period of the Doppler FFT).
    pub fn symbol_period_s(&self) -> f64 {
        self.symbol_len() as f64 / self.sample_rate_hz()
    }

    /// Points of the range IFFT, K = zero_pad N.
    pub fn profile_len(&self) -> usize {
        self.zero_pad * self.subcarriers
    }

    /// Range of profile bin 1, m: C0 / (2 K df).
    pub fn range_bin_m(&self) -> f64 {
        C0 / (2.0 * self.profile_len() as f64 * self.subcarrier_spacing_hz())
    }

    /// Checks every field; the message names the field and what is allowed. The numerology
    /// (subcarriers, bandwidth, oversampling, cyclic prefix) is the one check the waveform's
    /// generator also uses ([`Numerology::check`]); zero padding and window are the receiver's own.
    pub(crate) fn validate(&self) -> Result<(), DspError> {
        let param = |m: String| Err(DspError::Param(m));
        let numerology = Numerology {
            subcarriers: self.subcarriers,
            oversampling: self.oversampling,
            cp_fraction: self.cp_fraction,
            bandwidth_hz: self.bandwidth_hz,
        };
        match numerology.check() {
            Ok(_) => {}
            Err(Fault::Subcarriers) => {
                return param(format!(
                    "OFDM radar: subcarriers = {}; allowed: at least 2 (128 in the thesis)",
                    self.subcarriers
                ))
            }
            Err(Fault::Bandwidth) => {
                return param(format!(
                    "OFDM radar: bandwidth_hz = {}; allowed: a positive frequency (1e9 in the \
                     thesis)",
                    self.bandwidth_hz
                ))
            }
            Err(Fault::Oversampling) => {
                return param(
                    "OFDM radar: oversampling = 0; allowed: 1 or more (16 in the thesis)".into(),
                )
            }
            Err(Fault::SymbolTooLong) => {
                return param(format!(
                    "OFDM radar: subcarriers * oversampling = {} * {}; allowed: at most 2^28 \
                     samples per symbol",
                    self.subcarriers, self.oversampling
                ))
            }
            Err(Fault::CpFraction) => {
                return param(format!(
                    "OFDM radar: cp_fraction = {}; allowed: 0 <= cp_fraction < 1 (0.25 in the \
                     thesis)",
                    self.cp_fraction
                ))
            }
            Err(Fault::CpNotWhole { samples, fft_len }) => {
                return param(format!(
                    "OFDM radar: cp_fraction {} of {fft_len} samples is {samples} samples; \
                     allowed: a fraction giving a whole number of samples",
                    self.cp_fraction
                ))
            }
        }
        if self.zero_pad < 1 {
            return param(
                "OFDM radar: zero_pad = 0; allowed: 1 (none) or more (10 in the thesis)".into(),
            );
        }
        self.window.validate()
    }
}
