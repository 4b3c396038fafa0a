//! The processing choices a user makes, declared once: the command line's options (flattened
//! into `capture`, `align`, `simulate run` and `process`), a campaign's `[processing]` table and
//! the Python package's keywords (through serde). Every choice is optional: one not made keeps
//! its base, the defaults of [`ProcessOptions`] (their one home) or what a saved capture
//! recorded.
//!
//! The command line's spellings (`--m`, `--forward-only`, `--min-range`) are older than the
//! files' (`music_m`, `forward_backward`, `min_range_m`) and both stay: files written before
//! load as they did. Python takes the files' names, and the command line's where they differ
//! (`m`, `p`, `min_range`, ...), as aliases.
//!
//! Doc comments on the fields are `--help` text, not rustdoc: brackets in them are literal.
#![allow(rustdoc::broken_intra_doc_links)]

use super::listed::listed;
use super::options::{
    Algorithm, DetectorName, FftPrecisionName, ProcessOptions, Ranging, WindowName,
};
use crate::measure::calibration::correction::CorrectionUsed;
use crate::measure::calibration::response::CorrectionMode;
use crate::waveform::WaveformKind;
use serde::{Deserialize, Serialize};
use std::path::PathBuf;

/// The processing choices (see the module's documentation).
#[derive(Debug, Clone, Default, PartialEq, clap::Args, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ProcessingChoices {
    /// Range processing: correlation (default for MSK-LFM), fourier (default for OFDM), music,
    /// root-music or esprit (OFDM).
    #[arg(long, value_parser = listed::<Algorithm>())]
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub algorithm: Option<Algorithm>,
    /// A campaign's algorithms, each applied to the same captures (`[processing] algorithms`;
    /// the command line takes one `--algorithm`).
    #[arg(skip)]
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub algorithms: Vec<Algorithm>,
    /// MUSIC sub-vector (covariance) length M [default: 64].
    #[arg(long = "m", value_name = "M")]
    #[serde(default, alias = "m", skip_serializing_if = "Option::is_none")]
    pub music_m: Option<usize>,
    /// Number of targets for MUSIC/root-MUSIC/ESPRIT [default: estimated with MDL]; a campaign
    /// may say "targets" (each step's number of targets).
    #[arg(long = "p", value_name = "P", value_parser = parse_model_order)]
    #[serde(default, alias = "p", skip_serializing_if = "Option::is_none")]
    pub music_p: Option<ModelOrderChoice>,
    /// Forward smoothing only (no forward-backward averaging) for MUSIC.
    #[arg(long = "forward-only", num_args = 0, default_missing_value = "false")]
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub forward_backward: Option<bool>,
    /// OFDM Fourier zero-padding factor: IFFT length = K x subcarriers [default: 10].
    #[arg(long, value_name = "K")]
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub zero_pad: Option<usize>,
    /// Window on the range processing (OFDM: across the subcarriers; correlation: on the
    /// matched filter's spectrum) [default: rect].
    #[arg(long, value_parser = listed::<WindowName>(), value_name = "NAME")]
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub window: Option<WindowName>,
    /// Precision of the OFDM receiver's per-symbol FFT (the rest is double precision)
    /// [default: single].
    #[arg(long, value_parser = listed::<FftPrecisionName>(), value_name = "P")]
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub fft_precision: Option<FftPrecisionName>,
    /// Report the on-grid peak (no sub-sample interpolation).
    #[arg(
        long = "no-interpolation",
        num_args = 0,
        default_missing_value = "false"
    )]
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub interpolate: Option<bool>,
    /// Detector of the correlation and Fourier profiles (docs/detection.md compares them)
    /// [default: clean].
    #[arg(long, value_parser = listed::<DetectorName>(), value_name = "NAME")]
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub detector: Option<DetectorName>,
    /// Probability of false alarm of the detector, per profile cell [default: 1e-6].
    #[arg(long, value_name = "P", allow_hyphen_values = true)]
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub pfa: Option<f64>,
    /// Targets closer than this are reported as one, metres [default: 0.75 resolution cells].
    #[arg(
        long = "min-separation",
        value_name = "METRES",
        allow_hyphen_values = true
    )]
    #[serde(
        default,
        alias = "min_separation",
        skip_serializing_if = "Option::is_none"
    )]
    pub min_separation_m: Option<f64>,
    /// Around a target whose main lobe does not fit the ideal point spread to 50 dB, a weaker
    /// echo within 1.6 m is a target only within this many dB of it (the chain's own echoes are
    /// part of its response; docs/detection.md). Lower it for a bench known to be cleaner;
    /// -200 turns it off [default: -17].
    #[arg(long, value_name = "DB", allow_hyphen_values = true)]
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub chain_floor_db: Option<f64>,
    /// How each target's range is measured: envelope (the echo's envelope), or phase: refined by
    /// the echo's carrier phase against the calibration's reference, to a fraction of a
    /// micrometre (docs/metrology.md; needs a response calibration) [default: envelope].
    #[arg(long, value_parser = listed::<Ranging>(), value_name = "MODE")]
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub ranging: Option<Ranging>,
    /// Ignore detections closer than this (the Tx -> Rx leakage sits near 0 m), metres
    /// [default: 0.15].
    #[arg(long = "min-range", value_name = "METRES", allow_hyphen_values = true)]
    #[serde(default, alias = "min_range", skip_serializing_if = "Option::is_none")]
    pub min_range_m: Option<f64>,
    /// Ignore detections farther than this, metres [default: 10].
    #[arg(long = "max-range", value_name = "METRES", allow_hyphen_values = true)]
    #[serde(default, alias = "max_range", skip_serializing_if = "Option::is_none")]
    pub max_range_m: Option<f64>,
    /// Correction of the chain's measured errors: none; rx (DC, I/Q imbalance and the chain's
    /// response on receive); tx (the AWG's codes pre-distorted for the response); both (tx, and
    /// the receiver's DC and I/Q imbalance). Default: rx when a response calibration is named
    /// (--calibration, or the bench file's), none otherwise; a saved capture keeps what it was
    /// processed with.
    #[arg(long, value_parser = listed::<CorrectionMode>())]
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub correction: Option<CorrectionMode>,
    /// A response calibration (`radbench calibrate response` wrote it) to correct with, instead
    /// of the bench file's (a campaign: relative to the spec's folder).
    #[arg(long, value_name = "FILE")]
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub calibration: Option<PathBuf>,
}

/// The subspace algorithms' model order as chosen: a number of targets, or (a campaign)
/// `"targets"`, each step's number of targets as the thesis set it by hand.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize, Serialize)]
#[serde(untagged)]
pub enum ModelOrderChoice {
    Fixed(usize),
    Named(ModelOrderName),
}

/// The named model orders.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize, Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum ModelOrderName {
    /// The step's number of nominal targets.
    Targets,
}

/// `--p`: a number (the command line has no steps to count targets in).
fn parse_model_order(s: &str) -> Result<ModelOrderChoice, String> {
    s.parse::<usize>()
        .map(ModelOrderChoice::Fixed)
        .map_err(|_| format!("`{s}`: allowed: a whole number of targets"))
}

impl ProcessingChoices {
    /// `base` with every choice made here replaced (the correction and the calibration are
    /// resolved by the caller, which knows the bench: they are left alone).
    pub fn apply(&self, base: ProcessOptions) -> ProcessOptions {
        // Destructured, so that a choice added later cannot be forgotten here.
        let ProcessingChoices {
            algorithm,
            algorithms: _,
            music_m,
            music_p,
            forward_backward,
            zero_pad,
            window,
            fft_precision,
            interpolate,
            detector,
            pfa,
            min_separation_m,
            chain_floor_db,
            ranging,
            min_range_m,
            max_range_m,
            correction: _,
            calibration: _,
        } = self;
        ProcessOptions {
            algorithm: algorithm.unwrap_or(base.algorithm),
            music_m: music_m.unwrap_or(base.music_m),
            music_p: match music_p {
                Some(ModelOrderChoice::Fixed(n)) => Some(*n),
                // Counted per step by a campaign; elsewhere estimated.
                Some(ModelOrderChoice::Named(_)) => None,
                None => base.music_p,
            },
            forward_backward: forward_backward.unwrap_or(base.forward_backward),
            zero_pad: zero_pad.unwrap_or(base.zero_pad),
            window: window.unwrap_or(base.window),
            fft_precision: fft_precision.unwrap_or(base.fft_precision),
            interpolate: interpolate.unwrap_or(base.interpolate),
            detector: detector.unwrap_or(base.detector),
            pfa: pfa.unwrap_or(base.pfa),
            min_separation_m: min_separation_m.or(base.min_separation_m),
            chain_floor_db: chain_floor_db.unwrap_or(base.chain_floor_db),
            ranging: ranging.unwrap_or(base.ranging),
            min_range_m: min_range_m.unwrap_or(base.min_range_m),
            max_range_m: max_range_m.unwrap_or(base.max_range_m),
            ..base
        }
    }

    /// The options for `waveform`: its default algorithm and [`ProcessOptions`]' defaults, with
    /// these choices over them.
    pub fn options(&self, waveform: WaveformKind) -> ProcessOptions {
        self.apply(ProcessOptions::for_waveform(waveform))
    }

    /// Every choice `options` made (the correction and calibration aside: they come resolved):
    /// applied to any base, they give `options` back, the carrier aside.
    pub fn of(options: &ProcessOptions) -> Self {
        let ProcessOptions {
            algorithm,
            music_m,
            music_p,
            forward_backward,
            zero_pad,
            window,
            fft_precision,
            interpolate,
            system_delay_s: _,
            min_range_m,
            max_range_m,
            detector,
            pfa,
            min_separation_m,
            chain_floor_db,
            carrier_hz: _,
            awg_amplitude_vpp: _,
            correction: _,
            ranging,
            trigger_jitter_s: _,
        } = options.clone();
        Self {
            algorithm: Some(algorithm),
            algorithms: Vec::new(),
            music_m: Some(music_m),
            music_p: music_p.map(ModelOrderChoice::Fixed),
            forward_backward: Some(forward_backward),
            zero_pad: Some(zero_pad),
            window: Some(window),
            fft_precision: Some(fft_precision),
            interpolate: Some(interpolate),
            detector: Some(detector),
            pfa: Some(pfa),
            min_separation_m,
            chain_floor_db: Some(chain_floor_db),
            ranging: Some(ranging),
            min_range_m: Some(min_range_m),
            max_range_m: Some(max_range_m),
            correction: None,
            calibration: None,
        }
    }

    /// The keys a table of choices may hold (a campaign's `[processing]`, the Python keywords),
    /// aliases included.
    pub const KEYS: &'static [&'static str] = &[
        "algorithm",
        "algorithms",
        "music_m",
        "m",
        "music_p",
        "p",
        "forward_backward",
        "zero_pad",
        "window",
        "fft_precision",
        "interpolate",
        "detector",
        "pfa",
        "min_separation_m",
        "min_separation",
        "chain_floor_db",
        "ranging",
        "min_range_m",
        "min_range",
        "max_range_m",
        "max_range",
        "correction",
        "calibration",
    ];
}

/// Processing options given explicitly, laid over a base (what a saved capture recorded, or the
/// defaults): the user's [`ProcessingChoices`], and what re-processing resolves beside them.
#[derive(Debug, Clone, Default)]
pub struct ProcessOverrides {
    /// The choices made (their correction and calibration are resolved into `correction`).
    pub choices: ProcessingChoices,
    pub system_delay_s: Option<f64>,
    pub awg_amplitude_vpp: Option<Option<f64>>,
    pub correction: Option<Option<CorrectionUsed>>,
    /// Subtract the background the capture recorded (when it had one).
    pub keep_background: bool,
    /// `--correction MODE` without a file: the capture must have recorded a calibration, used
    /// with this mode.
    pub require_correction: Option<CorrectionMode>,
    /// Every option exactly (a campaign's further algorithms), the carrier aside.
    pub(crate) exact: Option<Box<ProcessOptions>>,
}

impl ProcessOverrides {
    /// Every option of `options` (its carrier aside, which comes with the capture): a capture
    /// processed with these gives what `options` gave (a campaign's further algorithms). The
    /// capture's background is kept.
    pub(crate) fn replacing(options: &ProcessOptions) -> Self {
        Self {
            exact: Some(Box::new(options.clone())),
            keep_background: true,
            ..Self::default()
        }
    }

    /// Whether an algorithm was chosen (a capture recorded with another waveform's is then
    /// still processed as chosen).
    pub(crate) fn algorithm_given(&self) -> bool {
        self.exact.is_some() || self.choices.algorithm.is_some()
    }

    /// Whether the bench's system delay was given.
    pub(crate) fn system_delay_given(&self) -> bool {
        self.exact.is_some() || self.system_delay_s.is_some()
    }

    /// `base` with every given value replaced.
    pub(crate) fn apply(&self, base: ProcessOptions) -> ProcessOptions {
        if let Some(exact) = &self.exact {
            return ProcessOptions {
                carrier_hz: base.carrier_hz,
                ..(**exact).clone()
            };
        }
        let base = self.choices.apply(base);
        ProcessOptions {
            system_delay_s: self.system_delay_s.unwrap_or(base.system_delay_s),
            awg_amplitude_vpp: self.awg_amplitude_vpp.unwrap_or(base.awg_amplitude_vpp),
            correction: self.correction.clone().unwrap_or(base.correction.clone()),
            ..base
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use clap::Parser;

    #[derive(Parser)]
    struct Cli {
        #[command(flatten)]
        choices: ProcessingChoices,
    }

    fn parse(args: &[&str]) -> ProcessingChoices {
        Cli::try_parse_from(std::iter::once("radbench").chain(args.iter().copied()))
            .unwrap()
            .choices
    }

    #[test]
    fn nothing_given_is_the_defaults() {
        assert_eq!(parse(&[]), ProcessingChoices::default());
        assert_eq!(
            parse(&[]).options(WaveformKind::MskLfm),
            ProcessOptions::for_waveform(WaveformKind::MskLfm)
        );
    }

    #[test]
    fn the_flags_choose_the_off_state() {
        let c = parse(&["--forward-only", "--no-interpolation", "--p", "2"]);
        assert_eq!(c.forward_backward, Some(false));
        assert_eq!(c.interpolate, Some(false));
        assert_eq!(c.music_p, Some(ModelOrderChoice::Fixed(2)));
        let o = c.options(WaveformKind::Ofdm);
        assert!(!o.forward_backward && !o.interpolate);
        assert_eq!(o.music_p, Some(2));
    }

    #[test]
    fn the_command_line_and_a_table_make_the_same_choices() {
        let cli = parse(&[
            "--algorithm",
            "music",
            "--m",
            "32",
            "--window",
            "hann",
            "--min-range",
            "0.3",
            "--min-separation",
            "0.05",
            "--correction",
            "rx",
        ]);
        let table: ProcessingChoices = toml::from_str(
            "algorithm = \"music\"\nmusic_m = 32\nwindow = \"hann\"\nmin_range_m = 0.3\n\
             min_separation_m = 0.05\ncorrection = \"rx\"\n",
        )
        .unwrap();
        assert_eq!(cli, table);
        // Python's spellings are the command line's where the files' differ.
        let keywords: ProcessingChoices = serde_json::from_str(
            r#"{"algorithm":"music","m":32,"window":"hann","min_range":0.3,
                "min_separation":0.05,"correction":"rx"}"#,
        )
        .unwrap();
        assert_eq!(keywords, table);
    }

    #[test]
    fn every_option_survives_of_then_apply() {
        let mut o = ProcessOptions::for_waveform(WaveformKind::Ofdm);
        o.music_p = Some(3);
        o.window = WindowName::Hann;
        o.min_separation_m = Some(0.02);
        let back = ProcessingChoices::of(&o).apply(ProcessOptions::default());
        assert_eq!(back, o);
    }

    #[test]
    fn the_keys_are_the_serialized_names() {
        let all = ProcessingChoices {
            algorithms: vec![Algorithm::Music],
            correction: Some(CorrectionMode::Rx),
            calibration: Some("c.toml".into()),
            music_p: Some(ModelOrderChoice::Fixed(1)),
            ..ProcessingChoices::of(&ProcessOptions {
                min_separation_m: Some(0.1),
                ..ProcessOptions::default()
            })
        };
        let v = serde_json::to_value(&all).unwrap();
        let names: Vec<&str> = v.as_object().unwrap().keys().map(String::as_str).collect();
        for n in &names {
            assert!(ProcessingChoices::KEYS.contains(n), "{n} missing from KEYS");
        }
        assert_eq!(names.len(), 18);
    }

    #[test]
    fn an_unknown_key_is_refused_by_name() {
        let err = toml::from_str::<ProcessingChoices>("windw = \"hann\"\n")
            .unwrap_err()
            .to_string();
        assert!(err.contains("windw"), "{err}");
    }
}
