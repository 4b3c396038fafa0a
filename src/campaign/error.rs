//! Why a campaign could not start, or stopped ([`CampaignError`]), what to do about it and its
//! exit code. In a file of its own so that the campaign modules get it from a sibling, not from
//! their parent.

use super::spec_error::SpecError;
use crate::driver::ErrorKind;
use crate::exit::{Classify, ExitClass};
use crate::measure::MeasureError;
use crate::measure::StopSignal;
use std::path::PathBuf;

/// Why a campaign could not start, or stopped.
#[derive(Debug, thiserror::Error)]
pub enum CampaignError {
    /// The spec is unusable (file, line, field, what is allowed).
    #[error(transparent)]
    Spec(#[from] SpecError),
    /// A measurement failed (an instrument, a link, the processing).
    #[error(transparent)]
    Measure(#[from] MeasureError),
    /// The positioner program could not be started (the spec names something that is not there).
    #[error(
        "positioner: cannot run {program:?}: {source}; check `positioner.program` (a path relative \
         to the spec's folder, or a program on PATH)"
    )]
    PositionerStart {
        program: String,
        #[source]
        source: std::io::Error,
    },
    /// The positioner program failed or timed out: the targets are not where the step needs them.
    #[error(
        "positioner: {program} {reason}; the campaign stopped with the bench in its safe state"
    )]
    PositionerFailed { program: String, reason: String },
    /// The operator ended the prompt (end of input, or `q`).
    #[error("the operator stopped the campaign at the positioner prompt ({why})")]
    OperatorStopped { why: String },
    /// A stop signal arrived between measurements.
    #[error("interrupted by {}: {where_}", signal.name())]
    Interrupted { signal: StopSignal, where_: String },
    /// The simulated bench's control channel refused or did not answer.
    #[error("the simulated bench's scene control channel: {0}")]
    Control(String),
    /// A file of the run folder could not be read or written.
    #[error("{path}: {source}{}", io_remedy(source))]
    Io {
        path: PathBuf,
        #[source]
        source: std::io::Error,
    },
    /// A storage writer failed.
    #[error(transparent)]
    Storage(#[from] crate::storage::StorageError),
    /// The run folder was moved, deleted or replaced while the campaign ran.
    #[error(
        "the run folder {dir} was {what} while the campaign ran: the run stopped with the bench in \
         its safe state and wrote nothing more (radbench does not re-create it). Resume it where \
         it is now with `radbench campaign resume DIR`, or start a new run"
    )]
    FolderLost { dir: PathBuf, what: &'static str },
    /// The session's end (`results.json`, the report, the manifest) could not be written in the
    /// run folder: a read-only file system, a full disk. The run stopped (or had measured every
    /// step); the manifest on disk records the steps written completely before.
    #[error(
        "{dir}: the run could not write its end there: {source}. {}{} The manifest in the folder \
         records every step written completely before. Once the folder can be written again, \
         continue with `radbench campaign resume {dir} --allow-rf`: it measures only what is \
         missing",
        stop_text(stopped),
        bench_text(*safe)
    )]
    Unrecorded {
        dir: PathBuf,
        /// Why the run had stopped before its end was written (the manifest's reason), if it had.
        stopped: Option<String>,
        /// Whether the final safe state completed.
        safe: bool,
        #[source]
        source: Box<CampaignError>,
    },
    /// The output folder already holds something.
    #[error(
        "{dir} already exists and is not empty: choose another --out, or continue that run with \
         `radbench campaign resume {dir}`"
    )]
    OutExists { dir: PathBuf },
    /// The run folder's manifest cannot be used.
    #[error("{path}: {message}")]
    Manifest { path: PathBuf, message: String },
    /// Another radbench process works in this run folder.
    #[error("{dir} is in use by another radbench process (its lock file is held)")]
    Locked { dir: PathBuf },
    /// Resume found another bench than the run was measured on.
    #[error("{what}; pass --force to continue on this bench anyway (the manifest records it)")]
    DifferentBench { what: String },
    /// The run is already complete.
    #[error("{dir}: the run is complete; nothing to resume")]
    Complete { dir: PathBuf },
    /// Too little free space where the run writes.
    #[error(
        "{dir}: {free} free, the run needs about {needed} {when}; free some space (or thin the \
         output: [output] in the spec, docs/campaign.md \"Disk budget\") and run again \
         (`radbench campaign resume DIR --allow-rf` continues a started run)"
    )]
    DiskFull {
        dir: PathBuf,
        free: String,
        needed: String,
        when: String,
    },
}

impl CampaignError {
    /// What to do about it.
    pub fn kind(&self) -> ErrorKind {
        self.classes().0
    }

    /// What to do about it and the exit code it gives: one table for both.
    fn classes(&self) -> (ErrorKind, ExitClass) {
        use ErrorKind::{Abort, FixInput, Retry};
        match self {
            CampaignError::Measure(e) => (e.kind(), e.exit_class()),
            CampaignError::Spec(e) => (FixInput, e.exit_class()),
            CampaignError::Storage(e) => (Abort, e.exit_class()),
            CampaignError::PositionerStart { .. }
            | CampaignError::OutExists { .. }
            | CampaignError::Manifest { .. }
            | CampaignError::DifferentBench { .. }
            | CampaignError::Complete { .. } => (FixInput, ExitClass::BadInput),
            CampaignError::Locked { .. } => (Retry, ExitClass::BadInput),
            CampaignError::PositionerFailed { .. } | CampaignError::Control(_) => {
                (Retry, ExitClass::Instrument)
            }
            CampaignError::Io { .. }
            | CampaignError::FolderLost { .. }
            | CampaignError::DiskFull { .. }
            | CampaignError::Unrecorded { .. } => (Abort, ExitClass::Processing),
            CampaignError::OperatorStopped { .. } => (Abort, ExitClass::Interrupted),
            CampaignError::Interrupted { signal, .. } => (Abort, signal.exit_class()),
        }
    }

    /// The stop signal behind this error, when there is one.
    pub fn signal(&self) -> Option<StopSignal> {
        match self {
            CampaignError::Interrupted { signal, .. } => Some(*signal),
            CampaignError::Measure(MeasureError::Interrupted { signal, .. }) => Some(*signal),
            _ => None,
        }
    }
}

impl Classify for CampaignError {
    fn exit_class(&self) -> ExitClass {
        self.classes().1
    }
}

/// How [`CampaignError::Unrecorded`] tells the stop it was to record.
fn stop_text(stopped: &Option<String>) -> String {
    match stopped {
        Some(reason) => format!("The run had stopped: {reason}. "),
        None => "Every step had been measured. ".into(),
    }
}

/// How [`CampaignError::Unrecorded`] tells the bench's state.
fn bench_text(safe: bool) -> &'static str {
    if safe {
        "The bench is in its safe state."
    } else {
        "The final safe state did not complete: switch the bench off by hand."
    }
}

/// " (what to do)" after an I/O error that says it by itself (read-only, disk full); nothing
/// after others (this error is also a read's).
fn io_remedy(e: &std::io::Error) -> String {
    crate::storage::full_or_read_only(e).map_or(String::new(), |r| format!(" ({r})"))
}

/// An I/O error on `path`.
pub(crate) fn io(path: impl Into<PathBuf>) -> impl FnOnce(std::io::Error) -> CampaignError {
    let path = path.into();
    move |source| CampaignError::Io { path, source }
}
