//! Command-line arguments shared by several subcommands: the waveform and its parameters, the
//! processing choices, the built-in lab's transports. The library's named enums (waveform,
//! algorithm, window, FFT precision, detector, carrier phase, correction, the built-in lab's
//! transports and scope) are parsed as they are, by their own
//! `FromStr` over the values they list (`Listed`, `listed`); no clap derive lives outside `cli`.

use crate::exit::bad_input;
use crate::measure::bench::{AwgLink, ScopeLink, ScopeModel};
use crate::measure::family::overrides::{OverrideError, WaveformOverrides};
use crate::measure::options::{
    Algorithm, DetectorName, FftPrecisionName, ProcessOptions, WindowName,
};
use crate::measure::response::CorrectionMode;
use crate::simulate::scene::CarrierPhase;
use crate::waveform::spec::{SweepBand, WaveformKind, WaveformSpec};

/// A library enum the command line takes by name: its values (with a line of help each) and its
/// `FromStr`, so clap parses the library's own type (no mirror enum here).
pub(crate) trait Listed: std::str::FromStr + Copy + Send + Sync + 'static {
    fn all() -> &'static [Self];
    fn name(self) -> &'static str;
    fn about(self) -> &'static str;
}

impl Listed for WaveformKind {
    fn all() -> &'static [Self] {
        &WaveformKind::ALL
    }
    fn name(self) -> &'static str {
        WaveformKind::name(self)
    }
    fn about(self) -> &'static str {
        WaveformKind::about(self)
    }
}

impl Listed for Algorithm {
    fn all() -> &'static [Self] {
        &Algorithm::ALL
    }
    fn name(self) -> &'static str {
        Algorithm::name(self)
    }
    fn about(self) -> &'static str {
        Algorithm::about(self)
    }
}

impl Listed for WindowName {
    fn all() -> &'static [Self] {
        &WindowName::ALL
    }
    fn name(self) -> &'static str {
        WindowName::name(self)
    }
    fn about(self) -> &'static str {
        WindowName::about(self)
    }
}

impl Listed for FftPrecisionName {
    fn all() -> &'static [Self] {
        &FftPrecisionName::ALL
    }
    fn name(self) -> &'static str {
        FftPrecisionName::name(self)
    }
    fn about(self) -> &'static str {
        FftPrecisionName::about(self)
    }
}

impl Listed for DetectorName {
    fn all() -> &'static [Self] {
        &DetectorName::ALL
    }
    fn name(self) -> &'static str {
        DetectorName::name(self)
    }
    fn about(self) -> &'static str {
        DetectorName::about(self)
    }
}

impl Listed for CarrierPhase {
    fn all() -> &'static [Self] {
        &CarrierPhase::ALL
    }
    fn name(self) -> &'static str {
        CarrierPhase::name(self)
    }
    fn about(self) -> &'static str {
        CarrierPhase::about(self)
    }
}

impl Listed for AwgLink {
    fn all() -> &'static [Self] {
        &AwgLink::ALL
    }
    fn name(self) -> &'static str {
        AwgLink::name(self)
    }
    fn about(self) -> &'static str {
        AwgLink::about(self)
    }
}

impl Listed for ScopeLink {
    fn all() -> &'static [Self] {
        &ScopeLink::ALL
    }
    fn name(self) -> &'static str {
        ScopeLink::name(self)
    }
    fn about(self) -> &'static str {
        ScopeLink::about(self)
    }
}

impl Listed for ScopeModel {
    fn all() -> &'static [Self] {
        &ScopeModel::ALL
    }
    fn name(self) -> &'static str {
        ScopeModel::name(self)
    }
    fn about(self) -> &'static str {
        ScopeModel::about(self)
    }
}

impl Listed for CorrectionMode {
    fn all() -> &'static [Self] {
        &CorrectionMode::ALL
    }
    fn name(self) -> &'static str {
        CorrectionMode::name(self)
    }
    fn about(self) -> &'static str {
        CorrectionMode::about(self)
    }
}

/// clap's parser of a [`Listed`] enum: `--help` lists its values, a wrong one is refused naming
/// the option and every allowed value (as for a clap `ValueEnum`).
pub(crate) fn listed<T: Listed>() -> impl clap::builder::TypedValueParser<Value = T> {
    use clap::builder::{PossibleValue, PossibleValuesParser, TypedValueParser};
    PossibleValuesParser::new(T::all().iter().map(|v| match v.about() {
        "" => PossibleValue::new(v.name()),
        about => PossibleValue::new(v.name()).help(about),
    }))
    .map(|s| match s.parse::<T>() {
        Ok(v) => v,
        Err(_) => unreachable!("clap passes only the listed values"),
    })
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
    #[arg(long, value_parser = listed::<Algorithm>())]
    pub algorithm: Option<Algorithm>,
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
    #[arg(long, value_parser = listed::<WindowName>(), value_name = "NAME", default_value = "rect")]
    pub window: WindowName,
    /// Precision of the OFDM receiver's per-symbol FFT (the rest is double precision).
    #[arg(long, value_parser = listed::<FftPrecisionName>(), value_name = "P", default_value = "single")]
    pub fft_precision: FftPrecisionName,
    /// Report the on-grid peak (no sub-sample interpolation).
    #[arg(long)]
    pub no_interpolation: bool,
    /// Detector of the correlation and Fourier profiles (docs/detection.md compares them).
    #[arg(long, value_parser = listed::<DetectorName>(), value_name = "NAME", default_value = "clean")]
    pub detector: DetectorName,
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
            algorithm: self.algorithm.unwrap_or(Algorithm::default_for(waveform)),
            music_m: self.music_m,
            music_p: self.music_p,
            forward_backward: !self.forward_only,
            zero_pad: self.zero_pad,
            window: self.window,
            fft_precision: self.fft_precision,
            interpolate: !self.no_interpolation,
            detector: self.detector,
            pfa: self.pfa,
            min_separation_m: self.min_separation,
            chain_floor_db: self.chain_floor_db,
            ..ProcessOptions::default()
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Every value of `T` parses from its name (by clap too) and prints as it; clap refuses
    /// another one naming the option and every allowed value.
    fn round_trip<T: Listed + std::fmt::Display + PartialEq + std::fmt::Debug>() {
        let cmd = || {
            clap::Command::new("radbench").arg(
                clap::Arg::new("opt")
                    .long("opt")
                    .value_parser(listed::<T>()),
            )
        };
        for &v in T::all() {
            assert_eq!(v.name().parse::<T>().ok(), Some(v));
            assert_eq!(v.to_string(), v.name());
            let m = cmd()
                .try_get_matches_from(["radbench", "--opt", v.name()])
                .unwrap();
            assert_eq!(m.get_one::<T>("opt"), Some(&v));
        }
        let err = cmd()
            .try_get_matches_from(["radbench", "--opt", "nonsense"])
            .unwrap_err()
            .to_string();
        assert!(err.contains("--opt"), "{err}");
        for &v in T::all() {
            assert!(err.contains(v.name()), "{err}");
        }
    }

    #[test]
    fn the_library_enums_parse_by_their_own_names() {
        round_trip::<WaveformKind>();
        round_trip::<Algorithm>();
        round_trip::<WindowName>();
        round_trip::<FftPrecisionName>();
        round_trip::<DetectorName>();
        round_trip::<CarrierPhase>();
        round_trip::<CorrectionMode>();
        let err = "pmcw".parse::<WaveformKind>().unwrap_err();
        assert!(err.contains("msk-lfm, ofdm"), "{err}");
    }
}
