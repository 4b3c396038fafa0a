//! What archive processing reads from the catalog and writes back: the SHA-256 the catalog
//! holds for an input's files (hashed again only when a file changed since it was indexed), and
//! the `processed` rows naming each content-addressed output.

use super::db;
use super::index::path_text;
use super::RunsDbError;
use rusqlite::{params, OptionalExtension};
use std::collections::HashMap;
use std::os::unix::fs::MetadataExt;
use std::path::{Path, PathBuf};
use std::time::Duration;

/// The SHA-256 of each of `files` that the catalog's `assets` table holds for the file as it is
/// now (same size and, when recorded, same modification time). Files it has not, or has for an
/// older content, are left out: the caller hashes them.
pub(crate) fn known_sha256(
    catalog: &Path,
    files: &[PathBuf],
) -> Result<HashMap<PathBuf, String>, RunsDbError> {
    let conn = db::open_existing(catalog)?;
    let sql = |e| RunsDbError::sql(catalog, e);
    let mut q = conn
        .prepare("SELECT bytes, mtime_ns, sha256 FROM assets WHERE path = ?1")
        .map_err(sql)?;
    let mut out = HashMap::new();
    for f in files {
        let Ok(meta) = std::fs::metadata(f) else {
            continue;
        };
        let row: Option<(i64, Option<i64>, String)> = q
            .query_row([path_text(f)], |r| Ok((r.get(0)?, r.get(1)?, r.get(2)?)))
            .optional()
            .map_err(sql)?;
        let mtime_ns = meta.mtime() * 1_000_000_000 + meta.mtime_nsec();
        if let Some((bytes, recorded_mtime, sha)) = row {
            if bytes == meta.len() as i64 && recorded_mtime.is_none_or(|m| m == mtime_ns) {
                out.insert(f.clone(), sha);
            }
        }
    }
    Ok(out)
}

/// One content-addressed output of archive processing.
#[derive(Debug, Clone, serde::Serialize, PartialEq)]
pub struct ProcessedRow {
    pub input_sha256: String,
    pub options_sha256: String,
    pub radbench_version: String,
    pub out_dir: PathBuf,
    pub input_dir: PathBuf,
    /// The processing options as the output's address hashed them.
    pub options: String,
}

/// How long registering outputs waits for another writer of the catalog.
const BUSY: Duration = Duration::from_secs(2);

/// Writes `rows` into the catalog's `processed` table in one transaction (a row already there
/// is replaced: registering twice adds nothing).
pub fn record_processed(catalog: &Path, rows: &[ProcessedRow]) -> Result<(), RunsDbError> {
    if rows.is_empty() {
        return Ok(());
    }
    let mut conn = db::open(catalog, BUSY)?;
    let sql = |e| RunsDbError::sql(catalog, e);
    let tx = conn
        .transaction_with_behavior(rusqlite::TransactionBehavior::Immediate)
        .map_err(sql)?;
    {
        let mut q = tx
            .prepare(
                "INSERT OR REPLACE INTO processed (input_sha256, options_sha256, radbench_version,
                   out_dir, input_dir, options) VALUES (?1, ?2, ?3, ?4, ?5, ?6)",
            )
            .map_err(sql)?;
        for r in rows {
            q.execute(params![
                r.input_sha256,
                r.options_sha256,
                r.radbench_version,
                path_text(&super::record::absolute(&r.out_dir)),
                path_text(&r.input_dir),
                r.options,
            ])
            .map_err(sql)?;
        }
    }
    tx.commit().map_err(sql)
}
