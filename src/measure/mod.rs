//! Bench measurements: the bench in use, the transmission, one capture under the safe-state guard,
//! and the one processing pipeline every command goes through.
//!
//! | module | what it holds |
//! |---|---|
//! | `ambiguity` | a waveform's ambiguity function as uploaded, a capture's cross-ambiguity |
//! | `bench_file` | the bench file: instruments, resources, calibration |
//! | `bench` | the bench in use: a bench file, or the built-in mock lab started in-process |
//! | `family` | each waveform family's behaviour in one room (`family/msk_lfm.rs`, `family/ofdm.rs`): overrides, transmission, payload decoder, algorithms; `family::of` is the one `match` over the families |
//! | `transmit` | the waveform as AWG codes plus what the receiver needs |
//! | `choices` | the processing choices a user makes, declared once: command-line options, a campaign's `[processing]`, Python's keywords |
//! | `listed` | library enums taken by name on the command line and in files, and clap's parser of them |
//! | `options` | the processing options (algorithm, window, M/p, ranges, Pfa) as plain data, and their defaults |
//! | `pipeline` | decimation, alignment, background, range profile, detection, metrics, payload |
//! | `detect` | the detection stage of the pipeline |
//! | `doctor` | the bench doctor: every check of a bench that needs no RF, with what to fix |
//! | `clipping` | samples at the ADC's rails, the advice, and conservative detection when a record clipped |
//! | `payload` | the communication receivers of the pipeline |
//! | `scene_control` | the simulated bench's scene, typed: set it, reseed its noise, read it back |
//! | `station` | the connected instruments: plan, upload, RF on, capture, safe state |
//! | `capture` | one complete measurement: prepare (everything checked), capture, process |
//! | `reprocess` | saved captures (capture folders, SigMF, `.trc` pairs) through the pipeline again |
//! | `export` | a saved capture's arrays for a notebook (I/Q, profiles, detections, transmission), got through `reprocess` |
//! | `repeat` | several repetitions: coherent average and spread |
//! | `figure` | what a measurement's plot and profile table show |
//! | `record` | a measurement's files: SigMF, `.trc`, profiles, plots, `summary.json` |
//! | `calibration` | the system delay from a reference target |
//! | `interrupt` | SIGINT, SIGTERM and SIGHUP as a measurement's stop request |
//! | `verify_catalog` | `doctor --verify-catalog`: the catalog's inferred values asked of the instruments; override files |
//! | `manual` | front ends with `driver = "manual"`: the operator's instructions, confirmation and exit note |

pub(crate) mod ambiguity;
pub(crate) mod bench;
pub(crate) mod bench_file;
pub(crate) mod calibration;
pub(crate) mod capture;
pub(crate) mod choices;
pub(crate) mod clipping;
pub(crate) mod detect;
pub(crate) mod doctor;
pub(crate) mod export;
pub(crate) mod family;
pub(crate) mod figure;
pub(crate) mod interrupt;
pub(crate) mod listed;
pub(crate) mod manual;
pub(crate) mod numbers;
pub(crate) mod options;
pub(crate) mod payload;
pub(crate) mod pipeline;
#[cfg(test)]
mod predistortion_tests;
pub(crate) mod ranging;
pub(crate) mod record;
pub(crate) mod repeat;
pub(crate) mod reprocess;
pub(crate) mod response;
pub(crate) mod response_from_capture;
pub(crate) mod response_keep;
pub(crate) mod response_run;
pub(crate) mod scene_capture;
pub(crate) mod scene_control;
pub(crate) mod station;
pub(crate) mod transmit;
pub(crate) mod verify_catalog;

pub use ambiguity::*;
pub use bench::*;
pub use bench_file::*;
pub use calibration::*;
pub use capture::*;
pub use doctor::*;
pub use export::*;
pub use figure::*;
pub use interrupt::*;
pub use manual::{confirms, manual_exit_note, manual_instructions, manual_refused};
pub use numbers::*;
pub use options::*;
pub use pipeline::*;
pub use record::*;
pub use repeat::*;
pub use reprocess::*;
pub use response::*;
pub use response_keep::{check_gate_ns, check_response_out, gate_or_default_s};
pub use response_keep::{response_path, response_report, store_response};
pub use response_run::*;
pub use station::*;
pub use verify_catalog::{verify_catalog, write_overrides, CatalogCheck, CatalogValue, Verdict};

// Names two flattened submodules both define, chosen here: the capture's `measure` and the
// re-processing's `Repetition` (`response`'s are the crate's own).
pub use capture::measure;
pub use choices::{ModelOrderChoice, ModelOrderName, ProcessOverrides, ProcessingChoices};
pub use clipping::{ClipDetection, Clipping};
pub use listed::{listed, Listed};
pub use options::{Algorithm, FftPrecisionName, ProcessOptions, WindowName};
pub use pipeline::{Aligned, Pipeline, Processed, RawIq, RecordGeometry};
pub use reprocess::Repetition;
pub use transmit::{Dac, Transmission};

use crate::driver::ErrorKind;
use crate::exit::{Classify, ExitClass};
use std::fmt::Display;

/// Why a measurement failed.
#[derive(Debug, thiserror::Error)]
pub enum MeasureError {
    /// A processing or capture option is out of range.
    #[error("--{option} {value}: allowed: {allowed}")]
    Option {
        option: &'static str,
        value: String,
        allowed: String,
    },
    /// The algorithm needs OFDM symbols.
    #[error(
        "--algorithm {algorithm}: MSK-LFM is processed by correlation; fourier, music, root-music \
         and esprit need --waveform ofdm"
    )]
    AlgorithmNeedsOfdm { algorithm: &'static str },
    /// RF was asked for without the user's permit; `run` names what would have radiated
    /// ("capture", "campaign run", ...).
    #[error(
        "the AWG outputs and the front ends stay off without an explicit permit: pass --allow-rf \
         to switch them on for this {run} (they are switched off again at the end)"
    )]
    NoPermit { run: &'static str },
    /// The bench has manual front ends and the permit carries no operator confirmation of their
    /// settings: refused before anything is sent.
    #[error(
        "the {names} front end settings were not confirmed by the operator: the measurement did \
         not start and nothing was switched on (command line: answer yes on standard input; \
         Python: radbench.Bench(..., manual_front_ends_confirmed=True); Rust: \
         RfPermit::with_manual_front_ends_confirmed)"
    )]
    ManualNotConfirmed { names: String },
    /// The waveform does not fit the AWG (catalog limits).
    #[error("the {waveform} waveform does not fit the {instrument}: {reason}")]
    DoesNotFit {
        waveform: &'static str,
        instrument: String,
        reason: String,
    },
    /// The scope's rate is not a whole multiple of the waveform's.
    #[error(
        "the capture rate {capture_hz} Sa/s is not a whole multiple of the waveform rate \
         {waveform_hz} Sa/s: choose a waveform rate that divides the scope's"
    )]
    RateNotMultiple { capture_hz: f64, waveform_hz: f64 },
    /// The capture is shorter than one repetition.
    #[error(
        "the capture holds {points} points but one repetition needs {needed}: lengthen the \
         scope's record"
    )]
    RecordTooShort { points: usize, needed: usize },
    /// The record the pipeline was built for is shorter than the waveform (a caller bug).
    #[error("the record of {period} samples cannot hold the {waveform}-sample waveform")]
    RecordShorterThanWaveform { period: usize, waveform: usize },
    /// The background capture does not match this one.
    #[error(
        "the background capture holds {background} samples per repetition, this one {capture}: \
         capture the background with the same waveform"
    )]
    BackgroundShape { background: usize, capture: usize },
    /// The waveform could not be made.
    #[error(transparent)]
    Waveform(#[from] crate::waveform::ParamError),
    /// An instrument refused or its link failed.
    #[error(transparent)]
    Driver(#[from] crate::driver::DriverError),
    /// The bench file is unusable.
    #[error(transparent)]
    BenchFile(#[from] bench_file::BenchFileError),
    /// The catalog is unusable.
    #[error(transparent)]
    Catalog(#[from] crate::catalog::CatalogError),
    /// Range processing failed or refused its parameters.
    #[error(transparent)]
    Dsp(#[from] crate::dsp::DspError),
    /// A file could not be read or written.
    #[error(transparent)]
    Storage(#[from] crate::storage::StorageError),
    /// A recording given as input cannot be read.
    #[error(transparent)]
    Recording(#[from] crate::storage::RecordingError),
    /// The built-in mock lab did not start.
    #[error("cannot start the built-in mock lab: {0}")]
    Lab(#[from] mock_lab::lab::LabError),
    /// A scene file for the built-in mock lab is unusable.
    #[error(transparent)]
    Scene(#[from] mock_lab::scene::SceneError),
    /// A resource string in the bench file is unusable.
    #[error("[{section}] resource = {text:?}: {source}")]
    Resource {
        section: &'static str,
        text: String,
        source: crate::address::AddressError,
    },
    /// The capture did not finish while RF was on within its deadline: the bench was put in its
    /// safe state at once.
    #[error(
        "the capture did not finish within {seconds:.0} s of switching RF on (acquisition wait plus \
         fetching at the catalog's slowest rate): RF was switched off at once; check the marker \
         cable and the scope's link, or raise --wait"
    )]
    RfDeadline { seconds: f64 },
    /// A saved capture does not say which waveform it holds.
    #[error(
        "the capture does not say which waveform it holds (radbench did not make it): give \
         --waveform and its parameters, and --seed or --payload for its bits"
    )]
    NeedsWaveform,
    /// A calibration found no echo where the reference target should be.
    #[error(
        "no echo between {from_m:.3} m and {to_m:.3} m (uncalibrated): place the reference target \
         at {from_m} m, check RF is on, or widen --search"
    )]
    NoReferenceEcho { from_m: f64, to_m: f64 },
    /// A response calibration file is unusable (named, with what is wrong).
    #[error("calibration {path}: {reason}")]
    CalibrationFile { path: String, reason: String },
    /// A response calibration was measured but would not help: not stored.
    #[error("{0}")]
    CorrectionRefused(String),
    /// Processing could not run to its end (a worker thread failed).
    #[error("the processing thread failed: {0}; this is a radbench bug, please report it")]
    Worker(String),
    /// The user stopped the measurement (the bench was put in its safe state).
    #[error("interrupted by {}: the bench was put in its safe state ({report})", signal.name())]
    Interrupted {
        signal: interrupt::StopSignal,
        report: String,
    },
}

impl MeasureError {
    /// An option out of range: `--{option} {value}`, and what is allowed.
    pub fn option(option: &'static str, value: impl Display, allowed: impl Into<String>) -> Self {
        MeasureError::Option {
            option,
            value: value.to_string(),
            allowed: allowed.into(),
        }
    }

    /// What to do about it.
    pub fn kind(&self) -> ErrorKind {
        self.classes().0
    }

    /// What to do about it and the exit code it gives: one table for both.
    fn classes(&self) -> (ErrorKind, ExitClass) {
        use ErrorKind::{Abort, FixInput, Retry};
        match self {
            MeasureError::Option { .. }
            | MeasureError::AlgorithmNeedsOfdm { .. }
            | MeasureError::NoPermit { .. }
            | MeasureError::ManualNotConfirmed { .. }
            | MeasureError::DoesNotFit { .. }
            | MeasureError::RateNotMultiple { .. }
            | MeasureError::BackgroundShape { .. }
            | MeasureError::Waveform(_)
            | MeasureError::Scene(_)
            | MeasureError::Resource { .. }
            | MeasureError::CalibrationFile { .. }
            | MeasureError::NeedsWaveform => (FixInput, ExitClass::BadInput),
            MeasureError::BenchFile(e) => (FixInput, e.exit_class()),
            MeasureError::Recording(e) => (FixInput, e.exit_class()),
            MeasureError::CorrectionRefused(_) => (FixInput, ExitClass::Processing),
            MeasureError::Driver(e) => (e.kind(), e.exit_class()),
            MeasureError::RecordTooShort { .. } | MeasureError::RfDeadline { .. } => {
                (Retry, ExitClass::Instrument)
            }
            MeasureError::Lab(_) => (Abort, ExitClass::Instrument),
            MeasureError::Catalog(e) => (Abort, e.exit_class()),
            MeasureError::Dsp(e) => (Abort, e.exit_class()),
            MeasureError::Storage(e) => (Abort, e.exit_class()),
            MeasureError::NoReferenceEcho { .. } => (Abort, ExitClass::Processing),
            MeasureError::RecordShorterThanWaveform { .. } | MeasureError::Worker(_) => {
                (Abort, ExitClass::Internal)
            }
            MeasureError::Interrupted { signal, .. } => (Abort, signal.exit_class()),
        }
    }
}

impl Classify for MeasureError {
    fn exit_class(&self) -> ExitClass {
        self.classes().1
    }
}

impl interrupt::StopSignal {
    /// The exit code of a run this signal stopped.
    pub(crate) fn exit_class(self) -> ExitClass {
        match self {
            interrupt::StopSignal::Interrupt => ExitClass::Interrupted,
            interrupt::StopSignal::Terminate => ExitClass::Terminated,
            interrupt::StopSignal::HangUp => ExitClass::HungUp,
        }
    }
}

/// Runs heavy, synchronous work (DSP, file writing) off the async runtime's workers.
pub(crate) async fn off_runtime<T, F>(work: F) -> Result<T, MeasureError>
where
    F: FnOnce() -> T + Send + 'static,
    T: Send + 'static,
{
    tokio::task::spawn_blocking(work)
        .await
        .map_err(|e| MeasureError::Worker(e.to_string()))
}
