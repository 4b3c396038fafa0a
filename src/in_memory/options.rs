//! The options of `radbench process` and of the waveform, as clap parses them: the command
//! line flattens them into its commands, [`super::ProcessRequest`] and [`super::transmission`]
//! parse the same definitions for the Python package (one definition of names, defaults, checks
//! and messages).
//!
//! Doc comments on the clap structs are `--help` text, not rustdoc: brackets and angle brackets
//! in them are literal.
#![allow(rustdoc::broken_intra_doc_links, rustdoc::invalid_html_tags)]

use crate::exit::bad_input;
use crate::measure::family::overrides::{OverrideError, WaveformOverrides};
use crate::measure::CorrectionMode;
use crate::measure::Ranging;
use crate::measure::WaveformChoice;
use crate::measure::{Algorithm, DetectorName, FftPrecisionName, ProcessOverrides, WindowName};
use crate::measure::{AwgLink, ScopeLink, ScopeModel};
use crate::simulate::CarrierPhase;
use crate::waveform::{SweepBand, WaveformKind, WaveformSpec};
use std::path::{Path, PathBuf};

/// A library enum the command line takes by name: its values (with a line of help each) and its
/// `FromStr`, so clap parses the library's own type (no mirror enum here).
pub trait Listed: std::str::FromStr + Copy + Send + Sync + 'static {
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

impl Listed for Ranging {
    fn all() -> &'static [Self] {
        &Ranging::ALL
    }
    fn name(self) -> &'static str {
        Ranging::name(self)
    }
    fn about(self) -> &'static str {
        Ranging::about(self)
    }
}

/// clap's parser of a [`Listed`] enum: `--help` lists its values, a wrong one is refused naming
/// the option and every allowed value (as for a clap `ValueEnum`).
pub fn listed<T: Listed>() -> impl clap::builder::TypedValueParser<Value = T> {
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

/// The transmitted bits of `radbench capture`: a payload text, or PRBS bits of a seed.
#[derive(Debug, Clone, clap::Args)]
pub struct PayloadArgs {
    /// Text to send in the waveform (default: PRBS bits).
    #[arg(long, value_name = "TEXT")]
    pub payload: Option<String>,
    /// Seed of the PRBS bits when no payload is given.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
}

/// The processing options of `radbench process` (what it writes and how it runs are the
/// command's own: `INPUT`, `--out`, `--json`, `--jobs`, `--link-png`).
#[derive(Debug, clap::Args)]
pub struct ProcessArgs {
    /// The waveform of captures radbench did not make (overrides what a radbench capture recorded).
    #[arg(long, value_parser = listed::<WaveformKind>())]
    pub waveform: Option<WaveformKind>,
    #[command(flatten)]
    pub waveform_args: WaveformArgs,
    /// Seed of the transmitted PRBS bits (captures radbench did not make).
    #[arg(long)]
    pub seed: Option<u64>,
    /// The transmitted payload text (captures radbench did not make).
    #[arg(long, value_name = "TEXT")]
    pub payload: Option<String>,
    /// Time from the trigger to the first sample, seconds (default: what the file says, else 0).
    #[arg(long, value_name = "S", allow_hyphen_values = true)]
    pub trigger_offset: Option<f64>,
    /// Subtract this capture (.sigmf-meta) instead of the one the capture recorded.
    #[arg(long, value_name = "FILE", conflicts_with = "no_background")]
    pub background: Option<PathBuf>,
    /// Do not subtract the background the capture recorded.
    #[arg(long)]
    pub no_background: bool,
    #[arg(long, value_parser = listed::<Algorithm>())]
    pub algorithm: Option<Algorithm>,
    /// MUSIC sub-vector (covariance) length M.
    #[arg(long = "m", value_name = "M")]
    pub music_m: Option<usize>,
    /// Number of targets for MUSIC/root-MUSIC/ESPRIT.
    #[arg(long = "p", value_name = "P")]
    pub music_p: Option<usize>,
    /// Forward smoothing only for MUSIC.
    #[arg(long)]
    pub forward_only: bool,
    #[arg(long, value_name = "K")]
    pub zero_pad: Option<usize>,
    #[arg(long, value_parser = listed::<WindowName>(), value_name = "NAME")]
    pub window: Option<WindowName>,
    #[arg(long, value_parser = listed::<FftPrecisionName>(), value_name = "P")]
    pub fft_precision: Option<FftPrecisionName>,
    /// Report the on-grid peak (no sub-sample interpolation).
    #[arg(long)]
    pub no_interpolation: bool,
    #[arg(long, value_parser = listed::<DetectorName>(), value_name = "NAME")]
    pub detector: Option<DetectorName>,
    #[arg(long, value_name = "P", allow_hyphen_values = true)]
    pub pfa: Option<f64>,
    #[arg(long, value_name = "METRES", allow_hyphen_values = true)]
    pub min_separation: Option<f64>,
    /// The detector's chain floor, dB (see `capture --help`).
    #[arg(long, value_name = "DB", allow_hyphen_values = true)]
    pub chain_floor_db: Option<f64>,
    /// How each target's range is measured: envelope, or phase (see `capture --help`).
    #[arg(long, value_parser = listed::<Ranging>(), value_name = "MODE")]
    pub ranging: Option<Ranging>,
    #[arg(long, value_name = "METRES", allow_hyphen_values = true)]
    pub min_range: Option<f64>,
    #[arg(long, value_name = "METRES", allow_hyphen_values = true)]
    pub max_range: Option<f64>,
    /// The bench's fixed delay, seconds (default: what the capture was processed with).
    #[arg(long, value_name = "S", allow_hyphen_values = true)]
    pub system_delay: Option<f64>,
    /// Receive correction: none, or rx (DC, I/Q imbalance and the chain's response, from a
    /// calibration). Default: what the capture was processed with; rx with --calibration.
    #[arg(long, value_parser = listed::<CorrectionMode>())]
    pub correction: Option<CorrectionMode>,
    /// A response calibration (`radbench calibrate response` wrote it) to correct with, for
    /// captures made without one; with --reference-range, a capture of one reference pillar
    /// from which the response is measured (written to OUT/reference-response.toml).
    #[arg(long, value_name = "FILE")]
    pub calibration: Option<PathBuf>,
    /// The reference pillar's true range in the --calibration capture, metres.
    #[arg(long, value_name = "METRES", allow_hyphen_values = true)]
    pub reference_range: Option<f64>,
}

impl ProcessArgs {
    /// The waveform and the processing options asked for (`out`: where a response measured with
    /// `--reference-range` is stored).
    pub fn settings(&self, out: &Path) -> anyhow::Result<(WaveformChoice, ProcessOverrides)> {
        let waveform = self.waveform()?;
        let mut overrides = self.overrides();
        overrides.correction = self.correction(out)?;
        overrides.require_correction =
            self.correction == Some(CorrectionMode::Rx) && self.calibration.is_none();
        Ok((waveform, overrides))
    }

    fn overrides(&self) -> ProcessOverrides {
        ProcessOverrides {
            algorithm: self.algorithm,
            music_m: self.music_m,
            music_p: self.music_p.map(Some),
            forward_backward: self.forward_only.then_some(false),
            zero_pad: self.zero_pad,
            window: self.window,
            fft_precision: self.fft_precision,
            interpolate: self.no_interpolation.then_some(false),
            system_delay_s: self.system_delay,
            min_range_m: self.min_range,
            max_range_m: self.max_range,
            detector: self.detector,
            pfa: self.pfa,
            min_separation_m: self.min_separation.map(Some),
            chain_floor_db: self.chain_floor_db,
            awg_amplitude_vpp: None,
            correction: None,
            ranging: self.ranging,
            keep_background: !self.no_background,
            require_correction: false,
        }
    }

    /// The correction asked for: `None` keeps what each capture recorded.
    fn correction(
        &self,
        out: &Path,
    ) -> anyhow::Result<Option<Option<crate::measure::CorrectionUsed>>> {
        use crate::measure::Calibration;
        if let Some(r) = self.reference_range {
            crate::measure::check(r, 2.0)?;
            let Some(capture) = &self.calibration else {
                return Err(bad_input(
                    "--reference-range needs --calibration CAPTURE: the capture of one reference \
                     pillar to measure the response from",
                ));
            };
            if self.correction == Some(CorrectionMode::None) {
                return Err(bad_input(
                    "--correction none with --calibration: give one or the other",
                ));
            }
            std::fs::create_dir_all(out)?;
            let cal = crate::measure::response_from_capture::calibrate_from_capture(
                capture,
                r,
                crate::measure::default_gate_s(r),
                &out.join("reference-response.toml"),
            )?;
            eprintln!(
                "response measured from {} (reference at {r} m): side-lobe {:.2} -> {:.2} dB; \
                 stored in {}",
                capture.display(),
                cal.header.reference.sidelobe_db_before.unwrap_or(f64::NAN),
                cal.header.reference.sidelobe_db_after.unwrap_or(f64::NAN),
                cal.path.display()
            );
            return Ok(Some(Some(cal.used())));
        }
        if matches!(
            self.correction,
            Some(CorrectionMode::Tx | CorrectionMode::Both)
        ) {
            return Err(bad_input(
                "--correction: none or rx (a capture already made cannot be pre-distorted; one \
                 captured with tx or both is processed as it was unless --correction is given)",
            ));
        }
        Ok(match (self.correction, &self.calibration) {
            (Some(CorrectionMode::None), Some(_)) => {
                return Err(bad_input(
                    "--correction none with --calibration: give one or the other",
                ))
            }
            (Some(CorrectionMode::None), None) => Some(None),
            (_, Some(path)) => Some(Some(Calibration::load(path)?.used())),
            // rx without a file: what each capture recorded (checked per capture).
            (_, None) => None,
        })
    }

    fn waveform(&self) -> anyhow::Result<WaveformChoice> {
        let spec = match self.waveform {
            Some(w) => Some(self.waveform_args.spec(w)?),
            None => {
                let given = format!("{:?}", self.waveform_args);
                if given != format!("{:?}", WaveformArgs::default()) {
                    return Err(bad_input(
                        "waveform parameters need --waveform msk-lfm|ofdm to say which waveform \
                         they belong to",
                    ));
                }
                None
            }
        };
        Ok(WaveformChoice {
            spec,
            seed: self.seed,
            payload: self.payload.as_ref().map(|p| p.as_bytes().to_vec()),
        })
    }
}
