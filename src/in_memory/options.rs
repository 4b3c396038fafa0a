//! The options of `radbench process` and of the waveform, as clap parses them: the command
//! line flattens them into its commands, [`super::ProcessRequest`] and [`super::transmission`]
//! parse the same definitions for the Python package (one definition of names, defaults, checks
//! and messages).
//!
//! Doc comments on the clap structs are `--help` text, not rustdoc: brackets and angle brackets
//! in them are literal.
#![allow(rustdoc::broken_intra_doc_links, rustdoc::invalid_html_tags)]

use crate::exit::bad_input;
use crate::measure::processing::family::overrides::{OverrideError, WaveformOverrides};
use crate::measure::CorrectionMode;
use crate::measure::WaveformChoice;
use crate::measure::{CorrectionUsed, ProcessOverrides, ProcessingChoices};
use crate::waveform::{SweepBand, WaveformKind, WaveformSpec};
use std::path::{Path, PathBuf};

pub use crate::measure::{listed, Listed};

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
    #[command(flatten)]
    pub choices: ProcessingChoices,
    /// The bench's fixed delay, seconds (default: what the capture was processed with).
    #[arg(long, value_name = "S", allow_hyphen_values = true)]
    pub system_delay: Option<f64>,
    /// The reference pillar's true range in the --calibration capture, metres.
    #[arg(long, value_name = "METRES", allow_hyphen_values = true)]
    pub reference_range: Option<f64>,
}

impl ProcessArgs {
    /// The waveform and the processing options asked for; `measured`: the response
    /// [`measure_reference`](Self::measure_reference) measured, when it ran.
    pub fn settings(
        &self,
        measured: Option<CorrectionUsed>,
    ) -> anyhow::Result<(WaveformChoice, ProcessOverrides)> {
        let waveform = self.waveform()?;
        let mut overrides = ProcessOverrides {
            choices: self.choices.clone(),
            system_delay_s: self.system_delay,
            keep_background: !self.no_background,
            ..ProcessOverrides::default()
        };
        let (correction, require) = self.correction(measured)?;
        overrides.correction = correction;
        overrides.require_correction = require;
        Ok((waveform, overrides))
    }

    /// With `--reference-range`: the response measured from the `--calibration` capture of one
    /// reference pillar, written to `out/reference-response.toml` (the one option that writes:
    /// an explicit step of `radbench process`, never a side effect of parsing). `None` without
    /// it.
    pub fn measure_reference(&self, out: &Path) -> anyhow::Result<Option<CorrectionUsed>> {
        let Some(r) = self.reference_range else {
            return Ok(None);
        };
        crate::measure::check(r, 2.0)?;
        let Some(capture) = &self.choices.calibration else {
            return Err(bad_input(
                "--reference-range needs --calibration CAPTURE: the capture of one reference \
                 pillar to measure the response from",
            ));
        };
        if self.choices.correction == Some(CorrectionMode::None) {
            return Err(bad_input(
                "--correction none with --calibration: give one or the other",
            ));
        }
        std::fs::create_dir_all(out)?;
        let cal = crate::measure::calibration::response_from_capture::calibrate_from_capture(
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
        Ok(Some(std::sync::Arc::new(cal).used()))
    }

    /// The correction asked for (`None` keeps what each capture recorded), and the mode each
    /// capture's own recorded calibration is to be used with when no file is given.
    #[allow(clippy::type_complexity)]
    fn correction(
        &self,
        measured: Option<CorrectionUsed>,
    ) -> anyhow::Result<(Option<Option<CorrectionUsed>>, Option<CorrectionMode>)> {
        use crate::measure::Calibration;
        let mode = self.choices.correction;
        if let Some(used) = measured {
            // Measured from a capture of the reference pillar: applied on receive.
            return Ok((Some(Some(used)), None));
        }
        Ok(match (mode, &self.choices.calibration) {
            (Some(CorrectionMode::None), Some(_)) => {
                return Err(bad_input(
                    "--correction none with --calibration: give one or the other",
                ))
            }
            (Some(CorrectionMode::None), None) => (Some(None), None),
            (mode, Some(path)) => (
                Some(Some(
                    std::sync::Arc::new(Calibration::load(path)?)
                        .used_as(mode.unwrap_or(CorrectionMode::Rx)),
                )),
                None,
            ),
            // A mode without a file: each capture's own recorded calibration, with that mode
            // (checked per capture).
            (Some(mode), None) => (None, Some(mode)),
            (None, None) => (None, None),
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
