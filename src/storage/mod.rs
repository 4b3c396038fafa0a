//! Outputs: atomic file writes, SigMF recordings, npy and CSV range profiles, range-profile
//! plots (SVG/PNG), named arrays for notebooks (`export`: `.npz`, HDF5); and the readers of
//! recorded captures (`recording`: SigMF, `.trc`).
//!
//! Every writer goes through `atomic::write_atomic`: the bytes go to a temporary file in the
//! destination's folder, which is then renamed over the destination, so a reader never sees half a
//! file and an interrupted run keeps everything it had already written.

use crate::exit::{Classify, ExitClass};
use std::path::PathBuf;

pub(crate) mod atomic;
pub(crate) mod cache;
pub(crate) mod export;
pub(crate) mod hash;
pub(crate) mod npy;
pub(crate) mod npz;
pub(crate) mod plot;
pub(crate) mod profile;
pub(crate) mod recording;
pub(crate) mod sigmf;

pub(crate) use atomic::write_group;
pub use atomic::{write_atomic, write_group_open, GroupWritten, OpenGroup, WrittenFile};
pub use export::{Array, ComplexDtype, ExportFormat, ExportWriter};
pub use hash::sha256;
pub(crate) use hash::sha256_file;
pub use npy::encode_c128;
pub use plot::{draw, draw_ber, BerSeries, Curve, LineStyle, Marker, ProfilePlot};
pub use recording::{
    read_sigmf, read_trc, CaptureSegment, Component, Datatype, Extension, RadbenchMeta, Recording,
    RecordingError, SampleUnit,
};
pub use sigmf::utc_now_rfc3339;

/// Why an output could not be written.
#[derive(Debug, thiserror::Error)]
pub enum StorageError {
    /// The file system refused (missing folder, permissions, read-only, disk full).
    #[error("cannot write {path}: {source} ({})", remedy(source))]
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

/// What to do when a write failed with `e`. A read-only file system and a full disk need other
/// remedies than a missing folder: "check that the folder exists and is writable" sent the user
/// looking for a folder that was there.
pub(crate) fn remedy(e: &std::io::Error) -> &'static str {
    full_or_read_only(e).unwrap_or("check that the folder exists and is writable")
}

/// [`remedy`] for the two failures that say what to do by themselves: a read-only file system
/// and a full disk (or quota).
pub(crate) fn full_or_read_only(e: &std::io::Error) -> Option<&'static str> {
    match e.raw_os_error()? {
        libc::EROFS => Some("its file system is read-only: remount it read-write"),
        libc::ENOSPC | libc::EDQUOT => Some("its disk is full: free space on it"),
        _ => None,
    }
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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_read_only_file_system_and_a_full_disk_say_what_to_do() {
        let err = |code| std::io::Error::from_raw_os_error(code);
        let write = |code| {
            StorageError::Io {
                path: "run/results.json".into(),
                source: err(code),
            }
            .to_string()
        };
        assert!(
            write(libc::EROFS).contains("(its file system is read-only: remount it read-write)")
        );
        assert!(write(libc::ENOSPC).contains("(its disk is full: free space on it)"));
        assert!(write(libc::EDQUOT).contains("(its disk is full: free space on it)"));
        assert!(write(libc::ENOENT).contains("(check that the folder exists and is writable)"));
        assert_eq!(full_or_read_only(&err(libc::EACCES)), None);
    }
}
