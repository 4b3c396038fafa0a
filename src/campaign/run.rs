//! Executing a plan into a run folder, and resuming one: what callers use. The executor lives in
//! rooms beside this one:
//!
//! | module | what it holds |
//! |---|---|
//! | `start` | a new run: the folder created and locked, the inputs copied, the steps run |
//! | `folder` | the run folder: its identity and its lock |
//! | `inputs` | the run's inputs: copied in at the start, checked on resume |
//! | `resume` | continuing an interrupted run: what changed since, the steps whose files broke |
//! | `prepare` | every (waveform, algorithm) prepared before anything is connected |
//! | `runner` | the steps (connect, place, set the simulated scene, capture), settling the worker's steps, the finish |
//! | `step_job` | a step's job on the worker: process with every algorithm, write the files, record the step |
//!
//! Everything that can be built once is built once: one [`Prepared`](crate::measure::Prepared)
//! per (waveform, algorithm) before anything is connected (so a campaign that was going to be
//! refused never radiates), one connection to a bench of a bench file for the whole run, the
//! pipelines reused step after step. Each step: connect (see below), place the targets (RF off),
//! set the simulated scene, capture `repetitions` under the safe-state guard; then the step worker
//! (one thread, which holds every pipeline from the start of the run) processes the capture with
//! every algorithm, writes the step's files, hashes them and stores the manifest that records the
//! step (atomic, fsynced) while the next steps are captured. At most two steps wait for the
//! worker; it takes them in order, so manifests reach the disk in step order, and a step's result
//! is reported once the worker is done with it; `results.json` and the report follow at the end.
//! Nothing a capture does depends on an earlier step's processing.
//!
//! Reproducibility on a simulated bench: every step sets the scene's noise seed from the campaign
//! seed and the step, so a resumed run gives the same numbers as an uninterrupted one. The runner
//! asks the bench once to reseed its noise (restart the noise generator from N; setting the scene
//! does the same): a lab that does it keeps one connection for the whole run, the waveform
//! uploaded once, and is reseeded at each step. A lab that refuses (an older mock_lab) cannot
//! replay a step's noise: the built-in one is then started afresh for each step with its step's
//! scene (a new connection and an upload per step); on a bench file's `mock-lab serve` the noise
//! continues from capture to capture and the runner says that a resumed run will differ in it.
//!
//! Stop paths: a stop signal during a capture is handled by the measurement's guard (safe state,
//! then [`MeasureError::Interrupted`](crate::measure::MeasureError::Interrupted)); between steps
//! nothing radiates and the loop checks for a signal before each step; a capture that completed
//! before the signal is kept and written. Every stop writes the manifest with status
//! `interrupted`, the reason and the step to resume at.

use super::error::CampaignError;
use super::manifest::Status;
use super::plan::{BenchInfo, Plan, Step};
use super::positioner::LineSource;
use super::results::StepResult;
use super::retry::RetryRecord;
use super::spec::SpecFile;
use crate::driver::RfPermit;
use crate::exit::Classify;
use crate::measure::Bench;
use crate::measure::Interrupt;
use serde::Serialize;
use std::path::PathBuf;

/// `results.json` in a run folder.
pub(crate) const RESULTS_FILE: &str = "results.json";
/// Each step's own result (the entry of `results.json`), inside the step's folder.
pub(crate) const STEP_RESULT: &str = "result.json";

/// What a caller hears while the campaign runs.
pub trait Observer: Send {
    /// A step is about to be captured: the bench is connected, the targets placed, the scene set.
    fn step_starting(&mut self, _step: &Step, _of: usize, _bench: &Bench) {}
    /// A step is finished: measured now, or (`skipped`) measured by an earlier session.
    fn step_done(&mut self, _done: &StepDone<'_>) {}
    /// Something the user should know (on stderr in the CLI).
    fn note(&mut self, _text: &str) {}
    /// A step met a transient fault and is about to be measured again (the bench already in its
    /// safe state, the wait not passed yet). By default told as a note (`text`).
    fn retrying(&mut self, retry: &Retrying<'_>) {
        self.note(retry.text);
    }
}

/// A retry of a step, as it begins.
pub struct Retrying<'a> {
    /// What the manifest records of it.
    pub record: &'a RetryRecord,
    /// The plan's steps.
    pub of: usize,
    /// The most retries of one step (`[run] retries`, `--retries`).
    pub retries: usize,
    /// The same in a line, as told on stderr.
    pub text: &'a str,
}

/// An observer that hears nothing.
pub struct Quiet;
impl Observer for Quiet {}

/// One finished step.
pub struct StepDone<'a> {
    pub step: &'a Step,
    pub of: usize,
    pub result: &'a StepResult,
    /// The primary algorithm (whose files sit in the step folder).
    pub primary: &'static str,
    /// The step's folder.
    pub dir: PathBuf,
    pub skipped: bool,
}

/// How a run ended.
pub struct Finished {
    pub dir: PathBuf,
    pub status: Status,
    pub summary: Summary,
    /// Why it stopped early (the manifest says the same); `None` when complete.
    pub stopped: Option<CampaignError>,
}

/// The `summary` of the CLI's last JSON line.
#[derive(Debug, Clone, Serialize)]
pub struct Summary {
    pub name: String,
    pub steps: usize,
    /// Steps with results (measured in this session or before).
    pub done: usize,
    /// Steps measured by this session.
    pub measured: usize,
    /// Steps a resume skipped (already measured, files intact).
    pub skipped: usize,
    pub algorithms: Vec<&'static str>,
    /// Largest |measured - nominal| over every step and algorithm, metres.
    pub max_abs_error_m: Option<f64>,
    /// Largest |measured - ground truth| (simulated benches), metres.
    pub max_abs_truth_error_m: Option<f64>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub reason: Option<String>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub stopped_at_step: Option<usize>,
    pub manifest: PathBuf,
    pub results: PathBuf,
    pub report: PathBuf,
}

/// Everything a new run needs.
pub struct NewRun {
    pub spec: SpecFile,
    pub bench: BenchInfo,
    pub plan: Plan,
    /// The run folder (created; must be empty or absent).
    pub out: PathBuf,
    /// The I/O journal (default: `io-journal.jsonl` in the run folder).
    pub journal: Option<PathBuf>,
    pub permit: RfPermit,
    pub interrupt: Interrupt,
    /// The operator's input for the prompt positioner (standard input when `None`).
    pub input: Option<LineSource>,
}

/// The error class of a finished run's stop, for the exit code.
pub fn exit_code(finished: &Finished) -> i32 {
    finished
        .stopped
        .as_ref()
        .map_or(0, |e| e.exit_class().code())
}
