//! Reading captures back: SigMF recordings (radbench's own and other tools') and LeCroy `.trc`
//! files, for re-processing long after the bench is gone.
//!
//! SigMF: complex datatypes `ci8`, `cu8`, `ci16`, `cu16`, `ci32`, `cu32`, `cf32`, `cf64`, little
//! (`_le`) or big (`_be`) endian. The samples come back as `Complex64` in volts when radbench's
//! namespace gives the scaling (`radbench:vertical_gain`/`vertical_offset`, per channel:
//! `volts = gain * word - offset`), otherwise in the datatype's native scale (integer codes as
//! they are, floats as they are; no autoscaling to +-1). Captures' `core:header_bytes`, the global
//! `core:trailing_bytes`, `core:dataset` (a data file of another name) and `core:sha512` are
//! honoured; multi-channel recordings (`core:num_channels` > 1) are refused. Every error names the file and the field; all of them are bad input (exit code 2).

use std::path::{Path, PathBuf};

use bytes::Bytes;
use num_complex::Complex64;
use serde_json::{Map, Value};
use sha2::{Digest, Sha512};

use crate::exit::{Classify, ExitClass};
use crate::trc::{Trace, TrcError};

mod datatype;
pub use datatype::{Component, Datatype};

/// Why a recording or `.trc` file cannot be read.
#[derive(Debug, thiserror::Error)]
pub enum RecordingError {
    #[error("cannot read {path}: {source}")]
    Io {
        path: PathBuf,
        #[source]
        source: std::io::Error,
    },
    #[error("{path}: {source}")]
    Trc {
        path: PathBuf,
        #[source]
        source: TrcError,
    },
    #[error("{path}: not SigMF metadata (JSON): {source}")]
    NotJson {
        path: PathBuf,
        #[source]
        source: serde_json::Error,
    },
    #[error("{path}: `{field}` {reason}")]
    Field {
        path: PathBuf,
        field: String,
        reason: String,
    },
    #[error("{path}: `core:datatype` {value:?} is not supported: {reason}; radbench reads complex recordings: ci8, cu8, ci16, cu16, ci32, cu32, cf32, cf64 (multi-byte types with _le or _be)")]
    Datatype {
        path: PathBuf,
        value: String,
        reason: &'static str,
    },
    #[error("{path}: {bytes} bytes of samples is not a whole number of {datatype} samples ({sample_bytes} bytes each); the data file is truncated or not this recording's")]
    DataLength {
        path: PathBuf,
        bytes: u64,
        datatype: String,
        sample_bytes: u64,
    },
    #[error("{path}: the data does not match `core:sha512` of {meta}: the data file changed or is not this recording's")]
    Sha512 { path: PathBuf, meta: PathBuf },
    #[error("{meta}: its data file {data} cannot be read: {source}")]
    MissingData {
        meta: PathBuf,
        data: PathBuf,
        #[source]
        source: std::io::Error,
    },
    #[error("{path}: a SigMF archive (.sigmf, a tar file); extract it (`tar xf`) and give the .sigmf-meta")]
    Archive { path: PathBuf },
}

impl RecordingError {
    /// The file the error is about (for a missing data file: the metadata naming it).
    pub fn path(&self) -> &Path {
        match self {
            RecordingError::Io { path, .. }
            | RecordingError::Trc { path, .. }
            | RecordingError::NotJson { path, .. }
            | RecordingError::Field { path, .. }
            | RecordingError::Datatype { path, .. }
            | RecordingError::DataLength { path, .. }
            | RecordingError::Sha512 { path, .. }
            | RecordingError::Archive { path } => path,
            RecordingError::MissingData { meta, .. } => meta,
        }
    }
}

impl Classify for RecordingError {
    fn exit_class(&self) -> ExitClass {
        ExitClass::BadInput
    }
}

/// Reads a `.trc` file (see `Trace::from_file_bytes` for what is accepted).
pub fn read_trc(path: &Path) -> Result<Trace, RecordingError> {
    let bytes = std::fs::read(path).map_err(|source| RecordingError::Io {
        path: path.to_path_buf(),
        source,
    })?;
    Trace::from_file_bytes(Bytes::from(bytes)).map_err(|source| RecordingError::Trc {
        path: path.to_path_buf(),
        source,
    })
}

/// What the samples of a [`Recording`] are in.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum SampleUnit {
    /// Volts at the scope input (radbench's gain and offset applied).
    Volts,
    /// The datatype's own values (integer codes, or floats as stored).
    Native,
}

/// A `core:extensions` entry.
#[derive(Debug, Clone, PartialEq, Eq, serde::Serialize)]
pub struct Extension {
    pub name: String,
    pub version: String,
    pub optional: bool,
}

/// One `captures` segment.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct CaptureSegment {
    pub sample_start: u64,
    pub frequency_hz: Option<f64>,
    pub datetime: Option<String>,
}

/// The `radbench:` namespace of a recording radbench wrote (keys without the prefix).
#[derive(Debug, Clone, PartialEq)]
pub struct RadbenchMeta {
    /// Volts per code of I and Q (`radbench:vertical_gain`).
    pub vertical_gain: Option<[f64; 2]>,
    /// Offsets of I and Q, volts (`radbench:vertical_offset`).
    pub vertical_offset: Option<[f64; 2]>,
    /// Time from the marker edge to the first sample, seconds (`radbench:trigger_offset_s`).
    pub trigger_offset_s: Option<f64>,
    /// The bench's fixed delay the capture was processed with (`radbench:system_delay_s`).
    pub system_delay_s: Option<f64>,
    /// Every `radbench:` key, prefix removed: `waveform`, `processing`, `sample_rates_hz`,
    /// `instruments`, `scene`, `bench_file`, ...
    pub keys: Map<String, Value>,
}

impl RadbenchMeta {
    /// The waveform that was transmitted (`radbench:waveform`).
    pub fn waveform(&self) -> Option<&Value> {
        self.keys.get("waveform")
    }
    /// The processing options of the capture (`radbench:processing`).
    pub fn processing(&self) -> Option<&Value> {
        self.keys.get("processing")
    }
}

/// A SigMF recording, read.
#[derive(Debug, Clone)]
pub struct Recording {
    pub meta_path: PathBuf,
    pub data_path: PathBuf,
    pub datatype: Datatype,
    /// `core:sample_rate`, Sa/s (optional in SigMF).
    pub sample_rate_hz: Option<f64>,
    /// `core:version`, `core:description`, `core:hw`, `core:recorder`.
    pub version: Option<String>,
    pub description: Option<String>,
    pub hw: Option<String>,
    pub recorder: Option<String>,
    pub extensions: Vec<Extension>,
    pub captures: Vec<CaptureSegment>,
    /// Whether `core:sha512` was present (and matched).
    pub sha512_checked: bool,
    /// Present when the recording has `radbench:` keys.
    pub radbench: Option<RadbenchMeta>,
    pub unit: SampleUnit,
    /// The samples, I + jQ, in `unit`.
    pub samples: Vec<Complex64>,
}

impl Recording {
    /// `core:datetime` of the first capture segment.
    pub fn datetime(&self) -> Option<&str> {
        self.captures.first().and_then(|c| c.datetime.as_deref())
    }
    /// `core:frequency` of the first capture segment, Hz.
    pub fn frequency_hz(&self) -> Option<f64> {
        self.captures.first().and_then(|c| c.frequency_hz)
    }
}

/// `base.sigmf-meta` and `base.sigmf-data` for a path naming either file or their common base.
pub(crate) fn sigmf_paths(path: &Path) -> Result<(PathBuf, PathBuf), RecordingError> {
    let text = path.as_os_str().to_string_lossy();
    if text.ends_with(".sigmf") {
        return Err(RecordingError::Archive {
            path: path.to_path_buf(),
        });
    }
    let base = text
        .strip_suffix(".sigmf-meta")
        .or_else(|| text.strip_suffix(".sigmf-data"))
        .unwrap_or(&text);
    Ok((
        PathBuf::from(format!("{base}.sigmf-meta")),
        PathBuf::from(format!("{base}.sigmf-data")),
    ))
}

/// Field access that names the metadata file and the key in every error.
struct Fields<'a> {
    path: &'a Path,
}

impl Fields<'_> {
    fn err(&self, field: &str, reason: impl Into<String>) -> RecordingError {
        RecordingError::Field {
            path: self.path.to_path_buf(),
            field: field.to_string(),
            reason: reason.into(),
        }
    }
    fn text(&self, obj: &Map<String, Value>, key: &str) -> Result<Option<String>, RecordingError> {
        match obj.get(key) {
            None | Some(Value::Null) => Ok(None),
            Some(Value::String(s)) => Ok(Some(s.clone())),
            Some(v) => Err(self.err(key, format!("must be text, found {v}"))),
        }
    }
    fn number(&self, obj: &Map<String, Value>, key: &str) -> Result<Option<f64>, RecordingError> {
        match obj.get(key) {
            None | Some(Value::Null) => Ok(None),
            Some(v) => match v.as_f64() {
                Some(x) if x.is_finite() => Ok(Some(x)),
                _ => Err(self.err(key, format!("must be a finite number, found {v}"))),
            },
        }
    }
    /// [`Fields::number`] within `-limit ..= limit` (a time a scope or a bench can have, not
    /// 1e300 s).
    fn within(
        &self,
        obj: &Map<String, Value>,
        key: &str,
        limit: f64,
        unit: &str,
    ) -> Result<Option<f64>, RecordingError> {
        match self.number(obj, key)? {
            Some(x) if x.abs() > limit => Err(self.err(
                key,
                format!("must lie within -{limit:e} ..= {limit:e} {unit}, found {x:e}"),
            )),
            other => Ok(other),
        }
    }
    fn count(&self, obj: &Map<String, Value>, key: &str) -> Result<u64, RecordingError> {
        match obj.get(key) {
            None | Some(Value::Null) => Ok(0),
            Some(v) => v
                .as_u64()
                .ok_or_else(|| self.err(key, format!("must be a whole number >= 0, found {v}"))),
        }
    }
    /// `[I, Q]` from a two-element array (or one number for both channels).
    fn pair(
        &self,
        obj: &Map<String, Value>,
        key: &str,
    ) -> Result<Option<[f64; 2]>, RecordingError> {
        let finite = |v: &Value| v.as_f64().filter(|x| x.is_finite());
        match obj.get(key) {
            None | Some(Value::Null) => Ok(None),
            Some(Value::Array(a)) if a.len() == 2 => match (finite(&a[0]), finite(&a[1])) {
                (Some(i), Some(q)) => Ok(Some([i, q])),
                _ => Err(self.err(key, "must hold two finite numbers [I, Q]")),
            },
            Some(v) => finite(v).map(|x| Some([x, x])).ok_or_else(|| {
                self.err(
                    key,
                    format!("must be [I, Q] (two finite numbers), found {v}"),
                )
            }),
        }
    }
}

/// Reads a SigMF recording; `path` names the `.sigmf-meta`, the `.sigmf-data` or their base.
pub fn read_sigmf(path: &Path) -> Result<Recording, RecordingError> {
    read(path, None).map(|r| r.recording)
}

/// A SigMF recording read for processing again: as [`read_sigmf`] reads it, except that the
/// 16-bit words of a `ci16` recording are kept as they are (`recording.samples` is then empty):
/// converting them to volts is left to whoever reads them, with the same arithmetic (`gain *
/// f64::from(word) - offset`, the recording's scaling).
#[derive(Debug)]
pub(crate) struct StoredRecording {
    pub recording: Recording,
    /// I and Q of a `ci16` recording (either byte order), in native scale.
    pub words: Option<(Vec<i16>, Vec<i16>)>,
    /// SHA-256 of the metadata file and of the data file, of the bytes read (each file is read
    /// once).
    pub sha256: [(PathBuf, String); 2],
}

/// [`StoredRecording`] of `path` (as [`read_sigmf`] names it).
///
/// `recorded_sha256` is the data file's SHA-256 as recorded when it was written (a run
/// manifest's), if known. The data is checked against it when given: when it matches, the data
/// is the bytes that were written and `core:sha512` is not computed again (the data is hashed
/// once instead of twice; `sha512_checked` is then false). Otherwise, as [`read_sigmf`],
/// against `core:sha512`.
pub(crate) fn read_sigmf_stored(
    path: &Path,
    recorded_sha256: Option<&str>,
) -> Result<StoredRecording, RecordingError> {
    read(path, Some(recorded_sha256))
}

/// [`read_sigmf`], keeping a `ci16` recording's words and hashing the files when `stored`
/// (with the data's recorded SHA-256, if known).
fn read(path: &Path, stored: Option<Option<&str>>) -> Result<StoredRecording, RecordingError> {
    let (meta_path, default_data) = sigmf_paths(path)?;
    let (doc, meta_bytes) = read_meta(&meta_path)?;
    let f = Fields { path: &meta_path };
    let global = doc
        .get("global")
        .and_then(Value::as_object)
        .ok_or_else(|| f.err("global", "is missing or not an object"))?;
    let (datatype, sample_rate_hz) = stream_format(&f, global)?;
    let data_path = match f.text(global, "core:dataset")? {
        Some(name) => meta_path.with_file_name(name),
        None => default_data,
    };
    let extensions = read_extensions(&f, global)?;
    let captures = read_captures(&f, &doc)?;
    let header_bytes = read_header_bytes(&f, &doc)?;
    let trailing = f.count(global, "core:trailing_bytes")?;
    let radbench = read_radbench(&f, global)?;

    let data = std::fs::read(&data_path).map_err(|source| RecordingError::MissingData {
        meta: meta_path.clone(),
        data: data_path.clone(),
        source,
    })?;
    let data_sha256 = stored.map(|_| super::hash::sha256(&data));
    let recorded_matches = match (stored.flatten(), &data_sha256) {
        (Some(recorded), Some(actual)) => recorded.trim().eq_ignore_ascii_case(actual),
        _ => false,
    };
    let sha512_checked = match f.text(global, "core:sha512")? {
        Some(_) if recorded_matches => false,
        Some(expected) if !sha512_matches(&data, &expected) => {
            return Err(RecordingError::Sha512 {
                path: data_path,
                meta: meta_path,
            })
        }
        Some(_) => true,
        None => false,
    };
    let payload =
        sample_bytes(&data, &captures, &header_bytes, trailing, datatype).map_err(|bytes| {
            RecordingError::DataLength {
                path: data_path.clone(),
                bytes,
                datatype: datatype.to_string(),
                sample_bytes: datatype.sample_bytes() as u64,
            }
        })?;
    let scaling = radbench.as_ref().and_then(|r| {
        r.vertical_gain
            .map(|g| (g, r.vertical_offset.unwrap_or([0.0; 2])))
    });
    let words = (stored.is_some() && datatype.component == Component::I16)
        .then(|| decode_words(&payload, datatype.little_endian));
    let samples = match words {
        Some(_) => Vec::new(),
        None => decode_samples(&payload, datatype, scaling),
    };
    let sha256 = match data_sha256 {
        Some(data_sha256) => [
            (meta_path.clone(), super::hash::sha256(&meta_bytes)),
            (data_path.clone(), data_sha256),
        ],
        None => Default::default(),
    };
    let recording = Recording {
        version: f.text(global, "core:version")?,
        description: f.text(global, "core:description")?,
        hw: f.text(global, "core:hw")?,
        recorder: f.text(global, "core:recorder")?,
        samples,
        meta_path,
        data_path,
        datatype,
        sample_rate_hz,
        extensions,
        captures,
        sha512_checked,
        unit: if scaling.is_some() {
            SampleUnit::Volts
        } else {
            SampleUnit::Native
        },
        radbench,
    };
    Ok(StoredRecording {
        recording,
        words,
        sha256,
    })
}

/// The `.sigmf-meta` file as JSON, and its bytes.
fn read_meta(meta_path: &Path) -> Result<(Value, Vec<u8>), RecordingError> {
    let bytes = std::fs::read(meta_path).map_err(|source| RecordingError::Io {
        path: meta_path.to_path_buf(),
        source,
    })?;
    let doc = serde_json::from_slice(&bytes).map_err(|source| RecordingError::NotJson {
        path: meta_path.to_path_buf(),
        source,
    })?;
    Ok((doc, bytes))
}

/// The sample format and rate, checked: one I/Q stream that radbench can read, with samples.
fn stream_format(
    f: &Fields<'_>,
    global: &serde_json::Map<String, Value>,
) -> Result<(Datatype, Option<f64>), RecordingError> {
    let text = f
        .text(global, "core:datatype")?
        .ok_or_else(|| f.err("core:datatype", "is missing (SigMF requires it)"))?;
    let datatype = Datatype::parse(&text).map_err(|reason| RecordingError::Datatype {
        path: f.path.to_path_buf(),
        value: text.clone(),
        reason,
    })?;
    let sample_rate_hz = f.number(global, "core:sample_rate")?;
    if let Some(rate) = sample_rate_hz.filter(|&r| r <= 0.0) {
        return Err(f.err(
            "core:sample_rate",
            format!("must be positive, found {rate}"),
        ));
    }
    let channels = f.count(global, "core:num_channels")?;
    if channels > 1 {
        return Err(f.err(
            "core:num_channels",
            format!("is {channels}: radbench reads one I/Q stream (num_channels 1)"),
        ));
    }
    if global.get("core:metadata_only").and_then(Value::as_bool) == Some(true) {
        return Err(f.err(
            "core:metadata_only",
            "is true: this recording holds no samples",
        ));
    }
    Ok((datatype, sample_rate_hz))
}

/// Each capture's `core:header_bytes` (0 where not given).
fn read_header_bytes(f: &Fields<'_>, doc: &Value) -> Result<Vec<u64>, RecordingError> {
    Ok(doc
        .get("captures")
        .and_then(Value::as_array)
        .map(|c| {
            c.iter()
                .filter_map(Value::as_object)
                .map(|o| f.count(o, "core:header_bytes"))
                .collect::<Result<Vec<u64>, _>>()
        })
        .transpose()?
        .unwrap_or_default())
}

fn sha512_matches(data: &[u8], expected: &str) -> bool {
    let actual: String = Sha512::digest(data)
        .iter()
        .map(|b| format!("{b:02x}"))
        .collect();
    actual.eq_ignore_ascii_case(expected.trim())
}

/// The I/Q samples of the payload parts, in volts when `scaling` (gain and offset per
/// component) is given.
fn decode_samples(
    payload: &[&[u8]],
    datatype: Datatype,
    scaling: Option<([f64; 2], [f64; 2])>,
) -> Vec<Complex64> {
    let width = datatype.component.bytes();
    payload
        .iter()
        .flat_map(|part| part.chunks_exact(2 * width))
        .map(|s| {
            let (i, q) = (datatype.value(&s[..width]), datatype.value(&s[width..]));
            match scaling {
                Some((g, o)) => Complex64::new(g[0] * i - o[0], g[1] * q - o[1]),
                None => Complex64::new(i, q),
            }
        })
        .collect()
}

/// The I and Q words of `ci16` payload parts (whole samples only, as [`decode_samples`]).
fn decode_words(payload: &[&[u8]], little_endian: bool) -> (Vec<i16>, Vec<i16>) {
    let n = payload.iter().map(|p| p.len() / 4).sum();
    let (mut i, mut q) = (vec![0i16; n], vec![0i16; n]);
    let word = |b: [u8; 2]| {
        if little_endian {
            i16::from_le_bytes(b)
        } else {
            i16::from_be_bytes(b)
        }
    };
    // Into slices of known length (no capacity check per sample: the loop vectorises).
    let mut at = 0;
    for part in payload {
        let samples = part.len() / 4;
        let (i, q) = (&mut i[at..at + samples], &mut q[at..at + samples]);
        for ((s, i), q) in part.chunks_exact(4).zip(i.iter_mut()).zip(q.iter_mut()) {
            *i = word([s[0], s[1]]);
            *q = word([s[2], s[3]]);
        }
        at += samples;
    }
    (i, q)
}

fn read_extensions(
    f: &Fields<'_>,
    global: &Map<String, Value>,
) -> Result<Vec<Extension>, RecordingError> {
    let Some(list) = global.get("core:extensions") else {
        return Ok(Vec::new());
    };
    let list = list
        .as_array()
        .ok_or_else(|| f.err("core:extensions", "must be a list"))?;
    list.iter()
        .map(|e| {
            let o = e
                .as_object()
                .ok_or_else(|| f.err("core:extensions", "entries must be objects"))?;
            Ok(Extension {
                name: f.text(o, "name")?.unwrap_or_default(),
                version: f.text(o, "version")?.unwrap_or_default(),
                optional: o.get("optional").and_then(Value::as_bool).unwrap_or(false),
            })
        })
        .collect()
}

fn read_captures(f: &Fields<'_>, doc: &Value) -> Result<Vec<CaptureSegment>, RecordingError> {
    let Some(list) = doc.get("captures") else {
        return Ok(Vec::new());
    };
    let list = list
        .as_array()
        .ok_or_else(|| f.err("captures", "must be a list"))?;
    let mut out = Vec::with_capacity(list.len());
    for c in list {
        let o = c
            .as_object()
            .ok_or_else(|| f.err("captures", "entries must be objects"))?;
        let seg = CaptureSegment {
            sample_start: f.count(o, "core:sample_start")?,
            frequency_hz: f.number(o, "core:frequency")?,
            datetime: f.text(o, "core:datetime")?,
        };
        if out
            .last()
            .is_some_and(|p: &CaptureSegment| p.sample_start > seg.sample_start)
        {
            return Err(f.err(
                "core:sample_start",
                "captures must be in increasing sample order",
            ));
        }
        out.push(seg);
    }
    Ok(out)
}

fn read_radbench(
    f: &Fields<'_>,
    global: &Map<String, Value>,
) -> Result<Option<RadbenchMeta>, RecordingError> {
    let keys: Map<String, Value> = global
        .iter()
        .filter_map(|(k, v)| {
            k.strip_prefix("radbench:")
                .map(|k| (k.to_string(), v.clone()))
        })
        .collect();
    if keys.is_empty() {
        return Ok(None);
    }
    let vertical_gain = f.pair(global, "radbench:vertical_gain")?;
    let vertical_offset = f.pair(global, "radbench:vertical_offset")?;
    if vertical_gain.is_some() != vertical_offset.is_some() {
        let missing = if vertical_gain.is_some() {
            "radbench:vertical_offset"
        } else {
            "radbench:vertical_gain"
        };
        return Err(f.err(
            missing,
            "is missing: volts need both the gain and the offset",
        ));
    }
    Ok(Some(RadbenchMeta {
        vertical_gain,
        vertical_offset,
        trigger_offset_s: f.within(global, "radbench:trigger_offset_s", 1.0, "seconds")?,
        system_delay_s: f.within(global, "radbench:system_delay_s", 1e-3, "seconds")?,
        keys,
    }))
}

/// The sample bytes of the data file: each capture's header and the file's trailing bytes left
/// out. Err(bytes) when they are not a whole number of samples.
fn sample_bytes<'a>(
    data: &'a [u8],
    captures: &[CaptureSegment],
    header_bytes: &[u64],
    trailing: u64,
    datatype: Datatype,
) -> Result<Vec<&'a [u8]>, u64> {
    let size = datatype.sample_bytes() as u64;
    let total = data.len() as u64;
    let headers: u64 = header_bytes.iter().sum();
    let samples_bytes = total
        .checked_sub(headers.saturating_add(trailing))
        .ok_or(total)?;
    if samples_bytes % size != 0 {
        return Err(samples_bytes);
    }
    let end = total - trailing;
    if headers == 0 {
        return Ok(vec![&data[..end as usize]]);
    }
    // Capture k's samples run from its sample_start to the next capture's, after its header.
    let mut parts = Vec::with_capacity(captures.len());
    let mut at = 0u64;
    for (k, c) in captures.iter().enumerate() {
        at += header_bytes.get(k).copied().unwrap_or(0);
        let next = captures.get(k + 1).map(|n| n.sample_start);
        let len = match next {
            Some(n) => (n - c.sample_start).saturating_mul(size),
            None => end.saturating_sub(at),
        };
        let stop = at.saturating_add(len);
        if stop > end {
            return Err(samples_bytes);
        }
        parts.push(&data[at as usize..stop as usize]);
        at = stop;
    }
    Ok(parts)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn write(dir: &Path, name: &str, meta: Value, data: &[u8]) -> PathBuf {
        let base = dir.join(name);
        std::fs::write(base.with_extension("sigmf-meta"), meta.to_string()).unwrap();
        std::fs::write(base.with_extension("sigmf-data"), data).unwrap();
        base.with_extension("sigmf-meta")
    }

    fn meta(datatype: &str) -> Value {
        serde_json::json!({
            "global": {"core:datatype": datatype, "core:sample_rate": 1e6, "core:version": "1.0.0"},
            "captures": [{"core:sample_start": 0, "core:datetime": "2026-01-02T03:04:05Z"}],
            "annotations": []
        })
    }

    /// Byte layouts written out by hand, so the reader is checked against the spec, not itself.
    #[test]
    fn each_datatype_and_byte_order_decodes() {
        let dir = tempfile::tempdir().unwrap();
        let cases: Vec<(&str, Vec<u8>, [f64; 4])> = vec![
            (
                "ci8",
                vec![0x01, 0xff, 0x80, 0x7f],
                [1.0, -1.0, -128.0, 127.0],
            ),
            (
                "cu8",
                vec![0x01, 0xff, 0x80, 0x7f],
                [1.0, 255.0, 128.0, 127.0],
            ),
            (
                "ci16_le",
                vec![0x01, 0x00, 0x00, 0x80, 0xff, 0xff, 0x34, 0x12],
                [1.0, -32768.0, -1.0, 4660.0],
            ),
            (
                "ci16_be",
                vec![0x00, 0x01, 0x80, 0x00, 0xff, 0xff, 0x12, 0x34],
                [1.0, -32768.0, -1.0, 4660.0],
            ),
            (
                "cf32_le",
                [1.5f32, -2.0, 0.25, 1e-3]
                    .iter()
                    .flat_map(|x| x.to_le_bytes())
                    .collect(),
                [1.5, -2.0, 0.25, f64::from(1e-3f32)],
            ),
            (
                "cf32_be",
                [1.5f32, -2.0, 0.25, 1e-3]
                    .iter()
                    .flat_map(|x| x.to_be_bytes())
                    .collect(),
                [1.5, -2.0, 0.25, f64::from(1e-3f32)],
            ),
            (
                "ci32_be",
                [7i32, -9, 100_000, -1]
                    .iter()
                    .flat_map(|x| x.to_be_bytes())
                    .collect(),
                [7.0, -9.0, 1e5, -1.0],
            ),
            (
                "cf64_le",
                [0.1f64, 0.2, 0.3, 0.4]
                    .iter()
                    .flat_map(|x| x.to_le_bytes())
                    .collect(),
                [0.1, 0.2, 0.3, 0.4],
            ),
        ];
        for (t, data, want) in cases {
            let path = write(dir.path(), t, meta(t), &data);
            let r = read_sigmf(&path).unwrap();
            assert_eq!(r.datatype.to_string(), t);
            assert_eq!(r.unit, SampleUnit::Native);
            assert_eq!(
                r.samples,
                vec![
                    Complex64::new(want[0], want[1]),
                    Complex64::new(want[2], want[3])
                ],
                "{t}"
            );
            assert_eq!(r.sample_rate_hz, Some(1e6));
            assert_eq!(r.datetime(), Some("2026-01-02T03:04:05Z"));
            assert!(r.radbench.is_none());
        }
    }

    #[test]
    fn radbench_namespace_gives_volts() {
        let dir = tempfile::tempdir().unwrap();
        let mut m = meta("ci16_le");
        let g = m["global"].as_object_mut().unwrap();
        g.insert(
            "radbench:vertical_gain".into(),
            serde_json::json!([0.5, 0.25]),
        );
        g.insert(
            "radbench:vertical_offset".into(),
            serde_json::json!([1.0, -1.0]),
        );
        g.insert("radbench:trigger_offset_s".into(), serde_json::json!(-2e-9));
        g.insert(
            "radbench:waveform".into(),
            serde_json::json!({"kind": "msk-lfm"}),
        );
        g.insert(
            "core:extensions".into(),
            serde_json::json!([{"name": "radbench", "version": "1.0.0", "optional": true}]),
        );
        let data = [4u8, 0, 8, 0];
        let sha: String = Sha512::digest(data)
            .iter()
            .map(|b| format!("{b:02x}"))
            .collect();
        g.insert("core:sha512".into(), Value::String(sha));
        let path = write(dir.path(), "rb", m, &data);
        // The base name and the data file name work too.
        for p in [
            path.clone(),
            path.with_extension(""),
            path.with_extension("sigmf-data"),
        ] {
            let r = read_sigmf(&p).unwrap();
            assert_eq!(r.unit, SampleUnit::Volts);
            assert_eq!(
                r.samples,
                vec![Complex64::new(0.5 * 4.0 - 1.0, 0.25 * 8.0 + 1.0)]
            );
            let rb = r.radbench.unwrap();
            assert_eq!(rb.trigger_offset_s, Some(-2e-9));
            assert_eq!(rb.waveform().unwrap()["kind"], "msk-lfm");
            assert!(r.sha512_checked);
            assert_eq!(r.extensions[0].name, "radbench");
        }
    }

    #[test]
    fn stored_ci16_keeps_its_words_and_hashes_what_it_read() {
        let dir = tempfile::tempdir().unwrap();
        // A header to skip, and a sample split over two captures.
        let data = [
            9u8, 0x01, 0x80, 0xff, 0x7f, 0x10, 0x00, 0xfe, 0xff, 0x34, 0x12, 0x00, 0x80,
        ];
        for (datatype, i, q) in [
            ("ci16_le", [-32767i16, 16, 0x1234], [32767i16, -2, -32768]),
            ("ci16_be", [0x0180, 0x1000, 0x3412], [-129, -257, 128]),
        ] {
            let mut m = meta(datatype);
            m["captures"] = serde_json::json!([
                {"core:sample_start": 0, "core:header_bytes": 1},
                {"core:sample_start": 2}
            ]);
            let g = m["global"].as_object_mut().unwrap();
            g.insert(
                "radbench:vertical_gain".into(),
                serde_json::json!([0.1, 3e-5]),
            );
            g.insert(
                "radbench:vertical_offset".into(),
                serde_json::json!([-0.3, 1e-3]),
            );
            let path = write(dir.path(), datatype, m, &data);
            let stored = read_sigmf_stored(&path, None).unwrap();
            let (wi, wq) = stored.words.clone().unwrap();
            assert_eq!(
                (wi.as_slice(), wq.as_slice()),
                (&i[..], &q[..]),
                "{datatype}"
            );
            assert!(stored.recording.samples.is_empty());
            // The words in volts, as the pipeline converts them, are the samples read in volts.
            let volts: Vec<Complex64> = wi
                .iter()
                .zip(&wq)
                .map(|(&i, &q)| {
                    Complex64::new(0.1 * f64::from(i) - -0.3, 3e-5 * f64::from(q) - 1e-3)
                })
                .collect();
            let r = read_sigmf(&path).unwrap();
            assert_eq!(r.samples, volts);
            assert_eq!(stored.recording.radbench, r.radbench);
            assert_eq!(
                stored.sha256,
                [
                    (
                        path.clone(),
                        crate::storage::hash::sha256_file(&path).unwrap()
                    ),
                    (
                        path.with_extension("sigmf-data"),
                        crate::storage::sha256(&data)
                    ),
                ]
            );
        }
        // Other datatypes come back as samples, as read_sigmf reads them.
        let path = write(dir.path(), "f", meta("cf32_le"), &[0u8; 16]);
        let stored = read_sigmf_stored(&path, None).unwrap();
        assert!(stored.words.is_none());
        assert_eq!(stored.recording.samples, read_sigmf(&path).unwrap().samples);
    }

    #[test]
    fn header_and_trailing_bytes_are_skipped() {
        let dir = tempfile::tempdir().unwrap();
        let mut m = meta("ci8");
        m["captures"] = serde_json::json!([
            {"core:sample_start": 0, "core:header_bytes": 3},
            {"core:sample_start": 2, "core:header_bytes": 1}
        ]);
        m["global"]["core:trailing_bytes"] = serde_json::json!(2);
        let data = [9, 9, 9, 1, 2, 3, 4, 9, 5, 6, 9, 9];
        let r = read_sigmf(&write(dir.path(), "h", m, &data)).unwrap();
        let want: Vec<Complex64> = [(1.0, 2.0), (3.0, 4.0), (5.0, 6.0)]
            .iter()
            .map(|(i, q)| Complex64::new(*i, *q))
            .collect();
        assert_eq!(r.samples, want);
    }

    #[test]
    fn a_recorded_sha256_that_matches_stands_for_core_sha512_and_one_that_does_not_is_no_excuse() {
        let dir = tempfile::tempdir().unwrap();
        let data: Vec<u8> = (0..64u8).collect();
        let mut m = meta("ci16_le");
        // A wrong core:sha512: read_sigmf refuses the recording.
        m["global"]["core:sha512"] = serde_json::json!("00");
        let path = write(dir.path(), "ci16_le", m, &data);
        assert!(read_sigmf(&path).is_err());
        let actual = crate::storage::sha256(&data);
        // The data is the bytes recorded (its SHA-256 as written): core:sha512 is not computed.
        let stored = read_sigmf_stored(&path, Some(&actual.to_uppercase())).unwrap();
        assert!(!stored.recording.sha512_checked);
        assert_eq!(stored.sha256[1].1, actual);
        // A recorded hash the data does not match falls back to core:sha512, which refuses it.
        let other = crate::storage::sha256(b"other bytes");
        let e = read_sigmf_stored(&path, Some(&other))
            .unwrap_err()
            .to_string();
        assert!(e.contains("core:sha512"), "{e}");
        assert!(read_sigmf_stored(&path, None).is_err());
    }

    #[test]
    fn errors_name_the_file_and_the_field() {
        let dir = tempfile::tempdir().unwrap();
        let err = |m: Value, data: &[u8], name: &str| {
            read_sigmf(&write(dir.path(), name, m, data))
                .unwrap_err()
                .to_string()
        };
        let e = err(meta("rf32_le"), &[0; 8], "real");
        assert!(
            e.contains("real.sigmf-meta") && e.contains("core:datatype"),
            "{e}"
        );
        let e = err(meta("ci16_le"), &[0; 6], "odd");
        assert!(e.contains("odd.sigmf-data") && e.contains("6 bytes"), "{e}");
        let mut m = meta("ci8");
        m["global"]["core:sha512"] = serde_json::json!("00");
        let e = err(m, &[0; 2], "sha");
        assert!(e.contains("core:sha512"), "{e}");
        let mut m = meta("ci8");
        m["global"]["core:sample_rate"] = serde_json::json!("fast");
        let e = err(m, &[0; 2], "rate");
        assert!(e.contains("core:sample_rate"), "{e}");
        let mut m = meta("ci8");
        m["global"]["radbench:vertical_gain"] = serde_json::json!([1.0]);
        m["global"]["radbench:vertical_offset"] = serde_json::json!([1.0, 2.0]);
        let e = err(m, &[0; 2], "gain");
        assert!(e.contains("radbench:vertical_gain"), "{e}");
        let mut m = meta("ci8");
        m["global"]["radbench:vertical_gain"] = serde_json::json!([1.0, 1.0]);
        let e = err(m, &[0; 2], "offset");
        assert!(e.contains("radbench:vertical_offset"), "{e}");
        let mut m = meta("ci8");
        m["global"].as_object_mut().unwrap().remove("core:datatype");
        let e = err(m, &[0; 2], "nodt");
        assert!(e.contains("core:datatype") && e.contains("missing"), "{e}");
        let mut m = meta("ci8");
        m["global"]["core:num_channels"] = serde_json::json!(2);
        let e = err(m, &[0; 4], "chan");
        assert!(e.contains("core:num_channels"), "{e}");
        let e = err(Value::String("x".into()), &[], "notobj");
        assert!(e.contains("global"), "{e}");

        let lonely = dir.path().join("lonely.sigmf-meta");
        std::fs::write(&lonely, meta("ci8").to_string()).unwrap();
        let e = read_sigmf(&lonely).unwrap_err();
        assert!(matches!(e, RecordingError::MissingData { .. }), "{e}");
        assert!(e.to_string().contains("lonely.sigmf-data"), "{e}");
        let e = read_sigmf(&dir.path().join("x.sigmf")).unwrap_err();
        assert!(e.to_string().contains("tar"), "{e}");
        assert_eq!(e.exit_class(), ExitClass::BadInput);
        std::fs::write(dir.path().join("bad.sigmf-meta"), "{ not json").unwrap();
        let e = read_sigmf(&dir.path().join("bad.sigmf-meta")).unwrap_err();
        assert!(matches!(e, RecordingError::NotJson { .. }), "{e}");
    }

    /// A two-sample recording as radbench writes it, with `trigger_offset_s`; its meta path.
    fn written(dir: &Path, trigger_offset_s: f64) -> PathBuf {
        let mut ns = Map::new();
        ns.insert("vertical_gain".into(), serde_json::json!([0.001, 0.002]));
        ns.insert("vertical_offset".into(), serde_json::json!([0.0, 0.1]));
        ns.insert(
            "trigger_offset_s".into(),
            serde_json::json!(trigger_offset_s),
        );
        let meta = super::super::sigmf::SigmfMeta {
            sample_rate: 80e9,
            frequency_hz: 80e9,
            datetime: "2026-11-21T19:55:00.123Z".into(),
            description: "test".into(),
            hw: "MOCK_LAB".into(),
            radbench: ns,
            annotations: vec![],
        };
        super::super::sigmf::write_ci16(&dir.join("capture"), &[100, -200], &[5, 6], &meta)
            .unwrap()
            .meta
    }

    #[test]
    fn reads_what_radbench_writes() {
        let dir = tempfile::tempdir().unwrap();
        let r = read_sigmf(&written(dir.path(), 1.5e-9)).unwrap();
        assert_eq!(r.sample_rate_hz, Some(80e9));
        assert_eq!(r.frequency_hz(), Some(80e9));
        assert!(r.sha512_checked);
        assert_eq!(r.unit, SampleUnit::Volts);
        assert!((r.samples[1].re - (-0.2)).abs() < 1e-12);
        assert!((r.samples[1].im - (0.012 - 0.1)).abs() < 1e-12);
        assert_eq!(r.radbench.unwrap().trigger_offset_s, Some(1.5e-9));
    }

    /// A trigger offset of 1e300 s (a background file edited or damaged) is refused with its
    /// key, not used.
    #[test]
    fn an_absurd_trigger_offset_is_refused_by_its_key() {
        let dir = tempfile::tempdir().unwrap();
        let e = read_sigmf(&written(dir.path(), 1e300))
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("radbench:trigger_offset_s") && e.contains("1e300"),
            "{e}"
        );
    }
}
