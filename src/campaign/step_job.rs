//! A step's job on the worker thread: process the capture with every algorithm's pipeline, write
//! the step's files (one write group), hash them and record the step in the manifest's step
//! journal (`manifest_store`).

use super::error::{io, CampaignError};
use super::folder::FolderIdentity;
use super::manifest::{self, FileRecord, JournalLine, StepRecord, StepStatus, Timing};
use super::manifest_store::ManifestStore;
use super::plan::Step;
use super::prepare::{PreparedKey, PreparedSet};
use super::results::{self, AlgorithmOutput, StepResult};
use super::run::STEP_RESULT;
use super::spec::OutputSection;
use crate::measure::capture::{LentPipeline, Measurement, Processing, Taken};
use crate::measure::processing::ranging::{PhaseRanged, Previous};
use crate::measure::records::record::Provenance;
use crate::measure::records::recorder::Recorder;
use crate::measure::Detection;
use crate::measure::MeasureError;
use crate::storage::{write_atomic, write_group, GroupWritten};
use serde_json::json;
use std::collections::HashMap;
use std::path::{Path, PathBuf};
use std::sync::Mutex;
use std::time::Instant;

/// What a step's job reports.
pub(super) struct WorkerOutcome {
    pub(super) processing_s: f64,
    pub(super) done: Result<(StepResult, Written), CampaignError>,
}

/// What only step jobs use, one job at a time in step order: every pipeline of the campaign
/// (lent by the preparations when the run starts) and the manifest's store, which holds where
/// every step's table lies in the manifest last written (also the steps the runner has not
/// collected yet). The runner stores the manifest through it too, before the first step and at
/// the end, when no job runs.
#[derive(Default)]
pub(super) struct WorkerSide {
    pipelines: HashMap<PipelineKey, LentPipeline>,
    pub(super) store: ManifestStore,
    /// Per pipeline, the last step it processed: where its targets were set, and each one's
    /// phase range and uncertainty where it had one (`--ranging phase` unwraps the next step's
    /// against it). Empty after a resume: the first step resumed unwraps by its envelope.
    last_step: HashMap<PipelineKey, Vec<SetAndRanged>>,
}

/// As [`PreparedKey`].
type PipelineKey = PreparedKey;

/// Where a step set a target, m, and its phase range when it had one.
type SetAndRanged = (f64, Option<PhaseRanged>);

impl WorkerSide {
    /// Takes every pipeline out of `prepared`.
    pub(super) fn lend_all(prepared: &mut PreparedSet) -> Result<WorkerSide, MeasureError> {
        let mut side = WorkerSide::default();
        for (w, all) in prepared.base.iter_mut().enumerate() {
            for (a, p) in all.iter_mut().enumerate() {
                side.pipelines.insert((w, 0, a, None), p.lend()?);
            }
        }
        for (key, prep) in prepared.more.iter_mut() {
            side.pipelines.insert(*key, prep.lend()?);
        }
        Ok(side)
    }

    /// The key of the pipeline for waveform `w`, processing variant `v`, algorithm `a` at a
    /// step of model order `p` (as [`PreparedSet`] chooses).
    fn key(&self, w: usize, v: usize, a: usize, p: Option<usize>) -> PipelineKey {
        match p {
            Some(p) if self.pipelines.contains_key(&(w, v, a, Some(p))) => (w, v, a, Some(p)),
            _ => (w, v, a, None),
        }
    }
}

/// What the writer did for a step.
pub(super) struct Written {
    /// The step's manifest record as stored, without its files and what was applied
    /// ([`StepRecord::status_only`]).
    pub(super) record: StepRecord,
    pub(super) files_s: f64,
    /// Hashing and storing the manifest.
    pub(super) overhead_s: f64,
}

/// What the step's journal line records beside the step: the session, the retries met since
/// the step before was handed over, the session's timing at the hand-over.
pub(super) struct JournalPart {
    pub(super) session: usize,
    pub(super) retries: Vec<super::retry::RetryRecord>,
    pub(super) timing: Timing,
}

/// What a step's worker needs besides the capture and the pipelines.
pub(super) struct StepJob {
    pub(super) dir: PathBuf,
    pub(super) folder: FolderIdentity,
    pub(super) step: Step,
    pub(super) names: Vec<&'static str>,
    pub(super) bandwidth_hz: f64,
    pub(super) provenance: Provenance,
    /// Which files stay (`[output]`): the others are removed once written.
    pub(super) output: OutputSection,
}

impl StepJob {
    /// Processes the capture with every algorithm's pipeline, writes the step's files and
    /// records the step done in the manifest's step journal, with `part`.
    pub(super) fn run(
        self,
        side: &Mutex<WorkerSide>,
        taken: Taken,
        part: JournalPart,
    ) -> WorkerOutcome {
        let mut side = side.lock().unwrap_or_else(|p| p.into_inner());
        let t = Instant::now();
        let w = self.step.waveform;
        let set: Vec<f64> = self
            .step
            .nominal
            .targets
            .iter()
            .map(|t| t.range_m)
            .collect();
        let processed: Result<Vec<Processing>, MeasureError> = (0..self.names.len())
            .map(|a| {
                let key = side.key(w, self.step.processing, a, self.step.music_p);
                let last = side.last_step.get(&key).cloned();
                let pipeline = side.pipelines.get_mut(&key).ok_or_else(|| {
                    MeasureError::Worker("an earlier step lost the pipeline".into())
                })?;
                let from_calibration = pipeline.calibration_as_previous(&set);
                pipeline.set_previous_step(previous_step(last.as_ref(), &set, from_calibration));
                let processing = pipeline.process(&taken.captured)?;
                side.last_step
                    .insert(key, phase_ranges(&processing.processed.targets, &set));
                Ok(processing)
            })
            .collect();
        let processing_s = t.elapsed().as_secs_f64();
        let done = processed
            .map_err(CampaignError::from)
            .and_then(|p| self.record(taken, p, part, &mut side.store));
        WorkerOutcome { processing_s, done }
    }

    fn record(
        self,
        taken: Taken,
        mut processings: Vec<Processing>,
        part: JournalPart,
        store: &mut ManifestStore,
    ) -> Result<(StepResult, Written), CampaignError> {
        let others = processings.split_off(1);
        let mut m = taken.with(processings.pop().expect("the primary algorithm"));
        let mut others: Vec<(&'static str, Processing)> =
            self.names[1..].iter().copied().zip(others).collect();
        let result = {
            let mut outputs = vec![AlgorithmOutput {
                name: self.names[0],
                processed: &m.processing.processed,
                spread: m.processing.spread.as_ref(),
            }];
            for (name, o) in &others {
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
            &self.provenance,
            &result_json,
            self.output,
        )
        .map_err(|e| self.folder.lost(&self.dir).unwrap_or(e))?;
        // The files were hashed as they were written: that share of their time is the
        // campaign's bookkeeping (a lone `radbench capture` does not hash its files).
        let files_s = t_files.elapsed().as_secs_f64() - files.hashing_s;
        let t_over = Instant::now();
        // The files `[output]` drops were never written (the writers skip them); one that was
        // would be a bug: caught in tests, removed in a release build.
        let mut kept = Vec::with_capacity(files.files.len());
        for f in files.files {
            let name = f.path.file_name().map(|n| n.to_string_lossy().into_owned());
            let dropped = name.is_some_and(|n| !self.output.keeps(&n));
            debug_assert!(
                !dropped,
                "[output] drops {} but it was written",
                f.path.display()
            );
            if dropped {
                std::fs::remove_file(&f.path).map_err(io(&f.path))?;
            } else {
                kept.push(f);
            }
        }
        let records: Vec<FileRecord> = kept
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
        let record = StepRecord {
            index: self.step.index,
            status: StepStatus::Done,
            dir: rel,
            measured_at: Some(crate::time::rfc3339_millis(std::time::SystemTime::now())),
            applied,
            files: records,
        };
        self.folder.check(&self.dir)?;
        let status_only = record.status_only();
        let line = JournalLine {
            session: part.session,
            updated: crate::time::rfc3339_millis(std::time::SystemTime::now()),
            step: record,
            retries: part.retries,
            timing: part.timing,
        };
        store
            .record_step(&line, &self.dir)
            .map_err(|e| self.folder.lost(&self.dir).unwrap_or(e))?;
        let written = Written {
            record: status_only,
            files_s,
            overhead_s: t_over.elapsed().as_secs_f64() + files.hashing_s,
        };
        Ok((result, written))
    }
}

/// What the step before tells of the step whose targets are set at `set`, per target: `last`
/// (the pipeline's previous step: where each target was set, its phase range) where it
/// phase-ranged the target, with the move commanded since; else the calibration's record
/// (`from_calibration`, one per target, or none).
fn previous_step(
    last: Option<&Vec<SetAndRanged>>,
    set: &[f64],
    from_calibration: Vec<Previous>,
) -> Vec<Previous> {
    let last = last.filter(|l| l.len() == set.len());
    set.iter()
        .enumerate()
        .filter_map(|(i, now)| {
            let step = last.and_then(|l| {
                let (then_set, ranged) = l[i];
                ranged.map(|then| Previous {
                    then,
                    moved_m: now - then_set,
                })
            });
            step.or_else(|| from_calibration.get(i).copied())
        })
        .collect()
}

/// Each target set at `set`: where it was set, and the phase range of the detection nearest it,
/// when that one was phase-ranged and is within half a centimetre.
fn phase_ranges(targets: &[Detection], set: &[f64]) -> Vec<SetAndRanged> {
    set.iter()
        .map(|&at| {
            let nearest = targets
                .iter()
                .min_by(|a, b| (a.range_m - at).abs().total_cmp(&(b.range_m - at).abs()))
                .filter(|t| (t.range_m - at).abs() <= 0.005);
            (at, nearest.and_then(|t| t.phase_ranged))
        })
        .collect()
}

/// Writes a step's files: the raw capture and the primary algorithm's profiles in the step's
/// folder, each further algorithm's profiles in a subfolder named after it, the step's result.
/// They become durable together (one write group: hashed as written, synced and renamed at the
/// end, each folder synced once); the manifest that names them is written only afterwards.
#[allow(clippy::too_many_arguments)]
fn write_step_files(
    dir: &Path,
    rel: &Path,
    m: &mut Measurement,
    others: &mut [(&str, Processing)],
    provenance: &Provenance,
    result_json: &str,
    output: OutputSection,
) -> Result<GroupWritten, CampaignError> {
    let out = dir.join(rel);
    // The step's folder alone (not its parents): should the run folder vanish after the check,
    // this fails rather than re-create it.
    match std::fs::create_dir(&out) {
        Ok(()) => {}
        Err(e) if e.kind() == std::io::ErrorKind::AlreadyExists => {}
        Err(e) => return Err(io(&out)(e)),
    }
    let keep = |name: &str| output.keeps(name);
    let ((), written) = write_group(|| {
        Recorder::new(&out, provenance).write(m, others, &keep)?;
        write_atomic(&out.join(STEP_RESULT), result_json.as_bytes())?;
        Ok::<_, CampaignError>(())
    })?;
    Ok(written)
}
