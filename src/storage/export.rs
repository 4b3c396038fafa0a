//! Named arrays for notebooks: one file of `numpy` arrays (`.npz`) or an HDF5 file (`.h5`), the
//! same names and values in both (`docs/export.md`). Names may hold `/`: a group per step in
//! HDF5, the same path as the key in an `.npz` (`data["step-001/iq"]`).
//!
//! `.npz` is written as a stream (each array as it is put); HDF5 is encoded when the file is
//! finished (the encoder needs the whole tree), so it holds every array in memory until then.

use super::atomic::AtomicFile;
use super::npy;
use super::npz::NpzWriter;
use super::StorageError;
use hdf5_writer::{
    AttributeBuilder, ByteOrder, CompoundField, DatasetBuilder, Datatype, Hdf5Builder,
    StringEncoding, StringPadding, StringSize, WriteOptions,
};
use num_complex::Complex64;
use std::path::{Path, PathBuf};

/// One array.
#[derive(Debug, Clone, PartialEq)]
pub enum Array {
    /// float64 (`<f8`), row-major.
    F64 { shape: Vec<usize>, data: Vec<f64> },
    /// complex128 (`<c16`), row-major.
    C128 {
        shape: Vec<usize>,
        data: Vec<Complex64>,
    },
    /// uint8 (`|u1`), one-dimensional.
    U8(Vec<u8>),
    /// A text (0-d unicode array in `.npz`, a UTF-8 string in HDF5).
    Text(String),
    /// A one-dimensional table of named float64 columns (a structured array in `.npz`, a
    /// compound dataset in HDF5); NaN where a value is absent.
    Records {
        rows: usize,
        fields: Vec<(&'static str, Vec<f64>)>,
    },
}

impl Array {
    /// A float64 scalar.
    pub(crate) fn scalar(x: f64) -> Array {
        Array::F64 {
            shape: Vec::new(),
            data: vec![x],
        }
    }

    /// A one-dimensional float64 array.
    pub(crate) fn f64s(data: Vec<f64>) -> Array {
        Array::F64 {
            shape: vec![data.len()],
            data,
        }
    }

    /// A one-dimensional complex128 array.
    pub(crate) fn c128s(data: Vec<Complex64>) -> Array {
        Array::C128 {
            shape: vec![data.len()],
            data,
        }
    }

    fn npy(&self, complex: ComplexDtype) -> Result<Vec<u8>, String> {
        match self {
            Array::F64 { shape, data } => npy::encode_f64(shape, data),
            Array::C128 { shape, data } => match complex {
                ComplexDtype::Complex128 => npy::encode_c128(shape, data),
                ComplexDtype::Complex64 => npy::encode_c64(shape, data),
            },
            Array::U8(data) => npy::encode_u8(&[data.len()], data),
            Array::Text(text) => Ok(npy::encode_text(text)),
            Array::Records { rows, fields } => {
                let fields: Vec<(&str, Vec<f64>)> =
                    fields.iter().map(|(n, v)| (*n, v.clone())).collect();
                npy::encode_records(*rows, &fields)
            }
        }
    }

    fn hdf5(&self, name: &str, complex: ComplexDtype) -> Result<DatasetBuilder, String> {
        let f64_type = Datatype::FloatingPoint {
            size: 8,
            byte_order: ByteOrder::LittleEndian,
        };
        let shape = |s: &[usize]| s.iter().map(|&n| n as u64).collect::<Vec<u64>>();
        let check = |shape: &[usize], len: usize| {
            let n: usize = shape.iter().product();
            (n == len)
                .then_some(())
                .ok_or_else(|| format!("shape {shape:?} holds {n} values but {len} were given"))
        };
        Ok(match self {
            Array::F64 { shape: s, data } => {
                check(s, data.len())?;
                let raw: Vec<u8> = data.iter().flat_map(|v| v.to_le_bytes()).collect();
                DatasetBuilder::new(name, f64_type, shape(s)).raw_data(raw)
            }
            Array::C128 { shape: s, data } => {
                check(s, data.len())?;
                // h5py's complex128 (complex64): a compound of float64 (float32) `r` and `i`.
                let part = complex.part_bytes();
                let part_type = Datatype::FloatingPoint {
                    size: part as u8,
                    byte_order: ByteOrder::LittleEndian,
                };
                let compound = Datatype::Compound {
                    size: 2 * part as u32,
                    fields: vec![
                        CompoundField {
                            name: "r".into(),
                            byte_offset: 0,
                            datatype: part_type.clone(),
                        },
                        CompoundField {
                            name: "i".into(),
                            byte_offset: part as u32,
                            datatype: part_type,
                        },
                    ],
                };
                let mut raw: Vec<u8> = Vec::with_capacity(data.len() * 2 * part);
                for v in data {
                    match complex {
                        ComplexDtype::Complex128 => {
                            raw.extend_from_slice(&v.re.to_le_bytes());
                            raw.extend_from_slice(&v.im.to_le_bytes());
                        }
                        ComplexDtype::Complex64 => {
                            raw.extend_from_slice(&(v.re as f32).to_le_bytes());
                            raw.extend_from_slice(&(v.im as f32).to_le_bytes());
                        }
                    }
                }
                DatasetBuilder::new(name, compound, shape(s)).raw_data(raw)
            }
            Array::U8(data) => {
                let t = Datatype::FixedPoint {
                    size: 1,
                    signed: false,
                    byte_order: ByteOrder::LittleEndian,
                };
                DatasetBuilder::new(name, t, vec![data.len() as u64]).raw_data(data.clone())
            }
            Array::Text(text) => {
                let bytes = text.as_bytes().to_vec();
                let t = Datatype::String {
                    size: StringSize::Fixed(bytes.len().max(1) as u32),
                    encoding: StringEncoding::Utf8,
                    padding: StringPadding::NullPad,
                };
                let mut raw = bytes;
                if raw.is_empty() {
                    raw.push(0);
                }
                DatasetBuilder::new(name, t, Vec::<u64>::new()).raw_data(raw)
            }
            Array::Records { rows, fields } => {
                if let Some((n, v)) = fields.iter().find(|(_, v)| v.len() != *rows) {
                    return Err(format!(
                        "field {n} holds {} values for {rows} rows",
                        v.len()
                    ));
                }
                let t = Datatype::Compound {
                    size: 8 * fields.len() as u32,
                    fields: fields
                        .iter()
                        .enumerate()
                        .map(|(k, (n, _))| CompoundField {
                            name: (*n).into(),
                            byte_offset: 8 * k as u32,
                            datatype: f64_type.clone(),
                        })
                        .collect(),
                };
                let mut raw = Vec::with_capacity(rows * fields.len() * 8);
                for r in 0..*rows {
                    for (_, v) in fields {
                        raw.extend_from_slice(&v[r].to_le_bytes());
                    }
                }
                DatasetBuilder::new(name, t, vec![*rows as u64]).raw_data(raw)
            }
        })
    }
}

/// How complex arrays are stored (`radbench export --dtype`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum ComplexDtype {
    /// float32 real and imaginary parts (`<c8`; in HDF5 a compound of float32 `r`, `i`): half
    /// the bytes, about 7 significant digits.
    Complex64,
    /// float64 parts (`<c16`), every digit radbench computed.
    #[default]
    Complex128,
}

impl ComplexDtype {
    /// Bytes of one real or imaginary part.
    fn part_bytes(self) -> usize {
        match self {
            ComplexDtype::Complex64 => 4,
            ComplexDtype::Complex128 => 8,
        }
    }
}

/// The file formats `radbench export` writes.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ExportFormat {
    Npz,
    Hdf5,
}

impl ExportFormat {
    /// The file extension, without the dot.
    pub fn extension(self) -> &'static str {
        match self {
            ExportFormat::Npz => "npz",
            ExportFormat::Hdf5 => "h5",
        }
    }
}

enum Target {
    Npz(NpzWriter<AtomicFile>),
    Hdf5(Vec<DatasetBuilder>),
}

/// An export file being written: arrays are put one after the other, the file appears (whole,
/// atomically) at [`finish`](Self::finish).
pub struct ExportWriter {
    path: PathBuf,
    target: Target,
    names: std::collections::HashSet<String>,
    complex: ComplexDtype,
}

impl ExportWriter {
    /// Starts the file `path` (a temporary file beside it until finished).
    pub fn create(path: &Path, format: ExportFormat) -> Result<Self, StorageError> {
        let target = match format {
            ExportFormat::Npz => Target::Npz(NpzWriter::new(AtomicFile::create(path)?)),
            ExportFormat::Hdf5 => {
                // Fail now, not after the processing, when the folder cannot take the file.
                drop(AtomicFile::create(path)?);
                Target::Hdf5(Vec::new())
            }
        };
        Ok(Self {
            path: path.to_path_buf(),
            target,
            names: Default::default(),
            complex: ComplexDtype::default(),
        })
    }

    /// Stores every complex array as `complex` (complex128 unless told).
    pub fn with_complex_dtype(mut self, complex: ComplexDtype) -> Self {
        self.complex = complex;
        self
    }

    fn bad(&self, reason: String) -> StorageError {
        StorageError::BadData {
            path: self.path.clone(),
            reason,
        }
    }

    /// Puts `array` as `name` (`a/b` is array `b` of group `a` in HDF5); `unit`, when given,
    /// becomes the HDF5 dataset's `units` attribute (the `.npz` has it in its metadata).
    pub(crate) fn put(
        &mut self,
        name: &str,
        array: &Array,
        unit: Option<&str>,
    ) -> Result<(), StorageError> {
        if !self.names.insert(name.to_string()) {
            return Err(self.bad(format!("{name} is put twice (a radbench bug)")));
        }
        match &mut self.target {
            Target::Npz(w) => {
                let bytes = array.npy(self.complex).map_err(|r| StorageError::BadData {
                    path: self.path.clone(),
                    reason: format!("{name}: {r}"),
                })?;
                w.add(name, &bytes)
            }
            Target::Hdf5(datasets) => {
                let mut d = array
                    .hdf5(name, self.complex)
                    .map_err(|r| StorageError::BadData {
                        path: self.path.clone(),
                        reason: format!("{name}: {r}"),
                    })?;
                if let Some(u) = unit {
                    d = d.attribute(AttributeBuilder::fixed_string("units", u));
                }
                datasets.push(d);
                Ok(())
            }
        }
    }

    /// Writes what is left and puts the file in place.
    pub fn finish(self) -> Result<PathBuf, StorageError> {
        match self.target {
            Target::Npz(w) => w.finish()?.commit()?,
            Target::Hdf5(datasets) => {
                let bad = |e: hdf5_writer::Error| StorageError::BadData {
                    path: self.path.clone(),
                    reason: format!("HDF5 encoder: {e}"),
                };
                let builder = datasets
                    .into_iter()
                    .fold(Hdf5Builder::new(), |b, d| b.dataset(d));
                let bytes = builder
                    .into_plan()
                    .and_then(|plan| plan.encode(WriteOptions::default()))
                    .map_err(bad)?;
                super::atomic::write_atomic(&self.path, &bytes)?;
            }
        }
        Ok(self.path)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn hdf5_files_start_with_the_signature_and_npz_with_a_local_header() {
        let dir = tempfile::tempdir().unwrap();
        for format in [ExportFormat::Npz, ExportFormat::Hdf5] {
            let path = dir.path().join(format!("x.{}", format.extension()));
            let mut w = ExportWriter::create(&path, format).unwrap();
            w.put(
                "a/iq",
                &Array::c128s(vec![Complex64::new(1.0, -1.0)]),
                Some("V"),
            )
            .unwrap();
            w.put("text", &Array::Text("µ".into()), None).unwrap();
            w.put(
                "t",
                &Array::Records {
                    rows: 1,
                    fields: vec![("range_m", vec![1.0]), ("snr_db", vec![f64::NAN])],
                },
                None,
            )
            .unwrap();
            assert!(w.put("text", &Array::U8(vec![1]), None).is_err());
            let written = w.finish().unwrap();
            let bytes = std::fs::read(&written).unwrap();
            match format {
                ExportFormat::Npz => assert_eq!(&bytes[..4], b"PK\x03\x04"),
                ExportFormat::Hdf5 => assert_eq!(&bytes[..8], b"\x89HDF\r\n\x1a\n"),
            }
            // Nothing but the file itself is left in the folder.
            let names: Vec<_> = std::fs::read_dir(dir.path())
                .unwrap()
                .map(|e| e.unwrap().file_name())
                .collect();
            assert!(names.iter().all(|n| !n.to_string_lossy().starts_with('.')));
        }
    }

    #[test]
    fn a_ragged_array_is_refused() {
        let dir = tempfile::tempdir().unwrap();
        let mut w = ExportWriter::create(&dir.path().join("x.npz"), ExportFormat::Npz).unwrap();
        let ragged = Array::F64 {
            shape: vec![2, 2],
            data: vec![1.0],
        };
        assert!(w.put("x", &ragged, None).is_err());
    }
}
