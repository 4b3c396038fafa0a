//! radbench's commands with their results in memory instead of files: what radbench's Python
//! package (`python/`) calls, so that Python gets the command line's own option parsing (names,
//! defaults, checks and messages), readers and pipeline, not a second implementation.
//!
//! - [`ProcessRequest`]: `radbench process`'s options, then one capture (or samples) processed
//!   as `radbench process` processes it, its `summary.json` returned with the arrays behind it;
//! - [`captures`]: the captures `radbench process INPUT...` would process, with its folder names;
//! - [`read_capture`]: a capture's repetitions in volts, decimated and aligned, its metadata;
//! - [`transmission`]: the waveform `radbench capture --waveform KIND` makes, with its AWG codes;
//! - [`BenchSession`]: a warm session on a bench (`radbench.Bench`): captures as `radbench
//!   capture` takes them ([`CaptureOptions`]), connections, upload and pipeline kept between them.
//!
//! The options are parsed by the same clap definitions the command line flattens into its
//! commands ([`ProcessArgs`], [`WaveformArgs`], [`PayloadArgs`]); `radbench process` also
//! shares the per-capture work (`compute`, `folder_names`, the hashes a run recorded).
//!
//! Errors are the command line's ([`crate::exit::render`] gives its text, [`crate::classify`]
//! its exit class).

mod batch;
mod bench;
mod bench_lock;
mod capture_call;
mod keywords;
mod options;
mod processed;
mod response_call;

use batch::on_cached_pipeline;
pub use batch::{compute, folder_names, recorded_data_hashes, recorded_for};
pub use bench::{BenchSession, Call, CampaignEvents, CampaignSpec, SessionSource};
pub use capture_call::{calibration_warnings, prepare_out, resolve_correction, CaptureOptions};
pub use options::{listed, Listed, PayloadArgs, ProcessArgs, WaveformArgs};
pub use processed::InMemory;
pub use response_call::ResponseOptions;

use keywords::parse_error;

use crate::exit::bad_input;
use crate::measure::records::reprocess::{self, Loaded, Source, WaveformChoice};
use crate::measure::ProcessOverrides;
use crate::measure::{Aligned, Dac, MeasureError, RawIq, Transmission};
use crate::waveform::WaveformKind;
use clap::Parser;
use serde_json::{Map, Value};
use std::path::{Path, PathBuf};

/// The options of `radbench process` that processing in memory refuses (nothing is written).
const REFUSED_IN_MEMORY: [&str; 4] = ["--out", "--jobs", "--json", "--reference-range"];

/// `radbench process`'s processing options alone.
#[derive(clap::Parser)]
#[command(disable_help_flag = true, disable_version_flag = true)]
struct ProcessParser {
    #[command(flatten)]
    options: ProcessArgs,
}

/// The waveform options of `radbench capture` alone.
#[derive(clap::Parser)]
#[command(disable_help_flag = true, disable_version_flag = true)]
struct TransmissionParser {
    #[command(flatten)]
    waveform_args: WaveformArgs,
    #[command(flatten)]
    bits: PayloadArgs,
}

/// An option of `radbench process` that processing in memory has not.
fn not_in_memory(name: &str) -> anyhow::Error {
    bad_input(format!(
        "{name}: not an option of processing in memory (nothing is written; a response is \
         measured with `radbench process --calibration CAPTURE --reference-range M`, whose file \
         is then given as --calibration)"
    ))
}

/// One capture of the inputs: what names it (its `.sigmf-meta`, or its I and Q `.trc`) and the
/// folder name `radbench process` gives its results.
#[derive(Debug, Clone, PartialEq)]
pub struct CaptureInput {
    pub name: String,
    pub files: Vec<PathBuf>,
}

/// The captures `radbench process INPUT...` would process, in its order (a run folder gives
/// every step's); an input that is not a capture is an error naming it (bad input).
pub fn captures(inputs: &[PathBuf]) -> anyhow::Result<Vec<CaptureInput>> {
    let mut sources = Vec::new();
    for found in reprocess::discover(inputs) {
        sources.push(found.map_err(|e| bad_input(e.to_string()))?);
    }
    let refs: Vec<&Source> = sources.iter().collect();
    let names = folder_names(&refs);
    Ok(sources
        .iter()
        .zip(names)
        .map(|(s, name)| CaptureInput {
            name,
            files: match s {
                Source::Sigmf { meta, .. } => vec![meta.clone()],
                Source::TrcPair { i, q } => vec![i.clone(), q.clone()],
            },
        })
        .collect())
}

/// The one capture `files` name (a capture folder, a `.sigmf-meta`, or an I and a Q `.trc`).
fn one_capture(files: &[PathBuf]) -> anyhow::Result<Source> {
    let mut found = reprocess::discover(files);
    match found.len() {
        1 => found.remove(0).map_err(|e| bad_input(e.to_string())),
        0 => Err(bad_input("input: no capture given")),
        n => Err(bad_input(format!(
            "input: {} names {n} captures (a run folder?); give one capture (`captures` lists \
             them, `read_run` reads a run)",
            files
                .iter()
                .map(|f| f.display().to_string())
                .collect::<Vec<_>>()
                .join(" ")
        ))),
    }
}

/// `radbench process`'s options, parsed and checked as its command line does.
#[derive(Debug)]
pub struct ProcessRequest {
    args: Box<ProcessArgs>,
    waveform: WaveformChoice,
    overrides: ProcessOverrides,
    /// The option names to write as keywords in errors (`ProcessRequest::parse_keywords`).
    keywords: Option<Vec<String>>,
}

impl ProcessRequest {
    /// `options` as written after `radbench process INPUT` (e.g. `["--algorithm", "music",
    /// "--m", "32"]`). What writes files or steers the command (`--out`, `--jobs`, `--json`,
    /// `--reference-range`) is refused.
    pub fn parse(options: &[String]) -> anyhow::Result<ProcessRequest> {
        // What the command has but processing in memory has not: refused by name (the command's
        // parser would take them; this one would only call them unknown).
        for o in options.iter().filter(|o| o.starts_with("--")) {
            let name = o.split('=').next().unwrap_or(o);
            if REFUSED_IN_MEMORY[..3].contains(&name) {
                return Err(not_in_memory(name));
            }
        }
        let argv = ["radbench process"]
            .into_iter()
            .map(String::from)
            .chain(options.iter().cloned());
        let args = Box::new(
            ProcessParser::try_parse_from(argv)
                .map_err(|e| parse_error(&e))?
                .options,
        );
        if args.reference_range.is_some() {
            return Err(not_in_memory("--reference-range"));
        }
        // Nothing is written: --reference-range, the one option that writes, is refused above.
        let (waveform, overrides) = args.settings(None)?;
        Ok(ProcessRequest {
            args,
            waveform,
            overrides,
            keywords: None,
        })
    }

    /// [`parse`](Self::parse) for options given as keywords (the Python package's
    /// `process(window="hann")`, passed here as `--window=hann`): an unknown one is named as the
    /// keyword it was (`windw`, with a did-you-mean), and every message names keywords, not
    /// command-line options.
    pub(crate) fn parse_keywords(options: &[String]) -> anyhow::Result<ProcessRequest> {
        use clap::CommandFactory;
        let longs: Vec<String> = ProcessParser::command()
            .get_arguments()
            .filter_map(|a| a.get_long())
            .map(String::from)
            .collect();
        keywords::check_known(options, &longs, &REFUSED_IN_MEMORY)?;
        let named: Vec<String> = longs
            .into_iter()
            .chain(REFUSED_IN_MEMORY.iter().map(|r| r[2..].to_string()))
            .collect();
        let mut request = Self::parse(options).map_err(|e| keywords::in_keywords(e, &named))?;
        request.keywords = Some(named);
        Ok(request)
    }

    /// The Python package's keywords, a JSON object (`{"window": "hann", "m": 32}`): the
    /// processing choices through serde as [`crate::measure::ProcessingChoices`], the
    /// command's own options (the waveform of a capture radbench did not make, `seed`,
    /// `payload`, `background`, ...) as `parse_keywords` takes them.
    pub fn from_keywords(keywords: &str) -> anyhow::Result<ProcessRequest> {
        let (choices, own) = keywords::split(keywords)?;
        let mut request = Self::parse_keywords(&own)?;
        request.args.choices = choices;
        let (waveform, overrides) = request
            .args
            .settings(None)
            .map_err(|e| request.in_callers_words(e))?;
        request.waveform = waveform;
        request.overrides = overrides;
        Ok(request)
    }

    /// The options as parsed, and the waveform and processing options they resolve to (archive
    /// processing addresses its outputs by them).
    pub(crate) fn parts(&self) -> (&ProcessArgs, &WaveformChoice, &ProcessOverrides) {
        (&self.args, &self.waveform, &self.overrides)
    }

    /// `err` in the words the options were given in (keywords after
    /// `parse_keywords`).
    fn in_callers_words(&self, err: anyhow::Error) -> anyhow::Error {
        match &self.keywords {
            Some(named) => keywords::in_keywords(err, named),
            None => err,
        }
    }

    /// The capture `files` name, processed as `radbench process` processes it.
    pub fn capture(&self, files: &[PathBuf]) -> anyhow::Result<InMemory> {
        self.capture_files(files)
            .map_err(|e| self.in_callers_words(e))
    }

    /// A record of samples, processed as a capture radbench did not make (`--waveform` and its
    /// parameters, `--seed`, `--payload`, `--trigger-offset` describe it).
    pub fn samples(&self, raw: RawIq) -> anyhow::Result<InMemory> {
        self.samples_of(raw).map_err(|e| self.in_callers_words(e))
    }

    fn capture_files(&self, files: &[PathBuf]) -> anyhow::Result<InMemory> {
        let source = one_capture(files)?;
        // A capture of a run folder is checked against the hash its run recorded, as
        // `radbench process` checks it.
        let recorded = recorded_data_hashes(&[&source]);
        let (loaded, r, sources) = compute(
            &source,
            recorded_for(&source, &recorded),
            &self.waveform,
            &self.overrides,
            self.args.background.as_deref(),
            self.args.trigger_offset,
        )?;
        let summary = crate::measure::records::record::reprocessed_summary(&sources, &loaded, &r);
        Ok(InMemory {
            summary,
            options: r.resolved.options,
            processed: r.processed,
        })
    }

    /// A record of samples (volts, one repetition starting `first_point_s` after the marker)
    /// processed as a capture radbench did not make: the waveform must be given (`--waveform`).
    fn samples_of(&self, raw: RawIq) -> anyhow::Result<InMemory> {
        if raw.samples.is_empty() {
            return Err(bad_input(
                "samples: an empty record; give at least one repetition",
            ));
        }
        if !(raw.sample_rate_hz.is_finite() && raw.sample_rate_hz > 0.0) {
            return Err(bad_input(format!(
                "capture_rate: {} Hz; give the samples' rate in Hz, a positive number",
                raw.sample_rate_hz
            )));
        }
        let loaded = Loaded {
            repetitions: vec![RawIq {
                first_point_s: self.args.trigger_offset.unwrap_or(raw.first_point_s),
                ..raw
            }],
            clipping: Vec::new(),
            radbench: Map::new(),
            sha256: Vec::new(),
        };
        let resolved = reprocess::resolve(
            &loaded,
            &self.waveform,
            &self.overrides,
            self.args.background.as_deref(),
        )?;
        let r = on_cached_pipeline(&loaded, resolved)?;
        let summary = crate::measure::records::record::reprocessed_summary(&[], &loaded, &r);
        Ok(InMemory {
            summary,
            options: r.resolved.options,
            processed: r.processed,
        })
    }
}

/// A saved capture read back.
#[derive(Debug, Clone)]
pub struct CaptureData {
    /// The files read (a `.sigmf-meta` and its data, or the I and Q `.trc`).
    pub files: Vec<PathBuf>,
    /// Each repetition in volts at the capture rate, from the first sample after the marker.
    pub raw: Vec<RawIq>,
    /// Each repetition decimated to the processing rate and aligned to the marker as the pipeline
    /// aligns it (volts, before background and correction); empty when the capture does not say
    /// its waveform.
    pub decimated: Vec<Aligned>,
    /// The processing rate of `decimated` (`None` with it empty).
    pub processing_rate_hz: Option<f64>,
    /// Why `decimated` is empty, if it is.
    pub not_decimated: Option<String>,
    /// The `radbench:` metadata (empty for a capture radbench did not make).
    pub radbench: Map<String, Value>,
    /// The simulated scene of a simulated bench's capture (ground truth).
    pub scene: Option<Value>,
}

/// The capture `files` name (a capture folder, a `.sigmf-meta`, or an I and a Q `.trc`).
pub fn read_capture(files: &[PathBuf]) -> anyhow::Result<CaptureData> {
    let source = one_capture(files)?;
    let loaded = reprocess::load(&source, None)?;
    let rate = loaded
        .repetitions
        .first()
        .map(|r| r.sample_rate_hz)
        .ok_or_else(|| bad_input("input: a capture without a repetition"))?;
    let overrides = ProcessOverrides::default();
    let (decimated, processing_rate_hz, not_decimated) =
        match reprocess::resolve(&loaded, &WaveformChoice::default(), &overrides, None) {
            Ok(resolved) => {
                let fs = resolved.tx.sample_rate_hz();
                let mut pipeline = reprocess::pipeline(&resolved, rate)?;
                let aligned = loaded
                    .repetitions
                    .iter()
                    .map(|rep| pipeline.align(rep))
                    .collect::<Result<Vec<_>, _>>()?;
                (aligned, Some(fs), None)
            }
            Err(e @ MeasureError::NeedsWaveform) => (Vec::new(), None, Some(e.to_string())),
            Err(e) => return Err(e.into()),
        };
    Ok(CaptureData {
        files: source.files().into_iter().map(Path::to_path_buf).collect(),
        scene: loaded.ground_truth().cloned(),
        raw: loaded.repetitions,
        decimated,
        processing_rate_hz,
        not_decimated,
        radbench: loaded.radbench,
    })
}

/// Waveform options of `radbench capture` that [`transmission`] takes.
const WAVEFORM_OPTIONS: [&str; 11] = [
    "--bandwidth",
    "--sample-rate",
    "--pulse-us",
    "--bits-per-pulse",
    "--band",
    "--subcarriers",
    "--oversampling",
    "--cp-fraction",
    "--symbols",
    "--payload",
    "--seed",
];

/// The transmission `radbench capture --waveform KIND OPTIONS` makes (its parameters, defaults
/// and checks): the complex baseband, the AWG's 8-bit codes and marker, the bits. `options` are
/// the waveform's (`--bandwidth`, ..., `--payload`, `--seed`).
pub fn transmission(kind: WaveformKind, options: &[String]) -> anyhow::Result<Transmission> {
    for o in options.iter().filter(|o| o.starts_with("--")) {
        let name = o.split('=').next().unwrap_or(o);
        if !WAVEFORM_OPTIONS.contains(&name) {
            return Err(bad_input(format!(
                "{name}: not a waveform option; the options are {}",
                WAVEFORM_OPTIONS.join(", ")
            )));
        }
    }
    let argv = ["radbench capture"]
        .into_iter()
        .map(String::from)
        .chain(options.iter().cloned());
    let args = TransmissionParser::try_parse_from(argv).map_err(|e| parse_error(&e))?;
    let spec = args.waveform_args.spec(kind)?;
    let payload = args.bits.payload.as_ref().map(|p| p.as_bytes().to_vec());
    Ok(Transmission::new(
        &spec,
        payload.as_deref(),
        args.bits.seed,
        Dac::default(),
    )?)
}
