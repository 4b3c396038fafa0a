//! Why a measurement failed ([`MeasureError`]), what to do about it and its exit code. In a file
//! of its own so that the measure modules get it from a sibling, not from their parent.

use super::bench::{bench_file, interrupt};
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
