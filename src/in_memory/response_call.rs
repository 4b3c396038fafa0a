//! `radbench calibrate response`'s options given as keywords (Python's
//! `Bench.calibrate_response(2.0, bandwidth=..., repetitions=16)`), parsed by the command's own
//! definitions so the checks and messages are the command's.

use super::keywords;
use super::options::WaveformArgs;
use crate::exit::bad_input;
use crate::waveform::WaveformKind;
use clap::Parser;
use std::path::PathBuf;

/// The waveform's options `calibrate response` takes (the band measured is this waveform's).
#[derive(clap::Parser)]
#[command(disable_help_flag = true, disable_version_flag = true)]
struct ResponseParser {
    #[command(flatten)]
    waveform_args: WaveformArgs,
}

/// One response calibration's options, checked before anything radiates.
#[derive(Debug, Clone)]
pub struct ResponseOptions {
    pub waveform: WaveformKind,
    pub waveform_args: WaveformArgs,
    pub reference_range_m: f64,
    pub repetitions: usize,
    pub gate_ns: Option<f64>,
    /// A fixed reflector named in the reference's scene, m (`--reflector`).
    pub reflector_m: Option<f64>,
    /// The header's path (`.toml`); `None`: beside the bench file, or not stored on the
    /// built-in lab.
    pub out: Option<PathBuf>,
    /// Store it even when correcting does not bring the reference closer to a flat chain.
    pub force: bool,
}

impl ResponseOptions {
    /// `keywords`: a JSON object of the waveform's options (`bandwidth`, `pulse_us`, `band`,
    /// ...); errors name the keyword.
    #[allow(clippy::too_many_arguments)]
    pub fn from_keywords(
        waveform: WaveformKind,
        keywords: &str,
        reference_range_m: f64,
        repetitions: usize,
        gate_ns: Option<f64>,
        reflector_m: Option<f64>,
        out: Option<PathBuf>,
        force: bool,
    ) -> anyhow::Result<ResponseOptions> {
        use clap::CommandFactory;
        let (choices, own) = keywords::split(keywords)?;
        if choices != crate::measure::ProcessingChoices::default() {
            return Err(bad_input(
                "calibrate_response takes the waveform's options only: the processing choices \
                 (window, algorithm, ...) belong to the captures it corrects",
            ));
        }
        let longs: Vec<String> = ResponseParser::command()
            .get_arguments()
            .filter_map(|a| a.get_long())
            .map(String::from)
            .collect();
        keywords::check_known(&own, &longs, &[])?;
        let argv = ["calibrate-response"]
            .into_iter()
            .map(String::from)
            .chain(own.iter().cloned());
        let args = ResponseParser::try_parse_from(argv)
            .map_err(|e| keywords::in_keywords(keywords::parse_error(&e), &longs))?;
        let respelled = |e: crate::measure::MeasureError| {
            keywords::in_keywords(
                e.into(),
                &["gate-ns".into(), "reflector".into(), "out".into()],
            )
        };
        crate::measure::check(reference_range_m, 2.0)?;
        crate::measure::check_repetitions(repetitions)?;
        crate::measure::check_gate_ns(gate_ns).map_err(respelled)?;
        crate::measure::check_reflector_m(reflector_m, reference_range_m).map_err(respelled)?;
        crate::measure::check_response_out(out.as_deref()).map_err(respelled)?;
        args.waveform_args
            .spec(waveform)
            .map_err(|e| keywords::in_keywords(e, &longs))?;
        Ok(ResponseOptions {
            waveform,
            waveform_args: args.waveform_args,
            reference_range_m,
            repetitions,
            gate_ns,
            reflector_m,
            out,
            force,
        })
    }
}
