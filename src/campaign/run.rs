//! Executing a plan into a run folder, and resuming one.
//!
//! Everything that can be built once is built once: one [`Prepared`] per (waveform, algorithm)
//! before anything is connected (so a campaign that was going to be refused never radiates), one
//! connection to a bench of a bench file for the whole run, the pipelines reused step after step.
//! Each step: connect (see below), place the targets (RF off), set the simulated scene, capture
//! `repetitions` under the safe-state guard; then the step worker (one thread, which holds every
//! pipeline from the start of the run) processes the capture with every algorithm, writes the
//! step's files, hashes them and stores the manifest that records the step (atomic, fsynced)
//! while the next steps are captured. At most two steps wait for the worker; it takes them in
//! order, so manifests reach the disk in step order, and a step's result is reported once the
//! worker is done with it; `results.json` and the report follow at the end. Nothing a capture
//! does depends on an earlier step's processing.
//!
//! Reproducibility on a simulated bench: every step sets the scene's noise seed from the campaign
//! seed and the step, so a resumed run gives the same numbers as an uninterrupted one. The runner
//! asks the lab once for `{"cmd":"seed","seed":N}` (restart the noise generator from N; mock_lab's
//! `set` does the same): a lab that does it keeps one connection for the whole run, the waveform
//! uploaded once, and is reseeded at each step. A lab that refuses (an older mock_lab) cannot
//! replay a step's noise: the built-in one is then started afresh for each step with its step's
//! scene (a new connection and an upload per step); on a bench file's `mock-lab serve` the noise
//! continues from capture to capture and the runner says that a resumed run will differ in it.
//!
//! Stop paths: a stop signal during a capture is handled by the measurement's guard (safe state,
//! then [`MeasureError::Interrupted`]); between steps nothing radiates and the loop checks for a
//! signal before each step; a capture that completed before the signal is kept and written. Every
//! stop writes the manifest with status `interrupted`, the reason and the step to resume at.

use super::folder::FolderIdentity;
use super::manifest::{
    self, CalibrationRecord, FileRecord, InputFile, Instruments, Manifest, Session, Status,
    StepRecord, StepStatus, StepTables, Timing,
};
use super::plan::{BenchInfo, Plan, Step};
use super::positioner::{LineSource, Positioner};
use super::results::{self, AlgorithmOutput, Results, StepResult};
use super::spec::{PositionerKind, SpecFile};
use super::worker::StepWorker;
use super::{io, report, CampaignError};
use crate::catalog::Catalog;
use crate::driver::{Journal, RfPermit};
use crate::exit::Classify;
use crate::measure::bench::{Bench, BenchSource};
use crate::measure::capture::{self, LentPipeline, Measurement, Prepared, Processing, Rig, Taken};
use crate::measure::interrupt::Interrupt;
use crate::measure::record::{self, Provenance};
use crate::measure::scene_control::{Scene, SceneControlError, Target};
use crate::measure::MeasureError;
use crate::storage::atomic::{write_atomic, write_group, GroupWritten};
use serde::Serialize;
use serde_json::json;
use std::collections::{BTreeMap, HashMap, VecDeque};
use std::path::{Path, PathBuf};
use std::sync::{Arc, Mutex};
use std::time::Instant;

/// `results.json` in a run folder.
pub(crate) const RESULTS_FILE: &str = "results.json";
/// The spec's copy in a run folder.
pub(crate) const SPEC_COPY: &str = "spec.toml";
/// The bench file's copy in a run folder.
pub(crate) const BENCH_COPY: &str = "bench.toml";
/// Where the run keeps its copies of the bench file's own instrument files.
pub(crate) const BENCH_CATALOG_COPY: &str = "bench-catalog";
/// Where the run keeps its copy of the response calibration it corrects with.
pub(crate) const CALIBRATION_COPY: &str = "calibration";
/// Each step's own result (the entry of `results.json`), inside the step's folder.
pub(crate) const STEP_RESULT: &str = "result.json";
/// Held (flock) while a process works in the run folder.
const LOCK_FILE: &str = ".radbench.lock";

/// What a caller hears while the campaign runs.
pub trait Observer: Send {
    /// A step is about to be captured: the bench is connected, the targets placed, the scene set.
    fn step_starting(&mut self, _step: &Step, _of: usize, _bench: &Bench) {}
    /// A step is finished: measured now, or (`skipped`) measured by an earlier session.
    fn step_done(&mut self, _done: &StepDone<'_>) {}
    /// Something the user should know (on stderr in the CLI).
    fn note(&mut self, _text: &str) {}
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

/// Starts a new run. Errors before the run folder exists (a plan the instruments cannot play)
/// come back as `Err`; once it exists, every stop is recorded and returned in [`Finished`].
pub async fn start(run: NewRun, observer: &mut dyn Observer) -> Result<Finished, CampaignError> {
    let t_prepare = Instant::now();
    let catalog = run.bench.catalog().map_err(MeasureError::from)?;
    let prepared = prepare_all(&run.plan, &run.bench, &catalog).await?;
    let prepare_s = t_prepare.elapsed().as_secs_f64();
    let t0 = Instant::now();
    let out = run.out.clone();
    if out.exists() {
        let empty = std::fs::read_dir(&out).map_err(io(&out))?.next().is_none();
        if !empty {
            return Err(CampaignError::OutExists { dir: out });
        }
    }
    std::fs::create_dir_all(&out).map_err(io(&out))?;
    let lock = lock(&out)?;
    let now = crate::time::rfc3339_millis(std::time::SystemTime::now());
    write_atomic(&out.join(SPEC_COPY), run.spec.text.as_bytes())?;
    let spec_path = std::path::absolute(&run.spec.path).unwrap_or(run.spec.path.clone());
    let spec_in = InputFile {
        path: spec_path,
        copy: SPEC_COPY.into(),
        sha256: manifest::sha256_bytes(run.spec.text.as_bytes()),
    };
    let bench_in = match &run.plan.bench.file {
        Some(p) => {
            let bytes = std::fs::read(p).map_err(io(p))?;
            write_atomic(&out.join(BENCH_COPY), &bytes)?;
            Some(InputFile {
                path: p.clone(),
                copy: BENCH_COPY.into(),
                sha256: manifest::sha256_bytes(&bytes),
            })
        }
        None => None,
    };
    let bench_catalog = copy_bench_catalog(&out, &run.bench)?;
    let calibration = copy_calibration(&out, &run.plan)?;
    let journal_path = run
        .journal
        .clone()
        .unwrap_or_else(|| PathBuf::from("io-journal.jsonl"));
    let manifest = Manifest {
        format: manifest::FORMAT,
        status: Status::Running,
        reason: None,
        stopped_at_step: None,
        exit_code: None,
        radbench_version: env!("CARGO_PKG_VERSION").into(),
        git_commit: manifest::git_commit(),
        created: now.clone(),
        updated: now.clone(),
        spec: spec_in,
        bench_file: bench_in,
        bench_catalog,
        calibration,
        instruments: None,
        base_scene: None,
        plan: run.plan.clone(),
        sessions: vec![new_session("run", &now, &journal_path)],
        steps: run
            .plan
            .steps
            .iter()
            .map(|s| StepRecord {
                index: s.index,
                status: StepStatus::Pending,
                dir: s.dir_name().into(),
                measured_at: None,
                applied: None,
                files: Vec::new(),
            })
            .collect(),
        files: Vec::new(),
    };
    let mut runner = Runner::new(
        out,
        manifest,
        prepared,
        journal_path,
        run.permit,
        run.interrupt,
        run.input,
        false,
    )?;
    runner.timing.overhead_s += t0.elapsed().as_secs_f64();
    runner.timing.prepare_s = prepare_s;
    runner.started = t_prepare;
    let finished = runner.execute(observer).await;
    drop(lock);
    finished
}

/// Continues an interrupted run in `dir`.
pub async fn resume(
    dir: &Path,
    permit: RfPermit,
    force: bool,
    interrupt: Interrupt,
    input: Option<LineSource>,
    observer: &mut dyn Observer,
) -> Result<Finished, CampaignError> {
    let t0 = Instant::now();
    // A run folder at all? (Before the lock file is created in it.)
    Manifest::load(dir)?;
    let lock = lock(dir)?;
    // A run killed mid-write leaves temporaries behind (the step folders are cleaned when their
    // files are written again).
    crate::storage::atomic::remove_stale_temporaries(dir)?;
    let mut manifest = Manifest::load(dir)?;
    if manifest.status == Status::Complete {
        return Err(CampaignError::Complete {
            dir: dir.to_path_buf(),
        });
    }
    check_spec_unchanged(dir, &manifest)?;
    let mut plan = manifest.plan.clone();
    let mut forced = Vec::new();
    let bench_file = reload_bench_file(&plan, force, &mut forced)?;
    check_bench_catalog(&manifest, bench_file.as_ref(), force, &mut forced)?;
    check_calibration(dir, &manifest, &mut plan, force, &mut forced)?;
    let info = BenchInfo {
        file: plan.bench.file.clone().zip(bench_file.clone()),
        scene: plan.bench.scene.clone(),
        awg_transport: plan.bench.awg_transport,
        scope_transport: plan.bench.scope_transport,
        simulated: plan.bench.simulated,
        tx_attenuation_db: None,
    };
    let catalog = info.catalog().map_err(MeasureError::from)?;
    let t_prepare = Instant::now();
    let prepared = prepare_all(&plan, &info, &catalog).await?;
    let prepare_s = t_prepare.elapsed().as_secs_f64();
    let remeasured = reopen_broken_steps(dir, &mut manifest);
    let n = manifest.sessions.len();
    let journal_path = PathBuf::from(format!("io-journal-resume-{n}.jsonl"));
    let now = crate::time::rfc3339_millis(std::time::SystemTime::now());
    let mut session = new_session("resume", &now, &journal_path);
    session.remeasured = remeasured;
    if !forced.is_empty() {
        session.forced = Some(forced.join("; "));
    }
    manifest.sessions.push(session);
    manifest.status = Status::Running;
    manifest.reason = None;
    manifest.stopped_at_step = None;
    manifest.exit_code = None;
    let mut runner = Runner::new(
        dir.to_path_buf(),
        manifest,
        prepared,
        journal_path,
        permit,
        interrupt,
        input,
        force,
    )?;
    for note in runner.manifest.session_mut().remeasured.clone() {
        observer.note(&note);
    }
    runner.timing.overhead_s += t0.elapsed().as_secs_f64() - prepare_s;
    runner.timing.prepare_s = prepare_s;
    runner.started = t0;
    let finished = runner.execute(observer).await;
    drop(lock);
    finished
}

/// Copies the instrument files of the bench file's `catalog` folder into the run folder
/// (`bench-catalog/`), so the limits the run was planned with stay with its data.
fn copy_bench_catalog(out: &Path, bench: &BenchInfo) -> Result<Vec<InputFile>, CampaignError> {
    let Some(dir) = bench.file.as_ref().and_then(|(_, f)| f.catalog_dir()) else {
        return Ok(Vec::new());
    };
    let files = crate::catalog::folder_files(&dir).map_err(MeasureError::from)?;
    let folder = out.join(BENCH_CATALOG_COPY);
    std::fs::create_dir_all(&folder).map_err(io(&folder))?;
    let mut copied = Vec::with_capacity(files.len());
    for path in files {
        let bytes = std::fs::read(&path).map_err(io(&path))?;
        let copy = Path::new(BENCH_CATALOG_COPY).join(path.file_name().unwrap_or_default());
        write_atomic(&out.join(&copy), &bytes)?;
        copied.push(InputFile {
            path: std::path::absolute(&path).unwrap_or(path),
            copy,
            sha256: manifest::sha256_bytes(&bytes),
        });
    }
    Ok(copied)
}

/// Copies the response calibration the plan corrects with (header and table) into the run
/// folder (`calibration/`), checked against the SHA-256 the plan recorded, so the correction the
/// run was measured with stays with its data.
fn copy_calibration(out: &Path, plan: &Plan) -> Result<Option<CalibrationRecord>, CampaignError> {
    use crate::measure::response::Calibration;
    let Some(used) = plan.correction() else {
        return Ok(None);
    };
    let path = PathBuf::from(&used.calibration);
    let bad = |reason: String| {
        CampaignError::Measure(MeasureError::CalibrationFile {
            path: used.calibration.clone(),
            reason,
        })
    };
    let cal = Calibration::load(&path)?;
    let header = std::fs::read(&path).map_err(io(&path))?;
    if manifest::sha256_bytes(&header) != used.sha256 || cal.sha256 != used.sha256 {
        return Err(bad(
            "it changed since the campaign was planned (SHA-256 differs): run it again".into(),
        ));
    }
    let data = Path::new(&cal.header.data);
    let (Some(name), Some(data_name)) = (path.file_name(), data.file_name()) else {
        return Err(bad("a header file name and a table name are needed".into()));
    };
    if data.components().count() != 1 {
        return Err(bad(format!(
            "its table {} must sit beside the header (data = \"<name>.npy\")",
            cal.header.data
        )));
    }
    let table_path = path.parent().unwrap_or(Path::new(".")).join(data);
    let table = std::fs::read(&table_path).map_err(io(&table_path))?;
    if manifest::sha256_bytes(&table) != cal.header.data_sha256 {
        return Err(bad(format!(
            "its table {} changed since the campaign was planned: run it again",
            table_path.display()
        )));
    }
    let folder = out.join(CALIBRATION_COPY);
    std::fs::create_dir_all(&folder).map_err(io(&folder))?;
    let copy = Path::new(CALIBRATION_COPY).join(name);
    let table_copy = Path::new(CALIBRATION_COPY).join(data_name);
    write_atomic(&out.join(&copy), &header)?;
    write_atomic(&out.join(&table_copy), &table)?;
    Ok(Some(CalibrationRecord {
        mode: used.mode.clone(),
        path,
        copy,
        table_copy,
        sha256: used.sha256.clone(),
        measured_at: used.measured_at.clone(),
    }))
}

/// The run's response calibration must be the one it started with (the same SHA-256, its table
/// intact); a changed, unusable or missing one refuses the resume unless `force`, which is then
/// recorded in `forced`. The processing keeps the run's own calibration either way: forced, it
/// goes on with the copy in the run folder.
fn check_calibration(
    dir: &Path,
    manifest: &Manifest,
    plan: &mut Plan,
    force: bool,
    forced: &mut Vec<String>,
) -> Result<(), CampaignError> {
    use crate::measure::response::Calibration;
    let Some(rec) = &manifest.calibration else {
        return Ok(());
    };
    let what = match Calibration::load(&rec.path) {
        Ok(cal) if cal.sha256 == rec.sha256 => return Ok(()),
        Ok(cal) => format!(
            "the response calibration {} changed since the run started (SHA-256 {}, the run \
             was measured with {}, measured {})",
            rec.path.display(),
            cal.sha256,
            rec.sha256,
            rec.measured_at
        ),
        Err(e) => {
            let why = match e {
                MeasureError::CalibrationFile { reason, .. } => reason,
                other => other.to_string(),
            };
            format!(
                "the response calibration {} the run was measured with (SHA-256 {}) is gone or \
                 unusable: {why}",
                rec.path.display(),
                rec.sha256
            )
        }
    };
    if !force {
        return Err(CampaignError::DifferentBench { what });
    }
    forced.push(format!(
        "{what}; the run goes on with its own copy {}",
        rec.copy.display()
    ));
    let copy = dir.join(&rec.copy);
    let copy = std::path::absolute(&copy).unwrap_or(copy);
    for o in &mut plan.processing {
        if let Some(c) = &mut o.correction {
            c.calibration = copy.display().to_string();
        }
    }
    Ok(())
}

/// The run's copy of its spec must be the one it started with.
fn check_spec_unchanged(dir: &Path, manifest: &Manifest) -> Result<(), CampaignError> {
    let spec_copy = dir.join(&manifest.spec.copy);
    let (_, spec_hash) = manifest::sha256_file(&spec_copy)?;
    if spec_hash != manifest.spec.sha256 {
        return Err(CampaignError::Manifest {
            path: spec_copy,
            message: "changed since the run started (its SHA-256 differs from the manifest's): \
                      the run cannot be continued as planned"
                .into(),
        });
    }
    Ok(())
}

/// The run's bench file, loaded again; a different system delay refuses the resume unless
/// `force`, and is then recorded in `forced`.
fn reload_bench_file(
    plan: &Plan,
    force: bool,
    forced: &mut Vec<String>,
) -> Result<Option<crate::measure::bench_file::BenchFile>, CampaignError> {
    let Some(path) = &plan.bench.file else {
        return Ok(None);
    };
    let file = crate::measure::bench_file::BenchFile::load(path).map_err(MeasureError::from)?;
    let delay = file.system_delay_s();
    if delay != plan.bench.system_delay_s {
        let what = format!(
            "the bench file {} now calibrates a system delay of {:.4} ns; the run was measured \
             with {:.4} ns",
            path.display(),
            delay * 1e9,
            plan.bench.system_delay_s * 1e9
        );
        if !force {
            return Err(CampaignError::DifferentBench { what });
        }
        forced.push(what);
    }
    Ok(Some(file))
}

/// The bench file's instrument files must be those the run was planned with (the same names and
/// contents); a change refuses the resume unless `force`, and is then recorded in `forced`.
fn check_bench_catalog(
    manifest: &Manifest,
    bench_file: Option<&crate::measure::bench_file::BenchFile>,
    force: bool,
    forced: &mut Vec<String>,
) -> Result<(), CampaignError> {
    let name = |p: &Path| {
        p.file_name()
            .unwrap_or_default()
            .to_string_lossy()
            .into_owned()
    };
    let then: Vec<(String, String)> = manifest
        .bench_catalog
        .iter()
        .map(|f| (name(&f.copy), f.sha256.clone()))
        .collect();
    let mut now = Vec::new();
    if let Some(dir) = bench_file.and_then(|f| f.catalog_dir()) {
        for path in crate::catalog::folder_files(&dir).map_err(MeasureError::from)? {
            let bytes = std::fs::read(&path).map_err(io(&path))?;
            now.push((name(&path), manifest::sha256_bytes(&bytes)));
        }
    }
    if then == now {
        return Ok(());
    }
    let what = "the instrument files of the bench file's catalog folder changed since the run \
                started (the copies it was planned with are in bench-catalog/)"
        .to_string();
    if !force {
        return Err(CampaignError::DifferentBench { what });
    }
    forced.push(what);
    Ok(())
}

/// Completed steps are kept only when every file is as it was written; the others are pending
/// again. Returns a note per step reopened.
fn reopen_broken_steps(dir: &Path, manifest: &mut Manifest) -> Vec<String> {
    let mut remeasured = Vec::new();
    for rec in manifest.steps.iter_mut() {
        if rec.status != StepStatus::Done {
            continue;
        }
        let has_result = rec.files.iter().any(|f| f.path.ends_with(STEP_RESULT));
        let broken = rec
            .files
            .iter()
            .find_map(|f| f.check(dir))
            .or_else(|| (!has_result).then(|| format!("{STEP_RESULT} is not recorded")));
        if let Some(why) = broken {
            remeasured.push(format!("step {}: {why}: measured again", rec.index));
            rec.status = StepStatus::Pending;
            rec.files.clear();
            rec.applied = None;
            rec.measured_at = None;
        }
    }
    remeasured
}

fn new_session(kind: &str, now: &str, journal: &Path) -> Session {
    Session {
        kind: kind.into(),
        started: now.into(),
        ended: None,
        journal: journal.to_path_buf(),
        skipped: Vec::new(),
        remeasured: Vec::new(),
        forced: None,
        final_safe_state: None,
        timing: Timing::default(),
    }
}

/// Every (waveform, algorithm) prepared, and for `music_p = "targets"` every (waveform,
/// subspace algorithm, model order) the steps need: transmissions generated, options checked,
/// instrument settings planned against the catalog, pipelines built. Touches no instrument.
pub(crate) struct PreparedSet {
    /// `[waveform][algorithm]`.
    pub base: Vec<Vec<Prepared>>,
    /// `(waveform, algorithm, p)` for the steps' own model orders.
    ordered: Vec<((usize, usize, usize), Prepared)>,
}

impl PreparedSet {
    /// The preparation for waveform `w`, algorithm `a` at a step whose model order is `p`.
    fn get_mut(&mut self, w: usize, a: usize, p: Option<usize>) -> &mut Prepared {
        if let Some(p) = p {
            if let Some(i) = self.ordered.iter().position(|(k, _)| *k == (w, a, p)) {
                return &mut self.ordered[i].1;
            }
        }
        &mut self.base[w][a]
    }
}

/// Prepares everything a plan needs (see [`PreparedSet`]).
pub(crate) async fn prepare_all(
    plan: &Plan,
    bench: &BenchInfo,
    catalog: &Catalog,
) -> Result<PreparedSet, CampaignError> {
    let planning = plan
        .bench
        .planning_bench(bench.file.as_ref().map(|(_, f)| f));
    let mut base = Vec::with_capacity(plan.waveforms.len());
    for w in 0..plan.waveforms.len() {
        let first = capture::prepare(&planning, catalog, &plan.request(w)).await?;
        let mut all = Vec::with_capacity(plan.processing.len());
        for o in &plan.processing[1..] {
            all.push(first.with_options(o.clone()).await?);
        }
        all.insert(0, first);
        base.push(all);
    }
    let mut ordered: Vec<((usize, usize, usize), Prepared)> = Vec::new();
    for step in &plan.steps {
        let Some(p) = step.music_p else { continue };
        for (a, o) in plan.processing.iter().enumerate() {
            let key = (step.waveform, a, p);
            if !o.algorithm.is_subspace() || ordered.iter().any(|(k, _)| *k == key) {
                continue;
            }
            let mut options = o.clone();
            options.music_p = Some(p);
            let prepared = base[step.waveform][0].with_options(options).await?;
            ordered.push((key, prepared));
        }
    }
    Ok(PreparedSet { base, ordered })
}

/// An exclusive lock on the run folder for this process (released when dropped).
struct Lock {
    _file: std::fs::File,
}

fn lock(dir: &Path) -> Result<Lock, CampaignError> {
    use std::os::fd::AsRawFd;
    let path = dir.join(LOCK_FILE);
    let file = std::fs::OpenOptions::new()
        .create(true)
        .truncate(false)
        .write(true)
        .open(&path)
        .map_err(io(&path))?;
    // SAFETY: flock on a file descriptor this function owns; no memory is shared.
    let rc = unsafe { libc::flock(file.as_raw_fd(), libc::LOCK_EX | libc::LOCK_NB) };
    if rc != 0 {
        return Err(CampaignError::Locked {
            dir: dir.to_path_buf(),
        });
    }
    Ok(Lock { _file: file })
}

/// A captured step that the worker processes (every algorithm), writes, hashes and records in
/// the manifest while the next steps are captured.
struct PendingStep {
    k: usize,
    step: Step,
    outcome: tokio::sync::oneshot::Receiver<WorkerOutcome>,
}

/// Most captured steps waiting for (or with) the worker. Two lets a step whose processing and
/// files took longer than one capture catch up during the next one, instead of holding it;
/// more would only hide a worker that cannot keep up, and hold more captures in memory.
const STEPS_IN_FLIGHT: usize = 2;

/// What a step's job reports.
struct WorkerOutcome {
    processing_s: f64,
    done: Result<(StepResult, Written), CampaignError>,
}

/// What only step jobs use, one job at a time in step order: every pipeline of the campaign
/// (lent by the preparations when the run starts) and the records of the steps recorded so far.
#[derive(Default)]
struct WorkerSide {
    pipelines: HashMap<PipelineKey, LentPipeline>,
    /// Steps this session's jobs recorded: a job's manifest holds them all, also those the
    /// runner has not collected yet.
    recorded: BTreeMap<usize, StepRecord>,
    /// The manifest's step tables as last written, so each store serialises only what changed.
    tables: StepTables,
}

/// (waveform, algorithm, model order of the steps that set their own).
type PipelineKey = (usize, usize, Option<usize>);

impl WorkerSide {
    /// Takes every pipeline out of `prepared`.
    fn lend_all(prepared: &mut PreparedSet) -> Result<WorkerSide, MeasureError> {
        let mut side = WorkerSide::default();
        for (w, all) in prepared.base.iter_mut().enumerate() {
            for (a, p) in all.iter_mut().enumerate() {
                side.pipelines.insert((w, a, None), p.lend()?);
            }
        }
        for (&(w, a, p), prep) in prepared.ordered.iter_mut().map(|(k, v)| (&*k, v)) {
            side.pipelines.insert((w, a, Some(p)), prep.lend()?);
        }
        Ok(side)
    }

    /// The key of the pipeline for waveform `w`, algorithm `a` at a step of model order `p`
    /// (as [`PreparedSet`] chooses).
    fn key(&self, w: usize, a: usize, p: Option<usize>) -> PipelineKey {
        match p {
            Some(p) if self.pipelines.contains_key(&(w, a, Some(p))) => (w, a, Some(p)),
            _ => (w, a, None),
        }
    }
}

/// What the writer did for a step.
struct Written {
    /// The step's manifest record, as stored.
    record: StepRecord,
    files_s: f64,
    /// Hashing and storing the manifest.
    overhead_s: f64,
}

/// The connected bench.
struct Connection {
    bench: Bench,
    rig: Rig,
}

struct Runner {
    dir: PathBuf,
    /// The run folder as it was when this session opened it: checked before every write.
    folder: FolderIdentity,
    manifest: Manifest,
    plan: Plan,
    prepared: PreparedSet,
    /// The Tx attenuation each waveform's plan had before any step changed it.
    base_tx_attenuation: Vec<f64>,
    journal: Option<Journal>,
    permit: RfPermit,
    interrupt: Interrupt,
    positioner: Option<Positioner>,
    connection: Option<Connection>,
    /// The scene every step starts from (simulated benches).
    base_scene: Option<Scene>,
    /// Whether the next placement is the first of this session (the targets' position unknown).
    first_placement: bool,
    /// Whether this session has checked the instruments' identities.
    identified: bool,
    /// Whether the simulated lab reseeds its noise on request (`None`: not asked yet).
    reseed: Option<bool>,
    /// Whether the user was told that the noise will not be reproducible.
    warned_noise: bool,
    force: bool,
    results: Vec<Option<StepResult>>,
    /// Processes and writes the steps beside the captures.
    worker: StepWorker,
    worker_side: Arc<Mutex<WorkerSide>>,
    /// The steps handed to the worker and not collected yet, oldest first.
    pending: VecDeque<PendingStep>,
    /// When the session began (before its preparation).
    started: Instant,
    measured: usize,
    skipped: usize,
    timing: Timing,
}

impl Runner {
    #[allow(clippy::too_many_arguments)]
    fn new(
        dir: PathBuf,
        manifest: Manifest,
        mut prepared: PreparedSet,
        journal_path: PathBuf,
        permit: RfPermit,
        interrupt: Interrupt,
        input: Option<LineSource>,
        force: bool,
    ) -> Result<Runner, CampaignError> {
        let plan = manifest.plan.clone();
        let journal_file = if journal_path.is_absolute() {
            journal_path
        } else {
            dir.join(journal_path)
        };
        let journal = Journal::create(&journal_file, false).map_err(|e| CampaignError::Io {
            path: journal_file.clone(),
            source: std::io::Error::other(e.to_string()),
        })?;
        let positioner = plan.positioner.clone().map(|p| Positioner::new(p, input));
        let n = plan.steps.len();
        let worker_side = Arc::new(Mutex::new(WorkerSide::lend_all(&mut prepared)?));
        let worker = StepWorker::start().map_err(|e| CampaignError::Io {
            path: dir.clone(),
            source: e,
        })?;
        let folder = FolderIdentity::of(&dir)?;
        Ok(Runner {
            folder,
            base_tx_attenuation: prepared
                .base
                .iter()
                .map(|p| p[0].plan.tx.attenuation_db)
                .collect(),
            base_scene: plan.bench.scene.clone().or(manifest.base_scene.clone()),
            dir,
            plan,
            manifest,
            prepared,
            journal: Some(journal),
            permit,
            interrupt,
            positioner,
            connection: None,
            first_placement: true,
            identified: false,
            reseed: None,
            warned_noise: false,
            force,
            results: vec![None; n],
            worker,
            worker_side,
            pending: VecDeque::new(),
            started: Instant::now(),
            measured: 0,
            skipped: 0,
            timing: Timing::default(),
        })
    }

    /// Runs every step not done yet, then writes the results, the report and the manifest.
    async fn execute(mut self, observer: &mut dyn Observer) -> Result<Finished, CampaignError> {
        let t = Instant::now();
        self.folder.check(&self.dir)?;
        self.manifest.store(&self.dir)?;
        self.timing.overhead_s += t.elapsed().as_secs_f64();
        let mut stopped = self.steps(observer).await.err();
        // The last steps' files (also when the run stopped: a capture taken is kept).
        if let Err(e) = self.settle_all(observer).await {
            match &stopped {
                None => stopped = Some(e),
                Some(_) => observer.note(&format!("the last step's files: {e}")),
            }
        }
        // Nothing radiates between measurements and every measurement's guard ran the safe
        // state; run it once more on whatever is connected (a bench found in an unknown state
        // and left by an error before its first capture), then close the links.
        let mut safe = true;
        if let Some(conn) = self.connection.take() {
            let report = conn.rig.safe_state().engage().await;
            safe = report.is_safe();
            if !safe {
                observer.note(&format!(
                    "WARNING: the final safe state did not complete: {report}; switch the bench \
                     off by hand"
                ));
            }
            self.manifest.session_mut().final_safe_state = Some(report.to_string());
        }
        let t = Instant::now();
        let outcome = self.finish(stopped).await;
        self.timing.overhead_s += t.elapsed().as_secs_f64();
        outcome.map_err(|e| self.unrecorded(e, safe))
    }

    /// A session's end that could not be written (`results.json`, the report, the manifest: a
    /// read-only file system, a full disk) as the error the user sees: the write that failed,
    /// why the run had stopped, the bench's state and how to go on. The bare write error ("cannot
    /// write results.json") dropped the stop it was to record (the step whose files had failed)
    /// and said nothing of resuming.
    fn unrecorded(&self, e: CampaignError, safe: bool) -> CampaignError {
        if matches!(e, CampaignError::FolderLost { .. }) {
            return e;
        }
        if let Some(lost) = self.folder.lost(&self.dir) {
            return lost;
        }
        CampaignError::Unrecorded {
            dir: self.dir.clone(),
            stopped: self.manifest.reason.clone(),
            safe,
            source: Box::new(e),
        }
    }

    async fn steps(&mut self, observer: &mut dyn Observer) -> Result<(), CampaignError> {
        let n = self.plan.steps.len();
        for k in 0..n {
            let step = self.plan.steps[k].clone();
            if self.manifest.steps[k].status == StepStatus::Done {
                self.settle_all(observer).await?;
                let result = self.stored_result(&step)?;
                self.skipped += 1;
                self.manifest.session_mut().skipped.push(step.index);
                observer.step_done(&StepDone {
                    step: &step,
                    of: n,
                    result: &result,
                    primary: self.plan.algorithm_names()[0],
                    dir: self.dir.join(step.dir_name()),
                    skipped: true,
                });
                self.results[k] = Some(result);
                // The targets may have been moved since: place them again at the next step.
                self.first_placement = true;
                continue;
            }
            if let Some(signal) = self.interrupt.received() {
                return Err(CampaignError::Interrupted {
                    signal,
                    where_: format!("before step {} of {n}; nothing was radiating", step.index),
                });
            }
            self.measure_step(k, &step, observer).await?;
            if let Some(signal) = self.interrupt.received() {
                if k + 1 < n {
                    return Err(CampaignError::Interrupted {
                        signal,
                        where_: format!("after step {} of {n} (its capture is kept)", step.index),
                    });
                }
            }
        }
        Ok(())
    }

    /// A step measured by an earlier session: its stored result.
    fn stored_result(&self, step: &Step) -> Result<StepResult, CampaignError> {
        let path = self.dir.join(step.dir_name()).join(STEP_RESULT);
        let text = std::fs::read_to_string(&path).map_err(io(&path))?;
        serde_json::from_str(&text).map_err(|e| CampaignError::Manifest {
            path,
            message: format!("not a step result: {e}"),
        })
    }

    /// The simulated scene of a step: the base scene with the step's noise seed, SNR and (with
    /// the mock-lab positioner) targets.
    fn step_scene(&self, step: &Step) -> Option<Scene> {
        let mut scene = self.base_scene.clone()?;
        if let Some(seed) = step.noise_seed {
            scene.seed = seed;
        }
        if let Some(snr) = step.nominal.snr_db {
            scene.snr_db = snr;
        }
        let mock = self
            .positioner
            .as_ref()
            .is_some_and(|p| p.kind() == PositionerKind::MockLab);
        if mock && !step.nominal.targets.is_empty() {
            let amplitude = |i: usize| {
                scene
                    .targets
                    .get(i)
                    .or(scene.targets.last())
                    .map_or(0.5, |t| t.amplitude)
            };
            scene.targets = step
                .nominal
                .targets
                .iter()
                .enumerate()
                .map(|(i, t)| Target {
                    range_m: t.range_m,
                    amplitude: amplitude(i),
                    velocity_mps: 0.0,
                })
                .collect();
        }
        Some(scene)
    }

    /// Connects for `step`: a fresh built-in lab with the step's scene, or the bench file's
    /// instruments once.
    async fn connect(&mut self, step: &Step) -> Result<(), CampaignError> {
        let built_in = self.plan.bench.file.is_none();
        if built_in && (self.reseed == Some(false) || self.connection.is_none()) {
            // A fresh lab per step when it cannot reseed its noise (see the module docs). Close
            // the previous lab's links before its servers go.
            self.connection = None;
            let scene = self.step_scene(step).unwrap_or_default();
            let bench = Bench::open(BenchSource::BuiltIn(Box::new(
                self.plan.bench.built_in(scene),
            )))
            .await?;
            let rig = Rig::connect(&bench, &catalog(&bench)?, self.journal.clone()).await?;
            self.connection = Some(Connection { bench, rig });
        } else if self.connection.is_none() {
            let path = self.plan.bench.file.clone().expect("a bench file");
            let bench = Bench::open(BenchSource::File(path)).await?;
            let rig = Rig::connect(&bench, &catalog(&bench)?, self.journal.clone()).await?;
            self.connection = Some(Connection { bench, rig });
        }
        if self.plan.bench.simulated && self.reseed.is_none() {
            // Does the lab reseed its noise on request? (mock_lab's `seed` control request; a lab
            // without it refuses and changes nothing.)
            let conn = self.connection.as_ref().expect("connected");
            let seed = step.noise_seed.unwrap_or(self.plan.seed);
            self.reseed = Some(conn.bench.reseed(seed).await.is_ok());
        }
        if !self.identified {
            self.identified = true;
            let conn = self.connection.as_ref().expect("connected");
            let now = Instruments::from(conn.rig.identities());
            match &self.manifest.instruments {
                None => self.manifest.instruments = Some(now),
                Some(then) if *then == now => {}
                Some(then) => {
                    let what = format!(
                        "the instruments answer differently than when the run was measured \
                         (then: {then:?}; now: {now:?})"
                    );
                    if !self.force {
                        return Err(CampaignError::DifferentBench { what });
                    }
                    let s = self.manifest.session_mut();
                    s.forced = Some(match s.forced.take() {
                        Some(f) => format!("{f}; {what}"),
                        None => what,
                    });
                }
            }
            // A bench file's simulated lab: the scene every step starts from.
            if self.base_scene.is_none() && self.plan.bench.simulated {
                let scene = conn.bench.scene().await.map_err(control)?;
                self.manifest.base_scene = Some(scene.clone());
                self.base_scene = Some(scene);
            }
        }
        Ok(())
    }

    /// Measures step `k` and hands its files to the writer (see [`Runner::settle`]).
    async fn measure_step(
        &mut self,
        k: usize,
        step: &Step,
        observer: &mut dyn Observer,
    ) -> Result<(), CampaignError> {
        let n = self.plan.steps.len();
        let t_bench = Instant::now();
        self.connect(step).await?;
        if self.plan.moves_at(k, self.first_placement) {
            if let Some(p) = self.positioner.as_mut() {
                p.place(&step.nominal.ranges(), step.index, n, &self.interrupt)
                    .await?;
            }
            self.first_placement = false;
        }
        let scene = self.step_scene(step);
        let reseeds = self.reseed == Some(true);
        // A built-in lab started afresh for this step already has its scene.
        let started_with_scene = self.plan.bench.file.is_none() && !reseeds;
        if !reseeds && !started_with_scene && !self.warned_noise {
            self.warned_noise = true;
            observer.note(
                "note: this simulated bench cannot reseed its noise per step (it refused \
                 {\"cmd\":\"seed\"}): a resumed run will differ from an uninterrupted one in \
                 the noise",
            );
        }
        let conn = self.connection.as_mut().expect("connected");
        if let (Some(scene), false) = (scene, started_with_scene) {
            conn.bench.set_scene(&scene).await.map_err(control)?;
            if reseeds {
                conn.bench.reseed(scene.seed).await.map_err(control)?;
            }
        }
        observer.step_starting(step, n, &conn.bench);
        let w = step.waveform;
        let primary = self.prepared.get_mut(w, 0, step.music_p);
        primary.plan.tx.attenuation_db = step
            .nominal
            .tx_attenuation_db
            .unwrap_or(self.base_tx_attenuation[w]);
        let taken = conn
            .rig
            .acquire(
                &conn.bench,
                primary,
                self.plan.repetitions,
                &self.permit,
                &self.interrupt,
            )
            .await
            .map_err(|e| match e {
                MeasureError::Interrupted { signal, report } => CampaignError::Interrupted {
                    signal,
                    where_: format!(
                        "during step {} of {n}, which will be measured again (safe state: \
                         {report})",
                        step.index
                    ),
                },
                other => other.into(),
            })?;
        self.timing.bench_s += t_bench.elapsed().as_secs_f64();
        // The steps before were processed and written while this one was captured: wait for
        // the oldest when the worker has its fill, then hand this step over. A failure of a step
        // before still hands this capture to the worker, so it is written before the run stops.
        let before = if self.pending.len() >= STEPS_IN_FLIGHT {
            self.settle_oldest(observer).await
        } else {
            Ok(())
        };
        self.hand_over(k, step, taken);
        before
    }

    /// Gives `taken` to the worker, which processes it with every algorithm, writes the step's
    /// files, hashes them and stores the manifest recording it.
    fn hand_over(&mut self, k: usize, step: &Step, taken: Taken) {
        let mut snapshot = self.manifest.clone();
        snapshot.session_mut().timing = self.timing.clone();
        let job = StepJob {
            dir: self.dir.clone(),
            folder: self.folder,
            step: step.clone(),
            names: self.plan.algorithm_names(),
            bandwidth_hz: self.plan.waveforms[step.waveform].bandwidth_hz(),
            provenance: Provenance {
                bench_file: self.plan.bench.file.clone(),
                simulated: self.plan.bench.simulated,
            },
        };
        let side = self.worker_side.clone();
        let outcome = self.worker.submit(move || job.run(&side, taken, snapshot));
        self.pending.push_back(PendingStep {
            k,
            step: step.clone(),
            outcome,
        });
    }

    /// Collects every step handed to the worker.
    async fn settle_all(&mut self, observer: &mut dyn Observer) -> Result<(), CampaignError> {
        let mut first_error = None;
        while !self.pending.is_empty() {
            if let Err(e) = self.settle_oldest(observer).await {
                match first_error {
                    None => first_error = Some(e),
                    Some(_) => observer.note(&format!("a later step: {e}")),
                }
            }
        }
        first_error.map_or(Ok(()), Err)
    }

    /// Waits for the oldest step the worker has, records it done and tells the observer.
    async fn settle_oldest(&mut self, observer: &mut dyn Observer) -> Result<(), CampaignError> {
        let Some(p) = self.pending.pop_front() else {
            return Ok(());
        };
        let t = Instant::now();
        let outcome = p.outcome.await.map_err(|_| {
            CampaignError::Measure(MeasureError::Worker(format!(
                "step {}'s processing stopped with a panic",
                p.step.index
            )))
        })?;
        let waited = t.elapsed().as_secs_f64();
        self.timing.wait_s += waited;
        self.timing.processing_s += outcome.processing_s;
        let (result, written) = outcome.done?;
        self.timing.files_s += written.files_s;
        self.timing.overhead_s += written.overhead_s;
        tracing::debug!(
            step = p.step.index,
            processing_s = outcome.processing_s,
            files_s = written.files_s,
            bookkeeping_s = written.overhead_s,
            waited_s = waited,
            "step processed and written"
        );
        *self.manifest.step_mut(p.step.index) = written.record;
        self.measured += 1;
        observer.step_done(&StepDone {
            step: &p.step,
            of: self.plan.steps.len(),
            result: &result,
            primary: self.plan.algorithm_names()[0],
            dir: self.dir.join(p.step.dir_name()),
            skipped: false,
        });
        self.results[p.k] = Some(result);
        Ok(())
    }

    /// `results.json` with every step that has a result, in step order, and `results.csv` from
    /// it.
    fn write_results(&mut self) -> Result<Results, CampaignError> {
        self.folder.check(&self.dir)?;
        let results = Results {
            steps: self.results.iter().flatten().cloned().collect(),
        };
        let path = self.dir.join(RESULTS_FILE);
        write_atomic(&path, format!("{:#}\n", json!(results)).as_bytes())?;
        self.manifest
            .set_file(FileRecord::of(&self.dir, Path::new(RESULTS_FILE))?);
        write_atomic(
            &self.dir.join(results::CSV_FILE),
            results::to_csv(&results).as_bytes(),
        )?;
        self.manifest
            .set_file(FileRecord::of(&self.dir, Path::new(results::CSV_FILE))?);
        Ok(results)
    }

    async fn finish(&mut self, stopped: Option<CampaignError>) -> Result<Finished, CampaignError> {
        let status = if stopped.is_some() {
            Status::Interrupted
        } else {
            Status::Complete
        };
        let first_pending = self
            .manifest
            .steps
            .iter()
            .find(|s| s.status != StepStatus::Done)
            .map(|s| s.index);
        self.manifest.status = status;
        let n = self.plan.steps.len();
        self.manifest.reason = stopped.as_ref().map(|e| match (e, first_pending) {
            (CampaignError::Interrupted { .. }, _) | (_, None) => crate::exit::render_chain(e),
            (_, Some(k)) => format!("step {k} of {n}: {}", crate::exit::render_chain(e)),
        });
        self.manifest.stopped_at_step = stopped.as_ref().and(first_pending);
        self.manifest.exit_code = stopped.as_ref().map(|e| e.exit_class().code());
        // After the reason: should a write fail from here on, the error tells the stop it was
        // to record (see `unrecorded`).
        let results = self.write_results()?;
        let now = crate::time::rfc3339_millis(std::time::SystemTime::now());
        self.manifest.session_mut().ended = Some(now);
        self.timing.total_s = self.started.elapsed().as_secs_f64();
        self.manifest.session_mut().timing = self.timing.clone();
        // The journals are final now: hash them.
        let journals: Vec<PathBuf> = self
            .manifest
            .sessions
            .iter()
            .map(|s| s.journal.clone())
            .filter(|p| p.is_relative())
            .collect();
        if let Some(journal) = self.journal.take() {
            journal.flush();
        }
        for j in journals {
            if self.dir.join(&j).exists() {
                self.manifest.set_file(FileRecord::of(&self.dir, &j)?);
            }
        }
        let report = report::write(&self.dir, &self.manifest, &results)?;
        self.manifest
            .set_file(FileRecord::of(&self.dir, Path::new(report::FILE))?);
        self.manifest
            .set_file(FileRecord::of(&self.dir, Path::new(report::HTML_FILE))?);
        self.folder.check(&self.dir)?;
        self.manifest.store(&self.dir)?;
        let max = |f: fn(&results::AlgorithmResult) -> Option<f64>| {
            results
                .steps
                .iter()
                .flat_map(|s| s.algorithms.values())
                .filter_map(f)
                .map(f64::abs)
                .fold(None, |a: Option<f64>, x| Some(a.map_or(x, |a| a.max(x))))
        };
        let summary = Summary {
            name: self.plan.name.clone(),
            steps: self.plan.steps.len(),
            done: results.steps.len(),
            measured: self.measured,
            skipped: self.skipped,
            algorithms: self.plan.algorithm_names(),
            max_abs_error_m: max(|a| a.error_m),
            max_abs_truth_error_m: max(|a| a.truth_error_m),
            reason: self.manifest.reason.clone(),
            stopped_at_step: self.manifest.stopped_at_step,
            manifest: self.dir.join(manifest::FILE),
            results: self.dir.join(RESULTS_FILE),
            report,
        };
        Ok(Finished {
            dir: self.dir.clone(),
            status,
            summary,
            stopped,
        })
    }
}

/// What a step's worker needs besides the capture and the pipelines.
struct StepJob {
    dir: PathBuf,
    folder: FolderIdentity,
    step: Step,
    names: Vec<&'static str>,
    bandwidth_hz: f64,
    provenance: Provenance,
}

impl StepJob {
    /// Processes the capture with every algorithm's pipeline, writes the step's files and
    /// stores the manifest `snapshot` with this step and every step recorded before it done.
    fn run(self, side: &Mutex<WorkerSide>, taken: Taken, snapshot: Manifest) -> WorkerOutcome {
        let mut side = side.lock().unwrap_or_else(|p| p.into_inner());
        let t = Instant::now();
        let w = self.step.waveform;
        let processed: Result<Vec<Processing>, MeasureError> = (0..self.names.len())
            .map(|a| {
                let key = side.key(w, a, self.step.music_p);
                let pipeline = side.pipelines.get_mut(&key).ok_or_else(|| {
                    MeasureError::Worker("an earlier step lost the pipeline".into())
                })?;
                pipeline.process(&taken.captured)
            })
            .collect();
        let processing_s = t.elapsed().as_secs_f64();
        let done = processed.map_err(CampaignError::from).and_then(|p| {
            let side = &mut *side;
            self.record(taken, p, snapshot, &side.recorded, &mut side.tables)
        });
        if let Ok((_, written)) = &done {
            side.recorded
                .insert(written.record.index, written.record.clone());
        }
        WorkerOutcome { processing_s, done }
    }

    fn record(
        self,
        taken: Taken,
        mut processings: Vec<Processing>,
        mut snapshot: Manifest,
        recorded: &BTreeMap<usize, StepRecord>,
        tables: &mut StepTables,
    ) -> Result<(StepResult, Written), CampaignError> {
        let mut others = processings.split_off(1);
        let mut m = taken.with(processings.pop().expect("the primary algorithm"));
        let result = {
            let mut outputs = vec![AlgorithmOutput {
                name: self.names[0],
                processed: &m.processing.processed,
                spread: m.processing.spread.as_ref(),
            }];
            for (o, name) in others.iter().zip(&self.names[1..]) {
                outputs.push(AlgorithmOutput {
                    name,
                    processed: &o.processed,
                    spread: o.spread.as_ref(),
                });
            }
            results::step_result(
                &self.step,
                self.bandwidth_hz,
                m.taken.captured.repetitions(),
                m.taken.ground_truth.as_ref(),
                &outputs,
            )
        };
        let applied = serde_json::to_value(&m.taken.captured.applied)
            .ok()
            .as_ref()
            .and_then(manifest::json_to_toml);
        let result_json = format!("{:#}\n", json!(result));
        let rel = PathBuf::from(self.step.dir_name());
        let t_files = Instant::now();
        self.folder.check(&self.dir)?;
        let files = write_step_files(
            &self.dir,
            &rel,
            &mut m,
            &mut others,
            &self.names,
            &self.provenance,
            &result_json,
        )
        .map_err(|e| self.folder.lost(&self.dir).unwrap_or(e))?;
        // The files were hashed as they were written: that share of their time is the
        // campaign's bookkeeping (a lone `radbench capture` does not hash its files).
        let files_s = t_files.elapsed().as_secs_f64() - files.hashing_s;
        let t_over = Instant::now();
        let records: Vec<FileRecord> = files
            .files
            .into_iter()
            .map(|f| FileRecord {
                path: f
                    .path
                    .strip_prefix(&self.dir)
                    .map(Path::to_path_buf)
                    .unwrap_or(f.path),
                bytes: f.bytes,
                sha256: f.sha256,
            })
            .collect();
        for (&index, record) in recorded {
            *snapshot.step_mut(index) = record.clone();
        }
        let rec = snapshot.step_mut(self.step.index);
        rec.status = StepStatus::Done;
        rec.measured_at = Some(crate::time::rfc3339_millis(std::time::SystemTime::now()));
        rec.applied = applied;
        rec.files = records;
        let record = rec.clone();
        self.folder.check(&self.dir)?;
        snapshot
            .store_cached(&self.dir, tables)
            .map_err(|e| self.folder.lost(&self.dir).unwrap_or(e))?;
        let written = Written {
            record,
            files_s,
            overhead_s: t_over.elapsed().as_secs_f64() + files.hashing_s,
        };
        Ok((result, written))
    }
}

/// A refusal of the simulated bench's scene control, as the campaign's error.
fn control(e: SceneControlError) -> CampaignError {
    CampaignError::Control(e.to_string())
}

fn catalog(bench: &Bench) -> Result<Catalog, CampaignError> {
    Ok(bench.file.catalog().map_err(MeasureError::from)?)
}

/// Writes a step's files: the raw capture and the primary algorithm's profiles in the step's
/// folder, each further algorithm's profiles in a subfolder named after it, the step's result.
/// They become durable together (one write group: hashed as written, synced and renamed at the
/// end, each folder synced once); the manifest that names them is written only afterwards.
fn write_step_files(
    dir: &Path,
    rel: &Path,
    m: &mut Measurement,
    others: &mut [Processing],
    names: &[&'static str],
    provenance: &Provenance,
    result_json: &str,
) -> Result<GroupWritten, CampaignError> {
    let out = dir.join(rel);
    // The step's folder alone (not its parents): should the run folder vanish after the check,
    // this fails rather than re-create it.
    match std::fs::create_dir(&out) {
        Ok(()) => {}
        Err(e) if e.kind() == std::io::ErrorKind::AlreadyExists => {}
        Err(e) => return Err(io(&out)(e)),
    }
    let ((), written) = write_group(|| {
        let raw = record::write_raw(&out, &m.taken, &m.processing.options, provenance)?;
        record::write_processed(&out, m, &raw, provenance)?;
        for (p, name) in others.iter_mut().zip(&names[1..]) {
            swap_processing(m, p);
            let written = record::write_processed(&out.join(name), m, &raw, provenance);
            swap_processing(m, p);
            written?;
        }
        write_atomic(&out.join(STEP_RESULT), result_json.as_bytes())?;
        Ok::<_, CampaignError>(())
    })?;
    Ok(written)
}

/// Exchanges a measurement's processing with another algorithm's (to write that one's files).
fn swap_processing(m: &mut Measurement, p: &mut Processing) {
    std::mem::swap(&mut m.processing, p);
}

/// The error class of a finished run's stop, for the exit code.
pub fn exit_code(finished: &Finished) -> i32 {
    finished
        .stopped
        .as_ref()
        .map_or(0, |e| e.exit_class().code())
}
