//! The run folder's identity (device and inode), checked before anything is put in it: a folder
//! renamed, deleted or replaced while the campaign runs (an operator tidying up, a sync tool, a
//! disk cleaner) stops the run instead of being re-created at the old path and declared complete
//! with files that are not there.
//!
//! Also the folder's start (created empty, locked, the inputs copied in: spec, bench file, the
//! bench file's instrument files, the response calibration) and, on resume, the checks that those
//! inputs are still the ones the run started with.

use super::error::{io, CampaignError};
use super::manifest::{
    self, CalibrationRecord, InputFile, Manifest, Status, StepRecord, StepStatus,
};
use super::plan::{BenchInfo, Plan};
use super::prepare::prepare_all;
use super::run::{
    Finished, NewRun, Observer, BENCH_CATALOG_COPY, BENCH_COPY, CALIBRATION_COPY, SPEC_COPY,
};
use super::runner::{new_session, Runner};
use crate::measure::MeasureError;
use crate::storage::write_atomic;
use std::os::unix::fs::MetadataExt;
use std::path::{Path, PathBuf};
use std::time::Instant;

/// Held (flock) while a process works in the run folder.
const LOCK_FILE: &str = ".radbench.lock";

/// Which folder the run was started in.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) struct FolderIdentity {
    dev: u64,
    ino: u64,
}

impl FolderIdentity {
    /// The identity of `dir` as it is now.
    pub(crate) fn of(dir: &Path) -> Result<FolderIdentity, CampaignError> {
        let m = std::fs::metadata(dir).map_err(io(dir))?;
        Ok(FolderIdentity {
            dev: m.dev(),
            ino: m.ino(),
        })
    }

    /// That `dir` is still the folder the run was started in.
    pub(crate) fn check(&self, dir: &Path) -> Result<(), CampaignError> {
        let lost = |what: &'static str| CampaignError::FolderLost {
            dir: dir.to_path_buf(),
            what,
        };
        match std::fs::metadata(dir) {
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => Err(lost("moved or deleted")),
            Err(e) => Err(io(dir)(e)),
            Ok(m) if (m.dev(), m.ino()) != (self.dev, self.ino) => {
                Err(lost("replaced by another folder of that name"))
            }
            Ok(_) => Ok(()),
        }
    }
}

impl FolderIdentity {
    /// After a write failed: the folder's loss when that was the cause (a write racing the
    /// folder's removal fails with "not found", which would not say what happened).
    pub(crate) fn lost(&self, dir: &Path) -> Option<CampaignError> {
        self.check(dir)
            .err()
            .filter(|e| matches!(e, CampaignError::FolderLost { .. }))
    }
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

/// Copies the instrument files of the bench file's `catalog` folder into the run folder
/// (`bench-catalog/`), so the limits the run was planned with stay with its data.
fn copy_bench_catalog(out: &Path, bench: &BenchInfo) -> Result<Vec<InputFile>, CampaignError> {
    let Some((_, file)) = bench.file.as_ref() else {
        return Ok(Vec::new());
    };
    let files = file.catalog_files().map_err(MeasureError::from)?;
    if files.is_empty() {
        return Ok(Vec::new());
    }
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
    use crate::measure::Calibration;
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
        mode: used.mode,
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
pub(super) fn check_calibration(
    dir: &Path,
    manifest: &Manifest,
    plan: &mut Plan,
    force: bool,
    forced: &mut Vec<String>,
) -> Result<(), CampaignError> {
    use crate::measure::Calibration;
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
    let variants = plan.processing_variants.iter_mut().flatten();
    for o in plan.processing.iter_mut().chain(variants) {
        if let Some(c) = &mut o.correction {
            c.calibration = copy.display().to_string();
        }
    }
    Ok(())
}

/// The run's copy of its spec must be the one it started with.
pub(super) fn check_spec_unchanged(dir: &Path, manifest: &Manifest) -> Result<(), CampaignError> {
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

/// The bench file's instrument files must be those the run was planned with (the same names and
/// contents); a change refuses the resume unless `force`, and is then recorded in `forced`.
pub(super) fn check_bench_catalog(
    manifest: &Manifest,
    bench_file: Option<&crate::measure::BenchFile>,
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
    if let Some(file) = bench_file {
        for path in file.catalog_files().map_err(MeasureError::from)? {
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

/// An exclusive lock on the run folder for this process (released when dropped).
pub(super) struct Lock {
    _file: std::fs::File,
}

pub(super) fn lock(dir: &Path) -> Result<Lock, CampaignError> {
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

/// Whether a process holds `dir`'s lock (works in the run folder now). A shared lock taken
/// for a moment tells: it is refused while a run or resume holds the exclusive one. A folder
/// without a lock file has no process in it.
pub(crate) fn lock_is_held(dir: &Path) -> bool {
    use std::os::fd::AsRawFd;
    let Ok(file) = std::fs::File::open(dir.join(LOCK_FILE)) else {
        return false;
    };
    // SAFETY: flock on a file descriptor this function owns; closing it releases the lock.
    let rc = unsafe { libc::flock(file.as_raw_fd(), libc::LOCK_SH | libc::LOCK_NB) };
    rc != 0
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_moved_deleted_or_replaced_folder_is_told() {
        let tmp = tempfile::tempdir().unwrap();
        let run = tmp.path().join("run");
        std::fs::create_dir(&run).unwrap();
        let id = FolderIdentity::of(&run).unwrap();
        assert!(id.check(&run).is_ok());
        std::fs::rename(&run, tmp.path().join("elsewhere")).unwrap();
        let err = id.check(&run).unwrap_err().to_string();
        assert!(err.contains("moved or deleted"), "{err}");
        std::fs::create_dir(&run).unwrap();
        let err = id.check(&run).unwrap_err().to_string();
        assert!(err.contains("replaced"), "{err}");
        assert!(id.check(&tmp.path().join("elsewhere")).is_ok());
    }
}
