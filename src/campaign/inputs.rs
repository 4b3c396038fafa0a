//! A run's inputs: copied into the run folder when it starts (spec, bench file, the bench file's
//! instrument files, the response calibration) and, on resume, checked to be still the ones the
//! run started with.

use super::error::{io, CampaignError};
use super::manifest::{self, CalibrationRecord, InputFile, Manifest};
use super::plan::{BenchInfo, Plan};
use crate::measure::MeasureError;
use crate::storage::write_atomic;
use std::path::{Path, PathBuf};

/// The spec's copy in a run folder.
pub(crate) const SPEC_COPY: &str = "spec.toml";
/// The bench file's copy in a run folder.
pub(crate) const BENCH_COPY: &str = "bench.toml";
/// Where the run keeps its copies of the bench file's own instrument files.
pub(crate) const BENCH_CATALOG_COPY: &str = "bench-catalog";
/// Where the run keeps its copy of the response calibration it corrects with.
pub(crate) const CALIBRATION_COPY: &str = "calibration";

/// Copies the instrument files of the bench file's `catalog` folder into the run folder
/// (`bench-catalog/`), so the limits the run was planned with stay with its data.
pub(super) fn copy_bench_catalog(
    out: &Path,
    bench: &BenchInfo,
) -> Result<Vec<InputFile>, CampaignError> {
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
pub(super) fn copy_calibration(
    out: &Path,
    plan: &Plan,
) -> Result<Option<CalibrationRecord>, CampaignError> {
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
/// goes on with the copy in the run folder. Either is loaded here, once, into the plan's
/// processing (a plan read back names its calibration only).
pub(super) fn check_calibration(
    dir: &Path,
    manifest: &Manifest,
    plan: &mut Plan,
    force: bool,
    forced: &mut Vec<String>,
) -> Result<(), CampaignError> {
    use crate::measure::{load_recorded, Calibration};
    let Some(rec) = &manifest.calibration else {
        return Ok(load_recorded(corrections(plan))?);
    };
    let what = match Calibration::load(&rec.path) {
        Ok(cal) if cal.sha256 == rec.sha256 => {
            let cal = std::sync::Arc::new(cal);
            for used in corrections(plan) {
                used.load_from(&cal)?;
            }
            return Ok(());
        }
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
    for used in corrections(plan) {
        used.calibration = copy.display().to_string();
    }
    Ok(load_recorded(corrections(plan))?)
}

/// The corrections of every algorithm of every processing variant of `plan`.
fn corrections(plan: &mut Plan) -> impl Iterator<Item = &mut crate::measure::CorrectionUsed> {
    let variants = plan.processing_variants.iter_mut().flatten();
    plan.processing
        .iter_mut()
        .chain(variants)
        .filter_map(|o| o.correction.as_mut())
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
