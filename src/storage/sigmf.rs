//! Raw captures as SigMF recordings (`.sigmf-meta` JSON + `.sigmf-data` samples).
//!
//! radbench keeps the scope's own 16-bit words, I and Q interleaved (`ci16_le`), so nothing is lost;
//! `radbench:vertical_gain` and `radbench:vertical_offset` turn them into volts
//! (`volts = gain * word - offset`, per channel). Everything radbench knows about the capture that
//! the SigMF core has no field for lives in the `radbench:` namespace, declared in
//! `core:extensions`; docs/capture.md lists its keys.
//!
//! Both files are written atomically (temporary file, then rename): an interrupted write leaves
//! either the old file or the new one, never half of one.

use super::atomic::write_atomic;
use super::StorageError;
use serde_json::{json, Map, Value};
use sha2::{Digest, Sha512};
use std::path::{Path, PathBuf};

/// Version of the `radbench:` SigMF namespace written here.
pub(crate) const NAMESPACE_VERSION: &str = "1.0.0";

/// What a SigMF recording describes, besides its samples.
#[derive(Debug, Clone)]
pub(crate) struct SigmfMeta {
    /// Sample rate of the data, Sa/s.
    pub sample_rate: f64,
    /// RF centre frequency the baseband samples belong to, Hz.
    pub frequency_hz: f64,
    /// Capture time, RFC 3339 UTC (`2026-11-21T19:55:00.123Z`).
    pub datetime: String,
    /// One line saying what this is.
    pub description: String,
    /// The hardware, e.g. the scope's identity.
    pub hw: String,
    /// The `radbench:` namespace: keys without the prefix (it is added), any JSON values.
    pub radbench: Map<String, Value>,
    /// Annotations: (first sample, sample count, label).
    pub annotations: Vec<(u64, u64, String)>,
}

/// A recording as written: where its two files are.
#[derive(Debug, Clone, PartialEq, Eq)]
pub(crate) struct SigmfFiles {
    pub meta: PathBuf,
    pub data: PathBuf,
}

/// Writes `base.sigmf-data` (I/Q words interleaved, little-endian) and `base.sigmf-meta`.
pub(crate) fn write_ci16(
    base: &Path,
    i_words: &[i16],
    q_words: &[i16],
    meta: &SigmfMeta,
) -> Result<SigmfFiles, StorageError> {
    if i_words.len() != q_words.len() {
        return Err(StorageError::BadData {
            path: base.to_path_buf(),
            reason: format!(
                "I has {} samples and Q {}: a SigMF recording needs both of the same length",
                i_words.len(),
                q_words.len()
            ),
        });
    }
    let mut data = Vec::with_capacity(4 * i_words.len());
    for (i, q) in i_words.iter().zip(q_words) {
        data.extend_from_slice(&i.to_le_bytes());
        data.extend_from_slice(&q.to_le_bytes());
    }
    let files = SigmfFiles {
        meta: with_suffix(base, "sigmf-meta"),
        data: with_suffix(base, "sigmf-data"),
    };
    let sha512 = hex(&Sha512::digest(&data));
    write_atomic(&files.data, &data)?;
    let doc = meta_document(meta, "ci16_le", &sha512);
    let mut text = serde_json::to_string_pretty(&doc).map_err(|e| StorageError::BadData {
        path: files.meta.clone(),
        reason: e.to_string(),
    })?;
    text.push('\n');
    write_atomic(&files.meta, text.as_bytes())?;
    Ok(files)
}

fn meta_document(meta: &SigmfMeta, datatype: &str, sha512: &str) -> Value {
    let mut global = Map::new();
    global.insert("core:datatype".into(), json!(datatype));
    global.insert("core:sample_rate".into(), json!(meta.sample_rate));
    global.insert("core:version".into(), json!("1.0.0"));
    global.insert("core:sha512".into(), json!(sha512));
    global.insert("core:description".into(), json!(meta.description));
    global.insert("core:hw".into(), json!(meta.hw));
    global.insert(
        "core:recorder".into(),
        json!(format!("radbench {}", env!("CARGO_PKG_VERSION"))),
    );
    global.insert(
        "core:extensions".into(),
        json!([{"name": "radbench", "version": NAMESPACE_VERSION, "optional": true}]),
    );
    for (k, v) in &meta.radbench {
        global.insert(format!("radbench:{k}"), v.clone());
    }
    let annotations: Vec<Value> = meta
        .annotations
        .iter()
        .map(|(start, count, label)| {
            json!({"core:sample_start": start, "core:sample_count": count, "core:label": label})
        })
        .collect();
    json!({
        "global": global,
        "captures": [{
            "core:sample_start": 0,
            "core:frequency": meta.frequency_hz,
            "core:datetime": meta.datetime,
        }],
        "annotations": annotations,
    })
}

/// `base` with `.suffix` appended to its file name (not replacing an existing extension: run names
/// may contain dots).
fn with_suffix(base: &Path, suffix: &str) -> PathBuf {
    let mut name = base
        .file_name()
        .map(|n| n.to_os_string())
        .unwrap_or_default();
    name.push(".");
    name.push(suffix);
    base.with_file_name(name)
}

fn hex(bytes: &[u8]) -> String {
    bytes.iter().map(|b| format!("{b:02x}")).collect()
}

/// UTC time as RFC 3339 with milliseconds, from the system clock.
pub fn utc_now_rfc3339() -> String {
    crate::time::rfc3339_millis(std::time::SystemTime::now())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn writes_interleaved_words_and_a_meta_with_the_namespace() {
        let dir = tempfile::tempdir().unwrap();
        let base = dir.path().join("capture.001");
        let mut ns = Map::new();
        ns.insert("vertical_gain".into(), json!([1e-5, 1e-5]));
        let meta = SigmfMeta {
            sample_rate: 80e9,
            frequency_hz: 80e9,
            datetime: "1970-01-01T00:00:00.000Z".into(),
            description: "test".into(),
            hw: "MOCK_LAB".into(),
            radbench: ns,
            annotations: vec![(10, 5, "target".into())],
        };
        let files = write_ci16(&base, &[1, -2], &[256, -32768], &meta).unwrap();
        assert_eq!(files.data, dir.path().join("capture.001.sigmf-data"));
        let data = std::fs::read(&files.data).unwrap();
        assert_eq!(data, [1, 0, 0, 1, 0xfe, 0xff, 0, 0x80]);
        let doc: Value = serde_json::from_slice(&std::fs::read(&files.meta).unwrap()).unwrap();
        assert_eq!(doc["global"]["core:datatype"], "ci16_le");
        assert_eq!(doc["global"]["radbench:vertical_gain"][0], 1e-5);
        assert_eq!(doc["global"]["core:extensions"][0]["name"], "radbench");
        assert_eq!(doc["annotations"][0]["core:sample_count"], 5);
        assert_eq!(
            std::fs::read_dir(dir.path()).unwrap().count(),
            2,
            "no temporary files left"
        );
        assert!(write_ci16(&base, &[1], &[], &meta).is_err());
    }
}
