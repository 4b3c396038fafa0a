//! Command-line arguments shared by several subcommands: the waveform and its parameters, the
//! processing choices, the built-in lab's transports. Each maps onto the library's own types
//! (no clap derive lives outside `cli`).

use crate::exit::bad_input;
use crate::measure::bench::{AwgLink, ScopeLink};
use crate::measure::options::{
    Algorithm, DetectorName, FftPrecisionName, ProcessOptions, WindowName,
};
use crate::simulate::scene::CarrierPhase;
use crate::waveform::spec::{WaveformKind, WaveformSpec};

/// `--waveform`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum WaveformArg {
    /// MSK-LFM: a chirp carrying MSK bits (thesis Table 4.1: 1 GHz, 10 us, 128 bits).
    MskLfm,
    /// OFDM: QPSK subcarriers (thesis Table 4.2: 128 over 1 GHz, 100 symbols).
    Ofdm,
}

impl From<WaveformArg> for WaveformKind {
    fn from(w: WaveformArg) -> Self {
        match w {
            WaveformArg::MskLfm => WaveformKind::MskLfm,
            WaveformArg::Ofdm => WaveformKind::Ofdm,
        }
    }
}

/// `--algorithm`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum AlgorithmArg {
    /// FFT cross-correlation with the transmit signal (any waveform; the MSK-LFM radar).
    Correlation,
    /// OFDM: spectral division and zero-padded IFFT over the subcarriers.
    Fourier,
    /// OFDM: MUSIC pseudo-spectrum (spatial smoothing, forward-backward).
    Music,
    /// OFDM: root-MUSIC, ranges from polynomial roots (no grid).
    RootMusic,
    /// OFDM: ESPRIT, ranges from the shift invariance (no grid).
    Esprit,
}

impl From<AlgorithmArg> for Algorithm {
    fn from(a: AlgorithmArg) -> Self {
        match a {
            AlgorithmArg::Correlation => Algorithm::Correlation,
            AlgorithmArg::Fourier => Algorithm::Fourier,
            AlgorithmArg::Music => Algorithm::Music,
            AlgorithmArg::RootMusic => Algorithm::RootMusic,
            AlgorithmArg::Esprit => Algorithm::Esprit,
        }
    }
}

/// `--window`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum WindowArg {
    /// No window: narrowest main lobe, -13.3 dB side-lobes.
    Rect,
    Hann,
    /// Taylor, 4 nearly equal side-lobes at -35 dB.
    Taylor,
    /// Dolph-Chebyshev, equal side-lobes at -50 dB.
    Chebyshev,
}

impl From<WindowArg> for WindowName {
    fn from(w: WindowArg) -> Self {
        match w {
            WindowArg::Rect => WindowName::Rect,
            WindowArg::Hann => WindowName::Hann,
            WindowArg::Taylor => WindowName::Taylor,
            WindowArg::Chebyshev => WindowName::Chebyshev,
        }
    }
}

/// `--fft-precision`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum FftPrecisionArg {
    /// Single precision (default): rounding ~130 dB under the signal, about twice as fast.
    Single,
    /// Double precision, for noise-free studies that look below -130 dB.
    Double,
}

impl From<FftPrecisionArg> for FftPrecisionName {
    fn from(p: FftPrecisionArg) -> Self {
        match p {
            FftPrecisionArg::Single => FftPrecisionName::Single,
            FftPrecisionArg::Double => FftPrecisionName::Double,
        }
    }
}

/// `--detector`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum DetectorArg {
    /// CLEAN with the waveform's point spread: subtract each target, search again (default).
    Clean,
    /// CLEAN with a local ordered-statistic noise estimate.
    CleanOs,
    /// Ordered-statistic CFAR, side-lobes masked by the point spread's envelope.
    OsCfar,
    /// Cell-averaging CFAR.
    CaCfar,
    /// Greatest-of CFAR.
    GoCfar,
    /// Smallest-of CFAR.
    SoCfar,
}

impl From<DetectorArg> for DetectorName {
    fn from(d: DetectorArg) -> Self {
        match d {
            DetectorArg::Clean => DetectorName::Clean,
            DetectorArg::CleanOs => DetectorName::CleanOs,
            DetectorArg::OsCfar => DetectorName::OsCfar,
            DetectorArg::CaCfar => DetectorName::CaCfar,
            DetectorArg::GoCfar => DetectorName::GoCfar,
            DetectorArg::SoCfar => DetectorName::SoCfar,
        }
    }
}

/// `--carrier-phase`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum CarrierPhaseArg {
    /// The bench's 80 GHz carrier: what a real measurement sees.
    Physical,
    /// f_c = 0: pure baseband, no carrier phase.
    Centred,
    /// f_c = B/2: the thesis' own model (its chirp sweeps 0..B).
    Thesis,
}

impl From<CarrierPhaseArg> for CarrierPhase {
    fn from(c: CarrierPhaseArg) -> Self {
        match c {
            CarrierPhaseArg::Physical => CarrierPhase::Physical,
            CarrierPhaseArg::Centred => CarrierPhase::Centred,
            CarrierPhaseArg::Thesis => CarrierPhase::Thesis,
        }
    }
}

/// `--awg-transport` of the built-in lab.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum AwgTransportArg {
    Raw,
    Hislip,
    Vxi11,
}

impl From<AwgTransportArg> for AwgLink {
    fn from(t: AwgTransportArg) -> Self {
        match t {
            AwgTransportArg::Raw => AwgLink::Raw,
            AwgTransportArg::Hislip => AwgLink::Hislip,
            AwgTransportArg::Vxi11 => AwgLink::Vxi11,
        }
    }
}

/// `--scope-transport` of the built-in lab.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum ScopeTransportArg {
    Vicp,
    Vxi11,
}

impl From<ScopeTransportArg> for ScopeLink {
    fn from(t: ScopeTransportArg) -> Self {
        match t {
            ScopeTransportArg::Vicp => ScopeLink::Vicp,
            ScopeTransportArg::Vxi11 => ScopeLink::Vxi11,
        }
    }
}

/// The waveform's parameters; unset ones keep the thesis' values.
#[derive(Debug, Clone, Default, clap::Args)]
pub struct WaveformArgs {
    /// Bandwidth in Hz (both waveforms; OFDM keeps its sample rate, so the rate must be a whole
    /// multiple of it). Default 1e9.
    #[arg(long, value_name = "HZ", allow_hyphen_values = true)]
    pub bandwidth: Option<f64>,
    /// MSK-LFM sample rate in Sa/s (the AWG rate). Default 16e9.
    #[arg(long, value_name = "HZ", allow_hyphen_values = true)]
    pub sample_rate: Option<f64>,
    /// MSK-LFM pulse length in microseconds. Default 10.
    #[arg(long, value_name = "US", allow_hyphen_values = true)]
    pub pulse_us: Option<f64>,
    /// MSK-LFM bits per pulse (even). Default 128.
    #[arg(long, value_name = "N")]
    pub bits_per_pulse: Option<usize>,
    /// OFDM subcarriers (even). Default 128.
    #[arg(long, value_name = "N")]
    pub subcarriers: Option<usize>,
    /// OFDM oversampling factor (sample rate = bandwidth x factor). Default 16.
    #[arg(long, value_name = "N")]
    pub oversampling: Option<usize>,
    /// OFDM cyclic prefix as a fraction of the useful symbol. Default 0.25.
    #[arg(long, value_name = "F", allow_hyphen_values = true)]
    pub cp_fraction: Option<f64>,
    /// OFDM symbols per frame (a known preamble symbol included). Default 100.
    #[arg(long, value_name = "N")]
    pub symbols: Option<usize>,
}

/// Largest samples per repetition a command builds (AWG memory of the M8195A is 16 G samples,
/// but one repetition beyond this does not fit the scope or the host usefully).
const MAX_SAMPLES_PER_REPETITION: f64 = 64e6;

impl WaveformArgs {
    /// The spec of `kind` with these parameters; an option that does not apply to `kind` is
    /// refused, so nothing the user typed is silently ignored.
    pub fn spec(&self, kind: WaveformKind) -> anyhow::Result<WaveformSpec> {
        let only = |given: bool, option: &str, applies: &str| -> anyhow::Result<()> {
            if given {
                return Err(bad_input(format!(
                    "--{option} applies to {applies} only; this is --waveform {}",
                    kind.name()
                )));
            }
            Ok(())
        };
        let positive = |v: Option<f64>, option: &str, unit: &str| -> anyhow::Result<()> {
            if let Some(x) = v {
                if !(x.is_finite() && x > 0.0) {
                    return Err(bad_input(format!(
                        "--{option} {x}: must be a positive number of {unit}"
                    )));
                }
            }
            Ok(())
        };
        positive(self.bandwidth, "bandwidth", "Hz")?;
        positive(self.sample_rate, "sample-rate", "Sa/s")?;
        positive(self.pulse_us, "pulse-us", "microseconds")?;
        let mut spec = kind.thesis_default();
        match &mut spec {
            WaveformSpec::MskLfm {
                sample_rate_hz,
                bandwidth_hz,
                pulse_s,
                bits_per_pulse,
            } => {
                only(self.subcarriers.is_some(), "subcarriers", "OFDM")?;
                only(self.oversampling.is_some(), "oversampling", "OFDM")?;
                only(self.cp_fraction.is_some(), "cp-fraction", "OFDM")?;
                only(self.symbols.is_some(), "symbols", "OFDM")?;
                if let Some(v) = self.sample_rate {
                    *sample_rate_hz = v;
                }
                if let Some(v) = self.bandwidth {
                    *bandwidth_hz = v;
                }
                if let Some(v) = self.pulse_us {
                    *pulse_s = v * 1e-6;
                }
                if let Some(v) = self.bits_per_pulse {
                    *bits_per_pulse = v;
                }
                let samples = *pulse_s * *sample_rate_hz;
                if samples > MAX_SAMPLES_PER_REPETITION {
                    return Err(bad_input(format!(
                        "--pulse-us / --sample-rate: one pulse of {samples:.3e} samples; allowed \
                         at most {MAX_SAMPLES_PER_REPETITION:.0e} samples per repetition"
                    )));
                }
            }
            WaveformSpec::Ofdm {
                bandwidth_hz,
                subcarriers,
                oversampling,
                cp_fraction,
                symbols,
                ..
            } => {
                only(self.sample_rate.is_some(), "sample-rate", "MSK-LFM")?;
                only(self.pulse_us.is_some(), "pulse-us", "MSK-LFM")?;
                only(self.bits_per_pulse.is_some(), "bits-per-pulse", "MSK-LFM")?;
                if let Some(v) = self.subcarriers {
                    *subcarriers = v;
                }
                if let Some(v) = self.cp_fraction {
                    *cp_fraction = v;
                }
                if let Some(v) = self.symbols {
                    *symbols = v;
                }
                match (self.bandwidth, self.oversampling) {
                    (Some(b), Some(os)) => {
                        *bandwidth_hz = b;
                        *oversampling = os;
                    }
                    (Some(b), None) => {
                        let rate = *bandwidth_hz * *oversampling as f64;
                        let ratio = rate / b;
                        if ratio < 1.0 || (ratio - ratio.round()).abs() > 1e-9 * ratio {
                            return Err(bad_input(format!(
                                "--bandwidth {b}: OFDM keeps its sample rate of {rate} Sa/s, \
                                 which must be a whole multiple of the bandwidth (e.g. 1e9, 2e9, \
                                 4e9); or give --oversampling too"
                            )));
                        }
                        *bandwidth_hz = b;
                        *oversampling = ratio.round() as usize;
                    }
                    (None, Some(os)) => *oversampling = os,
                    (None, None) => {}
                }
                let samples = (*subcarriers as f64)
                    * (*oversampling as f64)
                    * (1.0 + cp_fraction.abs())
                    * (*symbols as f64);
                if samples > MAX_SAMPLES_PER_REPETITION {
                    return Err(bad_input(format!(
                        "--subcarriers x --oversampling x --symbols: a frame of {samples:.3e} \
                         samples; allowed at most {MAX_SAMPLES_PER_REPETITION:.0e} samples per \
                         repetition"
                    )));
                }
            }
        }
        Ok(spec)
    }
}

/// Range processing choices shared by `capture`, `simulate run` and `process`.
#[derive(Debug, Clone, clap::Args)]
pub struct ProcessingArgs {
    /// Range processing: correlation (default for MSK-LFM), fourier (default for OFDM), music,
    /// root-music or esprit (OFDM).
    #[arg(long, value_enum)]
    pub algorithm: Option<AlgorithmArg>,
    /// MUSIC sub-vector (covariance) length M.
    #[arg(long = "m", value_name = "M", default_value_t = 64)]
    pub music_m: usize,
    /// Number of targets for MUSIC/root-MUSIC/ESPRIT (default: estimated with MDL).
    #[arg(long = "p", value_name = "P")]
    pub music_p: Option<usize>,
    /// Forward smoothing only (no forward-backward averaging) for MUSIC.
    #[arg(long)]
    pub forward_only: bool,
    /// OFDM Fourier zero-padding factor: IFFT length = K x subcarriers.
    #[arg(long, value_name = "K", default_value_t = 10)]
    pub zero_pad: usize,
    /// Window on the range processing (OFDM: across the subcarriers; correlation: on the matched
    /// filter's spectrum).
    #[arg(long, value_enum, value_name = "NAME", default_value = "rect")]
    pub window: WindowArg,
    /// Precision of the OFDM receiver's per-symbol FFT (the rest is double precision).
    #[arg(long, value_enum, value_name = "P", default_value = "single")]
    pub fft_precision: FftPrecisionArg,
    /// Report the on-grid peak (no sub-sample interpolation).
    #[arg(long)]
    pub no_interpolation: bool,
    /// Detector of the correlation and Fourier profiles (docs/detection.md compares them).
    #[arg(long, value_enum, value_name = "NAME", default_value = "clean")]
    pub detector: DetectorArg,
    /// Probability of false alarm of the detector, per profile cell.
    #[arg(
        long,
        value_name = "P",
        default_value_t = 1e-6,
        allow_hyphen_values = true
    )]
    pub pfa: f64,
    /// Targets closer than this are reported as one, metres (default: 0.75 resolution cells).
    #[arg(long, value_name = "METRES", allow_hyphen_values = true)]
    pub min_separation: Option<f64>,
}

impl ProcessingArgs {
    /// The library options for `waveform` (ranges and calibration left at their defaults).
    pub fn options(&self, waveform: WaveformKind) -> ProcessOptions {
        ProcessOptions {
            algorithm: self
                .algorithm
                .map(Algorithm::from)
                .unwrap_or(Algorithm::default_for(waveform)),
            music_m: self.music_m,
            music_p: self.music_p,
            forward_backward: !self.forward_only,
            zero_pad: self.zero_pad,
            window: self.window.into(),
            fft_precision: self.fft_precision.into(),
            interpolate: !self.no_interpolation,
            detector: self.detector.into(),
            pfa: self.pfa,
            min_separation_m: self.min_separation,
            ..ProcessOptions::default()
        }
    }
}
