//! Starting a new run: the folder created empty and locked, the inputs copied in, the manifest
//! written, the steps run.

use super::error::{io, CampaignError};
use super::folder::lock;
use super::inputs::{copy_bench_catalog, copy_calibration, BENCH_COPY, SPEC_COPY};
use super::manifest::{self, InputFile, Manifest, Status, StepRecord, StepStatus};
use super::prepare::prepare_all;
use super::run::{Finished, NewRun, Observer};
use super::runner::{new_session, Runner};
use crate::measure::MeasureError;
use crate::storage::write_atomic;
use std::path::PathBuf;
use std::time::Instant;

/// Starts a new run. Errors before the run folder exists (a plan the instruments cannot play)
/// come back as `Err`; once it exists, every stop is recorded and returned in [`Finished`].
pub async fn start(run: NewRun, observer: &mut dyn Observer) -> Result<Finished, CampaignError> {
    let t_prepare = Instant::now();
    let catalog = run.bench.catalog().map_err(MeasureError::from)?;
    let prepared = prepare_all(&run.plan, &run.bench, &catalog).await?;
    let prepare_s = t_prepare.elapsed().as_secs_f64();
    let t0 = Instant::now();
    let out = run.out.clone();
    // Refused before anything is created or connected when the run cannot fit.
    let needed = run.plan.estimate_bytes_from(0, &prepared.costs());
    let when = format!("for its {} steps", run.plan.steps.len());
    if let Some(w) = super::disk::check(&out, needed, &when, super::disk::MARGIN_BYTES)? {
        observer.note(&w);
    }
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
        operator: Some(manifest::operator(run.plan.operator.as_deref())),
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
        retries: Vec::new(),
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
