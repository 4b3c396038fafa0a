//! Range profiles as CSV or npy: one range column (metres) and one or more value columns.

use super::{atomic::write_atomic, npy, StorageError};
use std::fmt::Write as _;
use std::path::Path;

/// A range profile table: a range axis and named columns of the same length (for example
/// `fourier_db` and `music_db`).
#[derive(Debug, Clone, PartialEq)]
pub struct ProfileTable {
    pub range_m: Vec<f64>,
    pub columns: Vec<(String, Vec<f64>)>,
}

impl ProfileTable {
    fn check(&self, path: &Path) -> Result<(), StorageError> {
        let bad = |reason: String| StorageError::BadData {
            path: path.to_path_buf(),
            reason,
        };
        if self.range_m.is_empty() {
            return Err(bad("the profile is empty".into()));
        }
        for (name, col) in &self.columns {
            if col.len() != self.range_m.len() {
                return Err(bad(format!(
                    "column {name} has {} values for {} ranges",
                    col.len(),
                    self.range_m.len()
                )));
            }
        }
        Ok(())
    }

    /// CSV with a header line `range_m,<column>...`; numbers in Rust's shortest round-trip form.
    pub(crate) fn to_csv(&self) -> String {
        let mut out = String::from("range_m");
        for (name, _) in &self.columns {
            out.push(',');
            out.push_str(name);
        }
        out.push('\n');
        for (i, r) in self.range_m.iter().enumerate() {
            let _ = write!(out, "{r}");
            for (_, col) in &self.columns {
                let _ = write!(out, ",{}", col[i]);
            }
            out.push('\n');
        }
        out
    }

    /// A float64 npy array of shape (n, 1 + columns): range first, then the columns in order.
    pub(crate) fn to_npy(&self) -> Result<Vec<u8>, String> {
        let width = 1 + self.columns.len();
        let mut data = Vec::with_capacity(self.range_m.len() * width);
        for (i, r) in self.range_m.iter().enumerate() {
            data.push(*r);
            data.extend(self.columns.iter().map(|(_, c)| c[i]));
        }
        npy::encode_f64(&[self.range_m.len(), width], &data)
    }

    /// Writes the table atomically; the format follows the extension (`.csv` or `.npy`).
    pub fn write(&self, path: &Path) -> Result<(), StorageError> {
        self.check(path)?;
        match extension(path).as_deref() {
            Some("csv") => write_atomic(path, self.to_csv().as_bytes()),
            Some("npy") => {
                let bytes = self.to_npy().map_err(|reason| StorageError::BadData {
                    path: path.to_path_buf(),
                    reason,
                })?;
                write_atomic(path, &bytes)
            }
            _ => Err(StorageError::UnsupportedFormat {
                path: path.to_path_buf(),
                allowed: "range profiles are written as .csv or .npy",
            }),
        }
    }
}

pub(crate) fn extension(path: &Path) -> Option<String> {
    path.extension()
        .map(|e| e.to_string_lossy().to_ascii_lowercase())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn table() -> ProfileTable {
        ProfileTable {
            range_m: vec![0.0, 0.015],
            columns: vec![("fourier_db".into(), vec![-3.5, 0.0])],
        }
    }

    #[test]
    fn csv_has_header_and_rows() {
        assert_eq!(table().to_csv(), "range_m,fourier_db\n0,-3.5\n0.015,0\n");
    }

    #[test]
    fn writes_by_extension_and_rejects_others() {
        let dir = tempfile::tempdir().unwrap();
        table().write(&dir.path().join("p.csv")).unwrap();
        table().write(&dir.path().join("p.npy")).unwrap();
        let npy = std::fs::read(dir.path().join("p.npy")).unwrap();
        assert_eq!(&npy[..6], b"\x93NUMPY");
        let err = table().write(&dir.path().join("p.txt")).unwrap_err();
        assert!(matches!(err, StorageError::UnsupportedFormat { .. }));
    }

    #[test]
    fn ragged_columns_are_refused() {
        let mut t = table();
        t.columns[0].1.pop();
        let dir = tempfile::tempdir().unwrap();
        assert!(t.write(&dir.path().join("p.csv")).is_err());
    }
}
