//! Opening the catalog: WAL mode (readers never wait for the writer, a killed writer leaves the
//! last committed state), the schema created when missing, a busy timeout.

use super::RunsDbError;
use rusqlite::Connection;
use std::path::{Path, PathBuf};
use std::time::Duration;

/// The schema, plain SQL (docs/catalog.md documents it).
pub(crate) const SCHEMA_SQL: &str = include_str!("schema.sql");

/// The schema's version, in the `meta` table: a catalog of another version is rebuilt.
pub(crate) const SCHEMA_VERSION: &str = "2";

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
    let conn = Connection::open(path).map_err(sql)?;
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
    let version: Option<String> = conn
        .query_row(
            "SELECT value FROM meta WHERE key = 'schema_version'",
            [],
            |r| r.get(0),
        )
        .ok();
    if version.as_deref() != Some(SCHEMA_VERSION) {
        conn.execute_batch(SCHEMA_SQL).map_err(sql)?;
        conn.execute(
            "INSERT INTO meta (key, value) VALUES ('schema_version', ?1)
             ON CONFLICT (key) DO UPDATE SET value = excluded.value",
            [SCHEMA_VERSION],
        )
        .map_err(sql)?;
    }
    Ok(conn)
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
