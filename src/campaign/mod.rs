//! Measurement campaigns: spec (TOML) -> plan (plain data, printable) -> run (one connected bench,
//! every step under the safe-state guard) -> run folder (manifest, step captures, `results.json`,
//! report), resumable after an interruption. docs/campaign.md describes the files.
//!
//! | module | what it holds |
//! |---|---|
//! | `spec_error` | why a spec cannot be used, at its file, line and field |
//! | `spec` | the spec file: serde with unknown fields refused, errors at file:line:field |
//! | [`plan`] | the resolved plan: steps, nominal set-points, noise seeds; dry-run text and estimates |
//! | `axis` | what a sweep moves, as plain data: the kind, a setting's value |
//! | `nominal` | a step's set-points (plain data) |
//! | `kind` | the campaign kinds (the swept parameter): name, unit, what a value sets, metrics and figures, in one table; and the table of every setting a step can set (sweep axes, `[[steps]]` keys) |
//! | `positioner` | who places the targets: the mock lab (in the step's scene), the operator (prompt), a program |
//! | `manifest` | `manifest.toml`: inputs and their SHA-256, plan, identities, steps, files, status |
//! | `manifest_store` | the manifest stored whole at a session's start and end, each step in between appended to its step journal (a cost per step that does not grow with the run), the step tables not held in memory |
//! | `results` | `results.json`: each step's measured numbers per algorithm, errors, ground truth; `results.csv`, the same flat |
//! | `run` | executing a plan into a run folder, and resuming one: what callers use |
//! | `start` | a new run: the folder created and locked, the inputs copied, the steps run |
//! | `folder` | the run folder: its identity and its lock |
//! | `inputs` | the run's inputs: copied in at the start, checked on resume |
//! | `resume` | continuing an interrupted run: what changed since, the steps whose files broke |
//! | `prepare` | every (waveform, algorithm) prepared before anything is connected |
//! | `runner` | the steps (connect, place, set the simulated scene, capture), settling the worker's steps, the finish |
//! | `retry` | the retry policy: which faults are transient, the wait before each retry, the record of one |
//! | `step_job` | a step's job on the worker: process with every algorithm, write the files, record the step |
//! | `report` | the run's `report.md` and `report.html` (plots inline) |
//! | `builtin` | the campaigns `radbench campaign new` prints, and the thesis' lab chapter |
//! | `worker` | the lower-priority thread that processes and writes steps beside the captures |
//! | [`disk`] | the disk budget: each step's bytes estimated, the free space probed, checked at the start and before each step |
//! | [`notify`] | telling someone: a bounded, logged program run when a run ends |
//! | `export` | a run folder's arrays for a notebook (`radbench export`): every step's capture, a group each |
//! | `error` | why a campaign could not start or stopped, what to do about it and its exit code |

pub(crate) mod axis;
pub(crate) mod builtin;
pub mod disk;
mod error;
pub(crate) mod export;
mod folder;
mod inputs;
pub(crate) mod kind;
pub(crate) mod lab_table;
pub(crate) mod manifest;
mod manifest_store;
pub(crate) mod nominal;
pub mod notify;
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
mod spec_error;
mod start;
mod step_job;
mod worker;

pub use builtin::{kinds, template, thesis_lab, LabChain, LabRow};
pub use error::CampaignError;
pub use export::{export_run, put_all, RunExported};
pub use lab_table::lab_table;
pub use manifest::{
    CalibrationRecord, FileRecord, InputFile, Instruments, JournalLine, Manifest, Session, Status,
    StepRecord, StepStatus, Timing, MANIFEST_FILE, STEPS_JOURNAL,
};
pub use manifest_store::ManifestStore;
pub use plan::{
    plan, BenchInfo, BenchPlan, Nominal, PositionerPlan, Range, Step, WaveformCost, MAX_RETRIES,
};
pub use prepare::prepare_all;
pub use report::{
    figures, load_results, rewrite, step_profiles, svg, theory, wilson95, write, Chart, Figure,
    HLine, Point, Series, Style, HTML_FILE,
};
pub use results::{
    AlgorithmResult, ChainEchoResult, MeanStd, PayloadFigures, Results, SpreadFigures, StepResult,
    TargetResult, Truth,
};
pub use resume::resume;
pub use retry::RetryRecord;
pub use run::{exit_code, Finished, NewRun, Observer, Quiet, Retrying, StepDone, Summary};
pub use start::start;

pub use axis::{AxisSetting, AxisValue};
pub use plan::Plan;
pub use spec::{SpecError, SpecFile};
