//! What the catalog holds of one folder, read from the folder's own files: a run folder's
//! `manifest.toml` and `results.json`, a capture folder's `summary.json`. Pure reading: the
//! rows are written by [`super::index`].

use super::RunsDbError;
use crate::campaign::{Manifest, Results, StepStatus, MANIFEST_FILE};
use serde_json::Value;
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

/// `results.json`'s name in a run folder.
pub(crate) const RESULTS_FILE: &str = "results.json";
/// The file that makes a folder a capture (written last, once everything else is in place).
pub(crate) const SUMMARY_FILE: &str = "summary.json";

/// A run folder, as the catalog holds it.
#[derive(Debug, Clone)]
pub(crate) struct RunRecord {
    pub run_id: String,
    pub dir: PathBuf,
    pub manifest: Manifest,
    pub manifest_sha256: String,
    pub results: Option<Results>,
    pub results_sha256: Option<String>,
}

/// The run's id: the first 16 hex digits of SHA-256 over when it was created, its spec's SHA-256
/// and its name, all from the manifest. A folder moved or copied keeps its id, so it stays one
/// row; two runs of the same spec differ by their creation time (milliseconds).
pub fn run_id(manifest: &Manifest) -> String {
    let key = format!(
        "{}\n{}\n{}",
        manifest.created, manifest.spec.sha256, manifest.plan.name
    );
    crate::storage::sha256(key.as_bytes())[..16].to_string()
}

/// The run folder `dir`, read. `Ok(None)` when it holds no manifest.
pub(crate) fn read_run(dir: &Path) -> Result<Option<RunRecord>, RunsDbError> {
    let manifest_path = dir.join(MANIFEST_FILE);
    let text = match std::fs::read(&manifest_path) {
        Ok(t) => t,
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(None),
        Err(e) => return Err(RunsDbError::io(&manifest_path, e)),
    };
    let manifest = Manifest::load(dir).map_err(|e| RunsDbError::Folder {
        path: manifest_path.clone(),
        reason: e.to_string(),
    })?;
    let results_path = dir.join(RESULTS_FILE);
    let (results, results_sha256) = match std::fs::read(&results_path) {
        Ok(bytes) => {
            let results: Results =
                serde_json::from_slice(&bytes).map_err(|e| RunsDbError::Folder {
                    path: results_path.clone(),
                    reason: format!("not a results.json radbench reads: {e}"),
                })?;
            (Some(results), Some(crate::storage::sha256(&bytes)))
        }
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => (None, None),
        Err(e) => return Err(RunsDbError::io(&results_path, e)),
    };
    Ok(Some(RunRecord {
        run_id: run_id(&manifest),
        dir: absolute(dir),
        manifest_sha256: crate::storage::sha256(&text),
        manifest,
        results,
        results_sha256,
    }))
}

/// `path` made absolute (as it is when that fails), without resolving links.
pub(crate) fn absolute(path: &Path) -> PathBuf {
    std::path::absolute(path).unwrap_or_else(|_| path.to_path_buf())
}

impl RunRecord {
    /// The sweep's parameter, as the steps name it.
    pub(crate) fn sweep(&self) -> Option<&'static str> {
        self.manifest
            .plan
            .steps
            .iter()
            .find_map(|s| s.nominal.parameter)
            .map(|p| p.name())
    }

    pub(crate) fn steps_done(&self) -> usize {
        self.manifest
            .steps
            .iter()
            .filter(|s| s.status == StepStatus::Done)
            .count()
    }

    /// The algorithms' names, the primary first.
    pub(crate) fn algorithms(&self) -> Vec<&'static str> {
        self.manifest
            .plan
            .processing
            .iter()
            .map(|o| o.algorithm.name())
            .collect()
    }

    pub(crate) fn waveforms(&self) -> Vec<&'static str> {
        let mut names: Vec<&'static str> = Vec::new();
        for w in &self.manifest.plan.waveforms {
            if !names.contains(&w.name()) {
                names.push(w.name());
            }
        }
        names
    }

    /// The run's figures (see [`metrics`]).
    pub(crate) fn metrics(&self) -> BTreeMap<String, f64> {
        self.results.as_ref().map(metrics).unwrap_or_default()
    }
}

/// The figures `--where` and `trend` read, over every step of `results`: unprefixed over every
/// algorithm (as the campaign's own summary), and `<algorithm>.<name>` for each algorithm alone.
/// A figure no step has (no SNR for MUSIC, no truth on a real bench) is absent, never zero.
pub(crate) fn metrics(results: &Results) -> BTreeMap<String, f64> {
    let mut out = BTreeMap::new();
    let mut names: Vec<&str> = results
        .steps
        .iter()
        .flat_map(|s| s.algorithms.keys().map(String::as_str))
        .collect();
    names.sort_unstable();
    names.dedup();
    add_figures(&mut out, "", results, None);
    for name in names {
        add_figures(&mut out, &format!("{name}."), results, Some(name));
    }
    out
}

/// Every metric name a run can have (without an algorithm's prefix), for messages and docs.
pub const METRIC_NAMES: [&str; 14] = [
    "steps",
    "max_abs_error_m",
    "mean_abs_error_m",
    "max_abs_error_on_grid_m",
    "max_abs_truth_error_m",
    "mean_abs_truth_error_m",
    "missed",
    "mean_snr_db",
    "min_snr_db",
    "mean_width_3db_cm",
    "mean_sidelobe_db",
    "resolved_fraction",
    "max_ber",
    "bit_errors",
];

fn add_figures(
    out: &mut BTreeMap<String, f64>,
    prefix: &str,
    results: &Results,
    only: Option<&str>,
) {
    let picked: Vec<_> = results
        .steps
        .iter()
        .flat_map(|s| s.algorithms.iter())
        .filter(|(name, _)| only.is_none_or(|o| o == name.as_str()))
        .map(|(_, a)| a)
        .collect();
    let steps = results
        .steps
        .iter()
        .filter(|s| only.is_none_or(|o| s.algorithms.contains_key(o)))
        .count();
    let mut put = |name: &str, v: Option<f64>| {
        if let Some(v) = v.filter(|v| v.is_finite()) {
            out.insert(format!("{prefix}{name}"), v);
        }
    };
    put("steps", Some(steps as f64));
    let abs = |f: fn(&crate::campaign::AlgorithmResult) -> Option<f64>| -> Vec<f64> {
        picked.iter().filter_map(|a| f(a)).map(f64::abs).collect()
    };
    let plain = |f: fn(&crate::campaign::AlgorithmResult) -> Option<f64>| -> Vec<f64> {
        picked.iter().filter_map(|a| f(a)).collect()
    };
    let errors = abs(|a| a.error_m);
    put("max_abs_error_m", max(&errors));
    put("mean_abs_error_m", mean(&errors));
    put("max_abs_error_on_grid_m", max(&abs(|a| a.error_on_grid_m)));
    let truth = abs(|a| a.truth_error_m);
    put("max_abs_truth_error_m", max(&truth));
    put("mean_abs_truth_error_m", mean(&truth));
    put(
        "missed",
        (!picked.is_empty()).then(|| picked.iter().map(|a| a.missed as f64).sum()),
    );
    let snr = plain(|a| a.snr_db);
    put("mean_snr_db", mean(&snr));
    put("min_snr_db", snr.iter().copied().reduce(f64::min));
    put("mean_width_3db_cm", mean(&plain(|a| a.width_3db_cm)));
    put("mean_sidelobe_db", mean(&plain(|a| a.sidelobe_db)));
    let resolved: Vec<f64> = picked
        .iter()
        .filter_map(|a| a.resolved)
        .map(|r| if r { 1.0 } else { 0.0 })
        .collect();
    put("resolved_fraction", mean(&resolved));
    let payloads: Vec<_> = picked.iter().filter_map(|a| a.payload.as_ref()).collect();
    put(
        "max_ber",
        max(&payloads.iter().map(|p| p.ber).collect::<Vec<_>>()),
    );
    put(
        "bit_errors",
        (!payloads.is_empty()).then(|| payloads.iter().map(|p| p.bit_errors as f64).sum()),
    );
}

fn max(v: &[f64]) -> Option<f64> {
    v.iter().copied().reduce(f64::max)
}

fn mean(v: &[f64]) -> Option<f64> {
    (!v.is_empty()).then(|| v.iter().sum::<f64>() / v.len() as f64)
}

/// A capture folder (`radbench capture`, `radbench process`), as the catalog holds it.
#[derive(Debug, Clone)]
pub(crate) struct CaptureRecord {
    pub dir: PathBuf,
    /// `capture` or `process`.
    pub origin: &'static str,
    pub summary: Value,
    pub summary_sha256: String,
    pub measured_at: Option<String>,
}

/// The capture folder `dir`, read. `Ok(None)` when it holds no `summary.json`.
pub(crate) fn read_capture(dir: &Path) -> Result<Option<CaptureRecord>, RunsDbError> {
    let path = dir.join(SUMMARY_FILE);
    let bytes = match std::fs::read(&path) {
        Ok(b) => b,
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(None),
        Err(e) => return Err(RunsDbError::io(&path, e)),
    };
    let summary: Value = serde_json::from_slice(&bytes).map_err(|e| RunsDbError::Folder {
        path: path.clone(),
        reason: format!("not a summary.json radbench reads: {e}"),
    })?;
    // `radbench process` writes a manifest of its sources beside the summary.
    let origin = if dir.join(crate::campaign::MANIFEST_FILE).is_file() {
        "process"
    } else {
        "capture"
    };
    let measured_at = sigmf_datetime(dir).or_else(|| {
        let modified = std::fs::metadata(&path).and_then(|m| m.modified()).ok()?;
        Some(crate::time::rfc3339_millis(modified))
    });
    Ok(Some(CaptureRecord {
        dir: absolute(dir),
        origin,
        summary_sha256: crate::storage::sha256(&bytes),
        summary,
        measured_at,
    }))
}

/// `core:datetime` of the capture's SigMF recording, when it has one.
fn sigmf_datetime(dir: &Path) -> Option<String> {
    let text = std::fs::read(dir.join("capture.sigmf-meta")).ok()?;
    let meta: Value = serde_json::from_slice(&text).ok()?;
    meta["captures"][0]["core:datetime"]
        .as_str()
        .map(str::to_owned)
}

impl CaptureRecord {
    pub(crate) fn waveform(&self) -> Option<String> {
        let w = &self.summary["waveform"];
        w.as_str().or_else(|| w["kind"].as_str()).map(str::to_owned)
    }

    pub(crate) fn algorithm(&self) -> Option<String> {
        let s = &self.summary;
        s["algorithm"]
            .as_str()
            .or_else(|| s["processing"]["algorithm"].as_str())
            .map(str::to_owned)
    }

    /// `*IDN?` by role (`awg`, `scope`, `tx`, `rx`).
    pub(crate) fn instruments(&self) -> Vec<(String, String)> {
        self.summary["instruments"]
            .as_object()
            .map(|o| {
                o.iter()
                    .filter_map(|(k, v)| Some((k.clone(), v.as_str()?.to_owned())))
                    .collect()
            })
            .unwrap_or_default()
    }

    /// Detected targets: (range, level).
    pub(crate) fn targets(&self) -> Vec<(f64, Option<f64>)> {
        self.summary["targets"]
            .as_array()
            .map(|t| {
                t.iter()
                    .filter_map(|x| Some((x["range_m"].as_f64()?, x["level_db"].as_f64())))
                    .collect()
            })
            .unwrap_or_default()
    }

    /// Every file of the folder the summary names (it names them as the command was given its
    /// `--out`, so by their file names here), the summary itself included.
    pub(crate) fn files(&self) -> Vec<PathBuf> {
        let mut files: Vec<PathBuf> = self.summary["files"]
            .as_object()
            .map(|o| {
                o.iter()
                    .filter(|(k, _)| k.as_str() != "dir")
                    .flat_map(|(_, v)| match v {
                        Value::String(s) => vec![PathBuf::from(s)],
                        Value::Array(a) => a
                            .iter()
                            .filter_map(|x| x.as_str().map(PathBuf::from))
                            .collect(),
                        _ => Vec::new(),
                    })
                    .collect()
            })
            .unwrap_or_default();
        files.push(SUMMARY_FILE.into());
        let mut files: Vec<PathBuf> = files
            .iter()
            .filter_map(|f| Some(self.dir.join(f.file_name()?)))
            .filter(|f| f.is_file())
            .collect();
        files.sort();
        files.dedup();
        files
    }
}
