//! Continuing an interrupted run: the folder locked again, its inputs checked against those it
//! started with (a change refuses the resume unless forced, and the manifest records it), the
//! steps whose files are no longer as written measured again, the rest skipped.

use super::error::CampaignError;
use super::folder::lock;
use super::inputs::{check_bench_catalog, check_calibration, check_spec_unchanged};
use super::manifest::{Manifest, Status, StepStatus};
use super::plan::{BenchInfo, Plan};
use super::positioner::LineSource;
use super::prepare::prepare_all;
use super::run::{Finished, Observer, STEP_RESULT};
use super::runner::{new_session, Runner};
use crate::driver::RfPermit;
use crate::measure::Interrupt;
use crate::measure::MeasureError;
use std::path::{Path, PathBuf};
use std::time::Instant;

/// Continues an interrupted run in `dir`; `retries`, when given, replaces the plan's `[run]
/// retries` from now on (as `campaign run --retries` sets it).
pub async fn resume(
    dir: &Path,
    permit: RfPermit,
    force: bool,
    retries: Option<usize>,
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
    if let Some(n) = retries {
        manifest.plan.retries = n;
    }
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
        scope_model: plan.bench.scope_model,
        simulated: plan.bench.simulated,
        tx_attenuation_db: None,
        rx_attenuation_db: None,
        awg_amplitude_vpp: None,
        volts_per_div: None,
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

/// The run's bench file, loaded again; a different system delay refuses the resume unless
/// `force`, and is then recorded in `forced`.
fn reload_bench_file(
    plan: &Plan,
    force: bool,
    forced: &mut Vec<String>,
) -> Result<Option<crate::measure::BenchFile>, CampaignError> {
    let Some(path) = &plan.bench.file else {
        return Ok(None);
    };
    let file = crate::measure::BenchFile::load(path).map_err(MeasureError::from)?;
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
