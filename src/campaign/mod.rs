//! Measurement campaigns: spec (TOML) -> plan (plain data, printable) -> run (one connected bench,
//! every step under the safe-state guard) -> run folder (manifest, step captures, `results.json`,
//! report), resumable after an interruption. docs/campaign.md describes the files.
//!
//! | module | what it holds |
//! |---|---|
//! | `spec` | the spec file: serde with unknown fields refused, errors at file:line:field |
//! | [`plan`] | the resolved plan: steps, nominal set-points, noise seeds; dry-run text and estimates |
//! | `kind` | the campaign kinds (the swept parameter): name, unit, what a value sets, metrics and figures, in one table |
//! | `positioner` | who places the targets: the mock lab (in the step's scene), the operator (prompt), a program |
//! | `manifest` | `manifest.toml`: inputs and their SHA-256, plan, identities, steps, files, status |
//! | `manifest_store` | storing the manifest after each step, the step tables copied from the last file, not held in memory |
//! | `results` | `results.json`: each step's measured numbers per algorithm, errors, ground truth; `results.csv`, the same flat |
//! | `run` | executing a plan into a run folder, and resuming one: what callers use |
//! | `folder` | the run folder: its identity, start (created, locked, inputs copied), the copies' checks on resume |
//! | `resume` | continuing an interrupted run: what changed since, the steps whose files broke |
//! | `prepare` | every (waveform, algorithm) prepared before anything is connected |
//! | `runner` | the steps (connect, place, set the simulated scene, capture), settling the worker's steps, the finish |
//! | `retry` | the retry policy: which faults are transient, the wait before each retry, the record of one |
//! | `step_job` | a step's job on the worker: process with every algorithm, write the files, record the step |
//! | `report` | the run's `report.md` and `report.html` (plots inline) |
//! | `builtin` | the campaigns `radbench campaign new` prints, and the thesis' lab chapter |
//! | `worker` | the lower-priority thread that processes and writes steps beside the captures |
//! | `export` | a run folder's arrays for a notebook (`radbench export`): every step's capture, a group each |

pub(crate) mod builtin;
pub(crate) mod export;
mod folder;
pub(crate) mod kind;
pub(crate) mod lab_table;
pub(crate) mod manifest;
mod manifest_store;
pub(crate) mod plan;
pub(crate) mod positioner;
mod prepare;
pub(crate) mod report;
pub(crate) mod results;
mod resume;
pub(crate) mod retry;
pub(crate) mod run;
mod runner;
pub(crate) mod spec;
mod step_job;
mod worker;

pub use builtin::*;
pub use export::*;
pub use lab_table::*;
pub use manifest::*;
pub use manifest_store::ManifestStore;
pub use plan::*;
pub use report::*;
pub use results::*;
pub use retry::RetryRecord;
pub use run::*;

use crate::driver::ErrorKind;
use crate::exit::{Classify, ExitClass};
use crate::measure::MeasureError;
use crate::measure::StopSignal;
use std::path::PathBuf;

pub use plan::Plan;
pub use spec::{SpecError, SpecFile};

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
