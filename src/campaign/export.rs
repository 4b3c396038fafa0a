//! A run folder's arrays for a notebook (`radbench export RUN_DIR`): every measured step's
//! capture exported as `radbench export` exports a capture folder, each in its own group
//! (`step-001/iq`, ...), the step's further algorithms in a group below it named after the
//! algorithm (`step-001/music/profile_amplitude`), as the run folder lays out their files; and
//! one run-level `metadata` (the plan's name, the steps, `results.json`).

use super::error::{io, CampaignError};
use super::manifest::{Manifest, StepStatus};
use crate::measure::records::export::{export_capture, Entry, FORMAT_VERSION};
use crate::measure::records::reprocess;
use crate::measure::ProcessOptions;
use crate::storage::{Array, ExportWriter};
use serde_json::{json, Value};
use std::path::Path;

/// What a run's export held.
pub struct RunExported {
    /// The steps exported (their group names).
    pub steps: Vec<String>,
    /// Steps not measured yet (an interrupted run), left out.
    pub pending: Vec<usize>,
}

/// The options a step's further algorithm was processed with: its `summary.json`'s.
fn algorithm_options(step_dir: &Path, name: &str) -> Result<ProcessOptions, CampaignError> {
    let path = step_dir.join(name).join("summary.json");
    let bad = |message: String| CampaignError::Manifest {
        path: path.clone(),
        message,
    };
    let bytes = std::fs::read(&path).map_err(io(&path))?;
    let summary: Value = serde_json::from_slice(&bytes)
        .map_err(|e| bad(format!("not a summary radbench wrote: {e}")))?;
    serde_json::from_value(summary["processing"].clone())
        .map_err(|e| bad(format!("its \"processing\" is not radbench's options: {e}")))
}

/// Exports every measured step of the run folder `dir` into `out`; `progress` hears each step's
/// group name as it is done.
pub fn export_run(
    dir: &Path,
    out: &mut ExportWriter,
    progress: &mut dyn FnMut(&str, usize, usize),
) -> Result<RunExported, CampaignError> {
    let manifest = Manifest::load(dir)?;
    let done: Vec<_> = manifest
        .steps
        .iter()
        .filter(|s| s.status == StepStatus::Done)
        .collect();
    let pending: Vec<usize> = manifest
        .steps
        .iter()
        .filter(|s| s.status != StepStatus::Done)
        .map(|s| s.index)
        .collect();
    let mut steps = Vec::new();
    for (k, step) in done.iter().enumerate() {
        let step_dir = dir.join(&step.dir);
        let group = step.dir.to_string_lossy().into_owned();
        let source = reprocess::sigmf(&step_dir.join("capture.sigmf-meta")).map_err(|e| {
            CampaignError::Manifest {
                path: e.path,
                message: format!("step {}: {}", step.index, e.reason),
            }
        })?;
        // The step's own algorithms (a step may set its own: `algorithm` in a sweep).
        let variant = manifest
            .plan
            .steps
            .iter()
            .find(|s| s.index == step.index)
            .map_or(0, |s| s.processing);
        let algorithms = manifest.plan.algorithm_names_of(variant);
        let others = algorithms[1..]
            .iter()
            .map(|name| algorithm_options(&step_dir, name))
            .collect::<Result<Vec<_>, _>>()?;
        let exported = export_capture(&source, &others)?;
        for (p, entries) in exported.processings.into_iter().enumerate() {
            let prefix = match p {
                0 => group.clone(),
                _ => format!("{group}/{}", exported.algorithms[p]),
            };
            put_all(out, &prefix, entries)?;
        }
        steps.push(group);
        progress(steps.last().map_or("", String::as_str), k + 1, done.len());
    }
    let results: Option<Value> = std::fs::read(dir.join(super::run::RESULTS_FILE))
        .ok()
        .and_then(|b| serde_json::from_slice(&b).ok());
    let meta = json!({
        "format": "radbench export",
        "format_version": FORMAT_VERSION,
        "radbench_version": env!("CARGO_PKG_VERSION"),
        "run": {
            "name": manifest.plan.name,
            "status": manifest.status.name(),
            "created": manifest.created,
            "dir": dir,
        },
        "algorithms": manifest.plan.algorithm_names(),
        "steps": steps,
        "pending_steps": pending,
        "nominal": manifest.plan.steps.iter().map(|s| json!({
            "step": s.index,
            "nominal": s.nominal,
        })).collect::<Vec<_>>(),
        "results": results,
    });
    out.put("metadata", &Array::Text(meta.to_string()), None)?;
    Ok(RunExported { steps, pending })
}

/// Puts `entries` under `prefix/`.
pub fn put_all(
    out: &mut ExportWriter,
    prefix: &str,
    entries: Vec<Entry>,
) -> Result<(), CampaignError> {
    for e in entries {
        let name = if prefix.is_empty() {
            e.name
        } else {
            format!("{prefix}/{}", e.name)
        };
        out.put(&name, &e.array, e.unit)?;
    }
    Ok(())
}
