//! One unit of archive processing: a capture the catalog holds, processed into the folder its
//! content addresses.

use super::{ArchiveSettings, VERSION};
use crate::exit::bad_input;
use crate::in_memory::{compute, recorded_data_hashes, recorded_for};
use crate::measure::{discover, write_reprocessed_by_content, Source};
use crate::runs_db::{self, ProcessedRow};
use crate::storage::write_group_open;
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};

/// A capture to process, with the SHA-256 that addresses it.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct Unit {
    /// The capture folder (as the catalog names it).
    pub input_dir: PathBuf,
    /// SHA-256 of the capture's files' SHA-256 (its metadata and data, or its I and Q `.trc`).
    pub input_sha256: String,
}

impl Unit {
    /// The output folder's name: input, options, version.
    pub(crate) fn address(&self, settings: &ArchiveSettings) -> String {
        format!(
            "{}-{}-v{VERSION}",
            &self.input_sha256[..16],
            &settings.options_sha256()[..16]
        )
    }
}

/// Whether a unit was computed now or found done.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum UnitStatus {
    Written,
    Skipped,
}

/// A unit done: where its output is.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct UnitDone {
    pub unit: Unit,
    pub out_dir: PathBuf,
    pub status: UnitStatus,
}

impl UnitDone {
    /// Its row of the catalog's `processed` table.
    pub fn row(&self, settings: &ArchiveSettings) -> ProcessedRow {
        ProcessedRow {
            input_sha256: self.unit.input_sha256.clone(),
            options_sha256: settings.options_sha256().to_string(),
            radbench_version: VERSION.to_string(),
            out_dir: self.out_dir.clone(),
            input_dir: self.unit.input_dir.clone(),
            options: settings.described().to_string(),
        }
    }
}

/// The files a capture is read from (what its address hashes).
fn source_files(source: &Source) -> Vec<PathBuf> {
    match source {
        Source::Sigmf { meta, data } => vec![meta.clone(), data.clone()],
        Source::TrcPair { i, q } => vec![i.clone(), q.clone()],
    }
}

/// The one capture of folder `dir`.
fn source_of(dir: &Path) -> anyhow::Result<Source> {
    let mut found = discover(&[dir.to_path_buf()]);
    match found.len() {
        1 => found.remove(0).map_err(|e| bad_input(e.to_string())),
        n => Err(bad_input(format!(
            "{}: holds {n} captures where the catalog has one (run `radbench runs index`)",
            dir.display()
        ))),
    }
}

/// The captures `query` selects in `catalog` (the language of
/// `runs_db::parse_query`), newest first, with their addresses' input SHA-256: as the
/// catalog's `assets` table has them, or hashed when a file is not there or changed since.
/// Outputs of `process` are results, not captures: never selected.
pub fn units(catalog: &Path, query: &str) -> anyhow::Result<Vec<Unit>> {
    let filter = runs_db::parse_query(query)?;
    let rows = runs_db::captures(catalog, &filter)?;
    let dirs: Vec<PathBuf> = rows
        .into_iter()
        .filter(|r| r.origin != "process")
        .map(|r| PathBuf::from(r.dir))
        .collect();
    units_of(catalog, &dirs)
}

/// The units of the capture folders `dirs` (as a query over the catalog listed them, e.g. the
/// Python package's `catalog(path).captures(...)`), hashed as [`units`] hashes them.
pub fn units_of(catalog: &Path, dirs: &[PathBuf]) -> anyhow::Result<Vec<Unit>> {
    let mut picked = Vec::new();
    for dir in dirs {
        let source = source_of(dir)?;
        picked.push((dir.clone(), source_files(&source)));
    }
    let all: Vec<PathBuf> = picked.iter().flat_map(|(_, f)| f.clone()).collect();
    let known = runs_db::known_sha256(catalog, &all)?;
    let mut out = Vec::with_capacity(picked.len());
    for (dir, files) in picked {
        let mut text = String::new();
        for f in &files {
            let sha = match known.get(f) {
                Some(s) => s.clone(),
                None => crate::storage::sha256_file(f)?,
            };
            text.push_str(&sha);
            text.push('\n');
        }
        out.push(Unit {
            input_dir: dir,
            input_sha256: crate::storage::sha256(text.as_bytes()),
        });
    }
    Ok(out)
}

/// The prefix of a unit's temporary folder (hidden: the catalog's index never reads it).
const PARTIAL: &str = ".partial-";

/// Temporary folders of this process told apart.
static PARTIALS: AtomicU64 = AtomicU64::new(0);

/// Processes `unit` into `out/<address>` unless that folder exists. `markers`: a folder where a
/// file is made each time a unit starts computing (accounting, and how tests count work done
/// twice).
pub fn process_unit(
    unit: &Unit,
    out: &Path,
    settings: &ArchiveSettings,
    markers: Option<&Path>,
) -> anyhow::Result<UnitDone> {
    let address = unit.address(settings);
    let done = |status| UnitDone {
        unit: unit.clone(),
        out_dir: out.join(&address),
        status,
    };
    let target = out.join(&address);
    if target.is_dir() {
        return Ok(done(UnitStatus::Skipped));
    }
    let k = PARTIALS.fetch_add(1, Ordering::Relaxed);
    let pid = std::process::id();
    if let Some(m) = markers {
        std::fs::create_dir_all(m)?;
        std::fs::write(m.join(format!("{address}.{pid}.{k}")), b"")?;
    }
    let partial = out.join(format!("{PARTIAL}{address}-{pid}-{k}"));
    let written = write_partial(unit, &partial, settings).and_then(|()| {
        std::fs::rename(&partial, &target).map_err(anyhow::Error::from)?;
        // The rename durable: the folder that holds it synced.
        std::fs::File::open(out)?.sync_all()?;
        Ok(())
    });
    match written {
        Ok(()) => Ok(done(UnitStatus::Written)),
        // Another worker finished the same unit first (a worker presumed dead that was not):
        // its result stands, this one goes.
        Err(_) if target.is_dir() => {
            let _ = std::fs::remove_dir_all(&partial);
            Ok(done(UnitStatus::Skipped))
        }
        Err(e) => {
            let _ = std::fs::remove_dir_all(&partial);
            Err(e.context(format!("{}", unit.input_dir.display())))
        }
    }
}

/// The unit computed and its files written, durable, into `partial`.
fn write_partial(unit: &Unit, partial: &Path, settings: &ArchiveSettings) -> anyhow::Result<()> {
    let source = source_of(&unit.input_dir)?;
    let recorded = recorded_data_hashes(&[&source]);
    let (loaded, r, sources) = compute(
        &source,
        recorded_for(&source, &recorded),
        &settings.waveform,
        &settings.overrides,
        settings.background.as_deref(),
        settings.trigger_offset,
    )?;
    let (_, group) = write_group_open(|| {
        write_reprocessed_by_content(partial, &sources, &loaded, &r, settings.link_png)
    })?;
    group.finish()?;
    Ok(())
}

/// Removes the temporary folders in `out` of units whose output is in place (left by killed
/// workers); the number removed. Those of units not done yet stay: their writer may be alive.
pub fn sweep_partials(out: &Path) -> usize {
    let Ok(entries) = std::fs::read_dir(out) else {
        return 0;
    };
    let mut removed = 0;
    for e in entries.filter_map(Result::ok) {
        let name = e.file_name().to_string_lossy().into_owned();
        let Some(rest) = name.strip_prefix(PARTIAL) else {
            continue;
        };
        // `<address>-<pid>-<k>`: the address is what precedes the last two parts.
        let mut parts = rest.rsplitn(3, '-');
        let (_, _, address) = (parts.next(), parts.next(), parts.next());
        if address.is_some_and(|a| out.join(a).is_dir())
            && std::fs::remove_dir_all(e.path()).is_ok()
        {
            removed += 1;
        }
    }
    removed
}
