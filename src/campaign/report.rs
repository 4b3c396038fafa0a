//! The run's report, written from `manifest.toml` and `results.json` alone (so `radbench campaign
//! report RUN_DIR` can write it again at any time).
//!
//! This is the minimal report: a Markdown table of the steps. The full report (plots, HTML) builds
//! on the same two files and replaces [`write()`]'s body.

use super::manifest::Manifest;
use super::results::Results;
use super::{io, CampaignError};
use crate::storage::atomic::write_atomic;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

/// The report's file name in a run folder.
pub const FILE: &str = "report.md";

/// Writes `dir/report.md`; returns its path.
pub fn write(dir: &Path, manifest: &Manifest, results: &Results) -> Result<PathBuf, CampaignError> {
    let path = dir.join(FILE);
    write_atomic(&path, markdown(manifest, results).as_bytes())?;
    Ok(path)
}

/// Reads a run folder's manifest and results and writes its report again.
pub fn rewrite(dir: &Path) -> Result<PathBuf, CampaignError> {
    let manifest = Manifest::load(dir)?;
    let path = dir.join(super::run::RESULTS_FILE);
    let text = std::fs::read_to_string(&path).map_err(io(&path))?;
    let results: Results = serde_json::from_str(&text).map_err(|e| CampaignError::Manifest {
        path: path.clone(),
        message: format!("not a campaign results.json: {e}"),
    })?;
    write(dir, &manifest, &results)
}

fn mm(v: Option<f64>) -> String {
    v.map_or("-".into(), |x| format!("{:+.2}", x * 1e3))
}

fn markdown(manifest: &Manifest, results: &Results) -> String {
    let plan = &manifest.plan;
    let mut out = String::new();
    let _ = writeln!(out, "# Campaign {}\n", plan.name);
    if let Some(d) = &plan.description {
        let _ = writeln!(out, "{d}\n");
    }
    let _ = writeln!(
        out,
        "Status: **{}**{}. Bench: {}. radbench {}{}.\n",
        manifest.status.name(),
        manifest
            .reason
            .as_ref()
            .map(|r| format!(" ({r})"))
            .unwrap_or_default(),
        plan.bench.describe(),
        manifest.radbench_version,
        manifest
            .git_commit
            .as_ref()
            .map(|c| format!(" ({c})"))
            .unwrap_or_default()
    );
    let _ = writeln!(
        out,
        "| step | nominal | algorithm | targets (m) | error (mm) | on grid (mm) | vs truth (mm) | resolved | -3 dB width (cm) | PSL (dB) |"
    );
    let _ = writeln!(out, "|---|---|---|---|---|---|---|---|---|---|");
    for s in &results.steps {
        for (name, a) in &s.algorithms {
            let targets: Vec<String> = a
                .targets
                .iter()
                .map(|t| format!("{:.4}", t.range_m))
                .collect();
            let _ = writeln!(
                out,
                "| {} | {} | {} | {} | {} | {} | {} | {} | {} | {} |",
                s.index,
                s.nominal.describe(),
                name,
                if targets.is_empty() {
                    "none".into()
                } else {
                    targets.join(", ")
                },
                mm(a.error_m),
                mm(a.error_on_grid_m),
                mm(a.truth_error_m),
                a.resolved.map_or("-", |r| if r { "yes" } else { "no" }),
                a.width_3db_cm.map_or("-".into(), |w| format!("{w:.2}")),
                a.sidelobe_db.map_or("-".into(), |w| format!("{w:.2}")),
            );
        }
    }
    let done = results.steps.len();
    if done < plan.steps.len() {
        let _ = writeln!(
            out,
            "\n{} of {} steps measured; `radbench campaign resume` continues the run.",
            done,
            plan.steps.len()
        );
    }
    let _ = writeln!(
        out,
        "\nFiles: `manifest.toml` (inputs, plan, identities, hashes), `results.json`, one folder \
         per step with its capture (SigMF, .trc) and profiles."
    );
    out
}
