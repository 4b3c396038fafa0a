//! Opening the catalog: WAL mode (readers never wait for the writer, a killed writer leaves the
//! last committed state), the schema created when missing, a busy timeout.

use super::RunsDbError;
use rusqlite::Connection;
use std::path::{Path, PathBuf};
use std::time::Duration;

/// The schema, plain SQL (docs/catalog.md documents it).
pub(crate) const SCHEMA_SQL: &str = include_str!("schema.sql");

/// The schema's version, in the `meta` table: an older catalog is upgraded in place when opened
/// (2: the `processed` table; 3: `runs.max_abs_error_m` and the newest-first index).
pub(crate) const SCHEMA_VERSION: &str = "3";

/// The catalog's file name in a runs folder.
pub(crate) const CATALOG_FILE: &str = "catalog.sqlite";

/// The default catalog: `runs/catalog.sqlite` (the folder radbench writes its runs in by default).
pub fn default_catalog() -> PathBuf {
    Path::new("runs").join(CATALOG_FILE)
}

/// The catalog at `path`, created with its schema when missing. `busy` bounds how long a write
/// waits for another writer before it gives up.
pub(crate) fn open(path: &Path, busy: Duration) -> Result<Connection, RunsDbError> {
    let sql = |e| RunsDbError::sql(path, e);
    if let Some(parent) = path.parent().filter(|p| !p.as_os_str().is_empty()) {
        std::fs::create_dir_all(parent).map_err(|e| RunsDbError::io(parent, e))?;
    }
    let mut conn = Connection::open(path).map_err(sql)?;
    conn.busy_timeout(busy).map_err(sql)?;
    // WAL: readers see the last commit while a writer works; NORMAL: a commit is durable at the
    // next checkpoint (a power loss may lose the last commits, never the file: the folders stay
    // the truth and the next `runs index` restores them).
    conn.pragma_update(None, "journal_mode", "WAL")
        .map_err(sql)?;
    conn.pragma_update(None, "synchronous", "NORMAL")
        .map_err(sql)?;
    conn.pragma_update(None, "foreign_keys", "ON")
        .map_err(sql)?;
    if older(stored_version(&conn).as_deref()) {
        upgrade(&mut conn).map_err(sql)?;
    }
    Ok(conn)
}

/// Whether a catalog of `stored` version (`None`: a new file) needs [`upgrade`]: a catalog a newer
/// radbench wrote is left as it is (its tables hold ours; writing our version would make the
/// newer one think it old).
fn older(stored: Option<&str>) -> bool {
    let ours: u32 = SCHEMA_VERSION.parse().unwrap_or(0);
    stored
        .and_then(|v| v.parse::<u32>().ok())
        .is_none_or(|v| v < ours)
}

fn stored_version(conn: &Connection) -> Option<String> {
    conn.query_row(
        "SELECT value FROM meta WHERE key = 'schema_version'",
        [],
        |r| r.get(0),
    )
    .ok()
}

/// Creates what is missing and brings an older catalog's tables to this version, in one
/// transaction that holds the write lock: two processes opening an old catalog at once upgrade
/// it once.
fn upgrade(conn: &mut Connection) -> rusqlite::Result<()> {
    let tx = conn.transaction_with_behavior(rusqlite::TransactionBehavior::Immediate)?;
    if !older(stored_version(&tx).as_deref()) {
        return Ok(());
    }
    tx.execute_batch(SCHEMA_SQL)?;
    let has_headline: bool = tx.query_row(
        "SELECT count(*) FROM pragma_table_info('runs') WHERE name = 'max_abs_error_m'",
        [],
        |r| r.get::<_, i64>(0).map(|n| n > 0),
    )?;
    if !has_headline {
        tx.execute_batch(
            "ALTER TABLE runs ADD COLUMN max_abs_error_m REAL;
             UPDATE runs SET max_abs_error_m = (SELECT value FROM run_metrics m
               WHERE m.run_id = runs.run_id AND m.name = 'max_abs_error_m');",
        )?;
    }
    tx.execute_batch("DROP INDEX IF EXISTS runs_by_created;")?;
    tx.execute(
        "INSERT INTO meta (key, value) VALUES ('schema_version', ?1)
         ON CONFLICT (key) DO UPDATE SET value = excluded.value",
        [SCHEMA_VERSION],
    )?;
    tx.commit()
}

/// The catalog at `path` for reading: it must exist. Its pages are read through a memory map
/// (up to 256 MiB), not a `read` call each: a query over 10 000 runs touches thousands of pages
/// (docs/catalog.md, "Speed"). Only readers map it: a file cut short under a mapping would
/// kill the process, which a query may risk and a campaign's registration may not.
pub(crate) fn open_existing(path: &Path) -> Result<Connection, RunsDbError> {
    if !path.is_file() {
        return Err(RunsDbError::Missing {
            path: path.to_path_buf(),
        });
    }
    let conn = open(path, Duration::from_secs(5))?;
    conn.pragma_update(None, "mmap_size", READ_MAP_BYTES)
        .map_err(|e| RunsDbError::sql(path, e))?;
    Ok(conn)
}

/// How much of the catalog a reader maps.
const READ_MAP_BYTES: i64 = 256 << 20;

/// Whether `e` says the file is not a database or is damaged (then `runs index` rebuilds it).
pub(crate) fn is_corrupt(e: &rusqlite::Error) -> bool {
    matches!(
        e.sqlite_error_code(),
        Some(rusqlite::ErrorCode::NotADatabase | rusqlite::ErrorCode::DatabaseCorrupt)
    )
}

/// Moves a damaged catalog (and its WAL files) aside as `<name>.corrupt`, so a new one can be
/// built from the folders; the old one stays for whoever wants to look at it.
pub(crate) fn set_aside(path: &Path) -> Result<PathBuf, RunsDbError> {
    let aside = path.with_extension("sqlite.corrupt");
    std::fs::rename(path, &aside).map_err(|e| RunsDbError::io(path, e))?;
    for suffix in ["-wal", "-shm"] {
        let mut side = path.as_os_str().to_owned();
        side.push(suffix);
        let _ = std::fs::remove_file(PathBuf::from(side));
    }
    Ok(aside)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A catalog of schema 2 (no headline column) gains it, filled from `run_metrics`, when
    /// opened; opening it again changes nothing.
    #[test]
    fn a_version_2_catalog_is_upgraded_in_place() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join(CATALOG_FILE);
        let conn = open(&path, Duration::from_secs(1)).unwrap();
        conn.execute_batch(
            "DROP INDEX runs_newest_first;
             ALTER TABLE runs DROP COLUMN max_abs_error_m;
             CREATE INDEX runs_by_created ON runs (created);
             UPDATE meta SET value = '2' WHERE key = 'schema_version';
             INSERT INTO runs (run_id, dir, name, status, created, updated, radbench_version,
               simulated, waveforms, algorithms, steps_total, steps_done, manifest_sha256)
             VALUES ('r1', 'runs/r1', 'accuracy', 'complete', '2026-12-01T00:00:00Z',
               '2026-12-01T00:00:00Z', '0', 1, 'msk-lfm', 'correlation', 5, 5, 'ab'),
               ('r2', 'runs/r2', 'accuracy', 'complete', '2026-12-02T00:00:00Z',
               '2026-12-02T00:00:00Z', '0', 1, 'msk-lfm', 'correlation', 5, 5, 'cd');
             INSERT INTO run_metrics (run_id, name, value) VALUES ('r1', 'max_abs_error_m', 2e-4),
               ('r1', 'missed', 0), ('r2', 'missed', 1);",
        )
        .unwrap();
        drop(conn);
        for _ in 0..2 {
            let conn = open(&path, Duration::from_secs(1)).unwrap();
            assert_eq!(stored_version(&conn).as_deref(), Some(SCHEMA_VERSION));
            let headline: Vec<(String, Option<f64>)> = conn
                .prepare("SELECT run_id, max_abs_error_m FROM runs ORDER BY run_id")
                .unwrap()
                .query_map([], |r| Ok((r.get(0)?, r.get(1)?)))
                .unwrap()
                .collect::<Result<_, _>>()
                .unwrap();
            assert_eq!(
                headline,
                [("r1".to_string(), Some(2e-4)), ("r2".to_string(), None)]
            );
            let indexes: Vec<String> = conn
                .prepare(
                    "SELECT name FROM sqlite_master WHERE type = 'index' AND tbl_name = 'runs'",
                )
                .unwrap()
                .query_map([], |r| r.get(0))
                .unwrap()
                .collect::<Result<_, _>>()
                .unwrap();
            assert!(
                indexes.contains(&"runs_newest_first".to_string()),
                "{indexes:?}"
            );
            assert!(
                !indexes.contains(&"runs_by_created".to_string()),
                "{indexes:?}"
            );
        }
    }
}
