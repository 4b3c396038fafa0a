//! The run catalog: one SQLite file (`catalog.sqlite` in the runs folder, WAL mode) indexing
//! every campaign run folder and capture folder: runs, steps, captures, targets, calibrations,
//! instruments and files with their SHA-256. The folders stay the truth: the catalog is built
//! from them (`radbench runs index`), kept up to date as the commands write them (off their
//! path: [`Registrar`]) and can be deleted and rebuilt at any time. The schema is plain SQL
//! (`src/runs_db/schema.sql`, docs/catalog.md), for `sqlite3`, pandas or DuckDB as much as for `radbench
//! runs`.

use crate::exit::{Classify, ExitClass};
use std::path::{Path, PathBuf};

pub(crate) mod db;
pub(crate) mod index;
pub(crate) mod processed;
pub(crate) mod query;
pub(crate) mod record;
pub(crate) mod register;

pub use db::default_catalog;
pub use index::{index, FailedFolder, IndexReport};
pub(crate) use processed::known_sha256;
pub use processed::{record_processed, ProcessedRow};
pub(crate) use query::parse_query;
pub use query::{
    captures, parse_time, parse_where, run_detail, runs, trend, AssetRow, CaptureRow, Condition,
    Op, RunDetail, RunFilter, RunRow, StepRow, TrendPoint,
};
pub use record::{run_id, METRIC_NAMES};
pub use register::{catalog_for, Registrar};

/// Why the catalog could not be read or written.
#[derive(Debug, thiserror::Error)]
pub enum RunsDbError {
    #[error("{path}: {source}")]
    Io {
        path: PathBuf,
        #[source]
        source: std::io::Error,
    },
    #[error("catalog {path}: {source}")]
    Sql {
        path: PathBuf,
        #[source]
        source: rusqlite::Error,
    },
    #[error("{path}: {reason}")]
    Folder { path: PathBuf, reason: String },
    #[error("no catalog at {path}: `radbench runs index DIR` builds it (or give --catalog FILE)")]
    Missing { path: PathBuf },
    #[error("{path} is not a folder: give folders holding run or capture folders")]
    NotAFolder { path: PathBuf },
    #[error("{field}: {reason}")]
    BadInput { field: String, reason: String },
}

impl RunsDbError {
    pub(crate) fn io(path: &Path, source: std::io::Error) -> RunsDbError {
        RunsDbError::Io {
            path: path.to_path_buf(),
            source,
        }
    }

    pub(crate) fn sql(path: &Path, source: rusqlite::Error) -> RunsDbError {
        RunsDbError::Sql {
            path: path.to_path_buf(),
            source,
        }
    }
}

impl Classify for RunsDbError {
    fn exit_class(&self) -> ExitClass {
        match self {
            RunsDbError::Missing { .. }
            | RunsDbError::NotAFolder { .. }
            | RunsDbError::BadInput { .. } => ExitClass::BadInput,
            RunsDbError::Io { .. } | RunsDbError::Sql { .. } | RunsDbError::Folder { .. } => {
                ExitClass::Processing
            }
        }
    }
}
