//! What `radbench process` does per capture, shared with the in-memory API: the captures'
//! folder names, the hashes their runs recorded, and one capture through this thread's pipeline
//! (one cache of pipelines per worker thread).

use crate::campaign::Manifest;
use crate::measure::records::reprocess::{
    self, Loaded, Record, Repetition, Reprocessed, Source, WaveformChoice,
};
use crate::measure::MeasureError;
use crate::measure::Pipeline;
use crate::measure::ProcessOverrides;
use crate::measure::SourceFile;
use serde_json::json;
use std::cell::RefCell;
use std::collections::{BTreeSet, HashMap};
use std::path::{Path, PathBuf};

thread_local! {
    /// Pipelines built on this worker, by what they were built for: a batch of captures of one
    /// waveform builds its filters, plans and tables once per thread.
    static PIPELINES: RefCell<Vec<(String, Pipeline)>> = const { RefCell::new(Vec::new()) };
}

/// Most pipelines a worker keeps (a batch rarely mixes more waveforms and options).
const PIPELINES_PER_WORKER: usize = 4;

/// The SHA-256 that run manifests recorded for the captures' data files, by path: the run
/// folder of each capture's folder, where it has a manifest radbench reads. A capture whose data
/// matches its recorded hash is not hashed a second time against the recording's own SHA-512
/// (see `read_sigmf_stored`). A manifest that cannot be read only means no such shortcut.
pub fn recorded_data_hashes(sources: &[&Source]) -> HashMap<PathBuf, String> {
    let runs: BTreeSet<&Path> = sources
        .iter()
        .filter_map(|s| match s {
            Source::Sigmf { data, .. } => data.parent()?.parent(),
            Source::TrcPair { .. } => None,
        })
        .filter(|run| run.join("manifest.toml").is_file())
        .collect();
    let mut hashes = HashMap::new();
    for run in runs {
        let Ok(manifest) = Manifest::load(run) else {
            continue;
        };
        for file in manifest.steps.into_iter().flat_map(|step| step.files) {
            hashes.insert(run.join(&file.path), file.sha256);
        }
    }
    hashes
}

/// The recorded SHA-256 of `source`'s data, if its run recorded one.
pub fn recorded_for<'a>(
    source: &Source,
    recorded: &'a HashMap<PathBuf, String>,
) -> Option<&'a str> {
    match source {
        Source::Sigmf { data, .. } => recorded.get(data).map(String::as_str),
        Source::TrcPair { .. } => None,
    }
}

/// One capture through the pipeline (one of this thread's pipelines when it was built for the
/// same transmission and options): the capture read, the result and its files' hashes.
pub fn compute(
    source: &Source,
    recorded_sha256: Option<&str>,
    waveform: &WaveformChoice,
    overrides: &ProcessOverrides,
    background: Option<&Path>,
    trigger_offset: Option<f64>,
) -> Result<(Loaded<Repetition>, Reprocessed, Vec<SourceFile>), anyhow::Error> {
    let loaded = reprocess::load_for_processing(source, trigger_offset, recorded_sha256)?;
    let resolved = reprocess::resolve(&loaded, waveform, overrides, background)?;
    let hashes = reprocess::source_hashes(source, &loaded.sha256)?;
    let r = on_cached_pipeline(&loaded, resolved)?;
    let sources: Vec<SourceFile> = hashes
        .into_iter()
        .map(|(path, sha256)| SourceFile { path, sha256 })
        .collect();
    Ok((loaded, r, sources))
}

/// `loaded` processed as `resolved` says, on this thread's pipeline for it (built when missing).
pub(crate) fn on_cached_pipeline<R: Record>(
    loaded: &Loaded<R>,
    resolved: reprocess::Resolved,
) -> Result<Reprocessed, anyhow::Error> {
    // A recording that names no repetition (an empty `.trc` sequence) has no rate to build for.
    let Some(rate) = loaded.repetitions.first().map(|r| r.sample_rate_hz()) else {
        return Err(MeasureError::RecordTooShort {
            points: 0,
            needed: resolved.period,
        }
        .into());
    };
    let key = serde_json::to_string(&json!({
        "tx": resolved.tx.describe(),
        "options": resolved.options,
        "period": resolved.period,
        "rate": rate,
    }))?;
    let r = PIPELINES.with(|cell| -> Result<_, MeasureError> {
        let mut cache = cell.borrow_mut();
        let index = match cache.iter().position(|(k, _)| *k == key) {
            Some(i) => i,
            None => {
                if cache.len() >= PIPELINES_PER_WORKER {
                    cache.remove(0);
                }
                cache.push((key.clone(), reprocess::pipeline(&resolved, rate)?));
                cache.len() - 1
            }
        };
        reprocess::process(&mut cache[index].1, loaded, resolved)
    })?;
    Ok(r)
}

/// Folder names for the sources: their labels, made unique.
pub fn folder_names(sources: &[&Source]) -> Vec<String> {
    let mut names: Vec<String> = Vec::new();
    for s in sources {
        let base = s.label();
        let mut name = base.clone();
        let mut k = 2;
        while names.contains(&name) {
            name = format!("{base}-{k}");
            k += 1;
        }
        names.push(name);
    }
    names
}
