//! Outputs: atomic file writes, SigMF recordings, npy and CSV range profiles, and range-profile
//! plots (SVG/PNG); and the readers of recorded captures ([`recording`]: SigMF, `.trc`).
//!
//! Every writer goes through `atomic::write_atomic`: the bytes go to a temporary file in the
//! destination's folder, which is then renamed over the destination, so a reader never sees half a
//! file and an interrupted run keeps everything it had already written.

use crate::exit::{Classify, ExitClass};
use std::path::PathBuf;

pub(crate) mod atomic;
pub mod hash;
pub(crate) mod npy;
pub(crate) mod plot;
pub(crate) mod profile;
pub mod recording;
pub(crate) mod sigmf;

/// Why an output could not be written.
#[derive(Debug, thiserror::Error)]
pub enum StorageError {
    /// The file system refused (missing folder, permissions, disk full).
    #[error("cannot write {path}: {source} (check that the folder exists and is writable)")]
    Io {
        path: PathBuf,
        #[source]
        source: std::io::Error,
    },
    /// The file name asks for a format radbench does not write.
    #[error("{path}: unsupported output format; {allowed}")]
    UnsupportedFormat {
        path: PathBuf,
        allowed: &'static str,
    },
    /// The data handed to a writer is inconsistent (a caller bug or an empty result).
    #[error("cannot write {path}: {reason}")]
    BadData { path: PathBuf, reason: String },
    /// The plotting library failed while drawing.
    #[error("cannot draw {path}: {reason}")]
    Plot { path: PathBuf, reason: String },
}

impl Classify for StorageError {
    fn exit_class(&self) -> ExitClass {
        match self {
            StorageError::UnsupportedFormat { .. } => ExitClass::BadInput,
            StorageError::Io { .. } | StorageError::BadData { .. } | StorageError::Plot { .. } => {
                ExitClass::Processing
            }
        }
    }
}
