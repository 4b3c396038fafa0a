//! Command-line arguments shared by several subcommands: the waveform and its parameters, the
//! processing choices, the built-in lab's transports. Each maps onto the library's own types
//! (no clap derive lives outside `cli`).

use crate::exit::bad_input;
use crate::measure::bench::{AwgLink, ScopeLink};
use crate::measure::options::{
    Algorithm, DetectorName, FftPrecisionName, ProcessOptions, WindowName,
};
use crate::simulate::scene::CarrierPhase;
use crate::waveform::overrides::{OverrideError, WaveformOverrides};
use crate::waveform::spec::{SweepBand, WaveformKind, WaveformSpec};

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

/// `--correction`: which of the chain's measured errors are corrected.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum CorrectionArg {
    /// Nothing corrected.
    None,
    /// On receive: DC, I/Q imbalance, and the chain's response divided out.
    Rx,
    /// On transmit: the AWG's codes pre-distorted by the inverse of the chain's response.
    Tx,
    /// Both: the codes pre-distorted, and the receiver's own DC and I/Q imbalance corrected.
    Both,
}

impl CorrectionArg {
    pub(crate) fn name(self) -> &'static str {
        match self {
            CorrectionArg::None => "none",
            CorrectionArg::Rx => "rx",
            CorrectionArg::Tx => "tx",
            CorrectionArg::Both => "both",
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

/// `--scope-model` of the built-in lab: which scope it serves.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum ScopeModelArg {
    /// Teledyne LeCroy LabMaster 10 Zi-A (VICP or VXI-11), saves `.trc` files beside the SigMF.
    Lecroy,
    /// Keysight Infiniium UXR0334A (HiSLIP, or VXI-11 with --scope-transport vxi11), saves the
    /// SigMF recording only.
    KeysightUxr,
}

impl From<ScopeModelArg> for crate::measure::bench::ScopeModel {
    fn from(m: ScopeModelArg) -> Self {
        match m {
            ScopeModelArg::Lecroy => Self::Lecroy,
            ScopeModelArg::KeysightUxr => Self::KeysightUxr,
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
    /// MSK-LFM: where the chirp sweeps: centred (-B/2 .. B/2, default), upper (0 .. B, the
    /// thesis' equation 2.4) or lower (-B .. 0).
    #[arg(long, value_name = "BAND", value_parser = str::parse::<SweepBand>)]
    pub band: Option<SweepBand>,
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

impl WaveformArgs {
    /// The spec of `kind` with these parameters; an option that does not apply to `kind` is
    /// refused, so nothing the user typed is silently ignored.
    pub fn spec(&self, kind: WaveformKind) -> anyhow::Result<WaveformSpec> {
        let overrides = WaveformOverrides {
            bandwidth_hz: self.bandwidth,
            sample_rate_hz: self.sample_rate,
            pulse_s: self.pulse_us.map(|us| us * 1e-6),
            bits_per_pulse: self.bits_per_pulse,
            band: self.band,
            subcarriers: self.subcarriers,
            oversampling: self.oversampling,
            cp_fraction: self.cp_fraction,
            symbols: self.symbols,
            preamble_symbols: None,
        };
        overrides.apply(kind).map_err(|e| {
            let option = match e.field() {
                "bandwidth_hz" => "--bandwidth",
                "sample_rate_hz" => "--sample-rate",
                "pulse_s" => "--pulse-us",
                "bits_per_pulse" => "--bits-per-pulse",
                "band" => "--band",
                "subcarriers" => "--subcarriers",
                "oversampling" => "--oversampling",
                "cp_fraction" => "--cp-fraction",
                _ => "--symbols",
            };
            let option = match &e {
                OverrideError::TooLong { .. } if kind == WaveformKind::MskLfm => {
                    "--pulse-us / --sample-rate"
                }
                OverrideError::TooLong { .. } => "--subcarriers x --oversampling x --symbols",
                _ => option,
            };
            bad_input(format!("{option}: {e}"))
        })
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
    /// Around a target whose main lobe does not fit the ideal point spread to 50 dB, a weaker
    /// echo within 1.6 m is a target only within this many dB of it (the chain's own echoes are
    /// part of its response; docs/detection.md). Lower it for a bench known to be cleaner;
    /// -200 turns it off.
    #[arg(
        long,
        value_name = "DB",
        default_value_t = -17.0,
        allow_hyphen_values = true
    )]
    pub chain_floor_db: f64,
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
            chain_floor_db: self.chain_floor_db,
            ..ProcessOptions::default()
        }
    }
}
