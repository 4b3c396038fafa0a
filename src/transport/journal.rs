//! The I/O journal: every exchange on every link as one JSON object per line (format in
//! `docs/io-journal.md`). Text messages are written as text; binary messages (those carrying an
//! IEEE 488.2 block, or not printable UTF-8) as their length and SHA-256, the bytes optionally kept
//! in a file beside the journal.

use serde::Serialize;
use sha2::{Digest, Sha256};
use std::fs::File;
use std::io::{BufWriter, Write};
use std::path::{Path, PathBuf};
use std::sync::{Arc, Mutex};
use std::time::SystemTime;

/// Messages longer than this are journalled as binary even when they are text.
const MAX_TEXT: usize = 16 << 10;

/// A shared, cloneable handle to one journal file.
#[derive(Clone)]
pub struct Journal {
    inner: Arc<Mutex<Inner>>,
}

struct Inner {
    out: BufWriter<File>,
    blobs: Option<PathBuf>,
    seq: u64,
    path: PathBuf,
    failed: bool,
}

/// Cannot create the journal or its folder.
#[derive(Debug, thiserror::Error)]
#[error("cannot create I/O journal `{path}`: {source}; check the --trace-io path")]
pub struct JournalError {
    pub path: PathBuf,
    pub source: std::io::Error,
}

impl crate::exit::Classify for JournalError {
    fn exit_class(&self) -> crate::exit::ExitClass {
        crate::exit::ExitClass::BadInput
    }
}

/// One journal line.
#[derive(Debug, Clone, Serialize, PartialEq, Eq)]
pub struct Entry<'a> {
    pub seq: u64,
    pub time: String,
    pub instrument: &'a str,
    pub resource: &'a str,
    pub direction: &'static str,
    pub kind: &'static str,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub text: Option<String>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub len: Option<u64>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub sha256: Option<String>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub head: Option<String>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub file: Option<String>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub value: Option<u64>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub error: Option<String>,
    pub elapsed_us: u64,
}

/// Who a journal entry is about.
#[derive(Debug, Clone, Default)]
pub struct Origin {
    pub instrument: String,
    pub resource: String,
}

impl Journal {
    /// Creates (truncates) the journal. With `keep_binary`, binary messages are also written to
    /// `<journal>.blobs/<seq>.bin`.
    pub fn create(path: &Path, keep_binary: bool) -> Result<Self, JournalError> {
        let err = |source| JournalError {
            path: path.to_path_buf(),
            source,
        };
        if let Some(parent) = path.parent().filter(|p| !p.as_os_str().is_empty()) {
            std::fs::create_dir_all(parent).map_err(err)?;
        }
        let file = File::create(path).map_err(err)?;
        let blobs = if keep_binary {
            let mut dir = path.as_os_str().to_owned();
            dir.push(".blobs");
            let dir = PathBuf::from(dir);
            std::fs::create_dir_all(&dir).map_err(err)?;
            Some(dir)
        } else {
            None
        };
        Ok(Self {
            inner: Arc::new(Mutex::new(Inner {
                out: BufWriter::new(file),
                blobs,
                seq: 0,
                path: path.to_path_buf(),
                failed: false,
            })),
        })
    }

    /// Journals a message that crossed the link, given as the parts it was sent in.
    pub fn message(
        &self,
        origin: &Origin,
        direction: &'static str,
        parts: &[&[u8]],
        elapsed_us: u64,
    ) {
        let total: usize = parts.iter().map(|p| p.len()).sum();
        let small = (total <= MAX_TEXT).then(|| parts.concat());
        let text = small.as_deref().and_then(as_text).map(str::to_string);
        self.record(origin, direction, elapsed_us, |entry, blobs, seq| {
            entry.len = Some(total as u64);
            if let Some(text) = text {
                entry.kind = "text";
                entry.text = Some(text);
                return;
            }
            entry.kind = "binary";
            let mut hasher = Sha256::new();
            for part in parts {
                hasher.update(part);
            }
            entry.sha256 = Some(hex(&hasher.finalize()));
            let mut head = Vec::with_capacity(32);
            for part in parts {
                let take = (32 - head.len()).min(part.len());
                head.extend_from_slice(&part[..take]);
            }
            entry.head = Some(escape_head(&head));
            if let Some(dir) = blobs {
                let file = dir.join(format!("{seq:06}.bin"));
                let written = File::create(&file).and_then(|f| {
                    let mut w = BufWriter::new(f);
                    for part in parts {
                        w.write_all(part)?;
                    }
                    w.flush()
                });
                match written {
                    Ok(()) => entry.file = Some(file.display().to_string()),
                    Err(e) => entry.error = Some(format!("binary not kept: {e}")),
                }
            }
        });
    }

    /// Journals an event without payload: `connect`, `device_clear`, `status_byte`, `close`...
    pub fn event(&self, origin: &Origin, kind: &'static str, value: Option<u64>, elapsed_us: u64) {
        self.record(origin, "event", elapsed_us, |entry, _, _| {
            entry.kind = kind;
            entry.value = value;
        });
    }

    /// Journals a failed operation.
    pub fn failure(
        &self,
        origin: &Origin,
        direction: &'static str,
        error: &dyn std::fmt::Display,
        elapsed_us: u64,
    ) {
        self.record(origin, direction, elapsed_us, |entry, _, _| {
            entry.kind = "error";
            entry.error = Some(error.to_string());
        });
    }

    fn record(
        &self,
        origin: &Origin,
        direction: &'static str,
        elapsed_us: u64,
        fill: impl FnOnce(&mut Entry<'_>, Option<&Path>, u64),
    ) {
        let Ok(mut inner) = self.inner.lock() else {
            return;
        };
        inner.seq += 1;
        let seq = inner.seq;
        let mut entry = Entry {
            seq,
            time: rfc3339_utc(SystemTime::now()),
            instrument: &origin.instrument,
            resource: &origin.resource,
            direction,
            kind: "",
            text: None,
            len: None,
            sha256: None,
            head: None,
            file: None,
            value: None,
            error: None,
            elapsed_us,
        };
        fill(&mut entry, inner.blobs.as_deref(), seq);
        let line = serde_json::to_string(&entry).expect("journal entries serialise");
        let written = writeln!(inner.out, "{line}").and_then(|_| inner.out.flush());
        if let Err(e) = written {
            if !inner.failed {
                inner.failed = true;
                tracing::error!("I/O journal {} stopped: {e}", inner.path.display());
            }
        }
    }
}

/// The message as text when it is printable UTF-8 without a binary block and not too long.
fn as_text(data: &[u8]) -> Option<&str> {
    if data.len() > MAX_TEXT {
        return None;
    }
    let text = std::str::from_utf8(data).ok()?;
    let printable = text
        .chars()
        .all(|c| !c.is_control() || matches!(c, '\n' | '\r' | '\t'));
    let has_block = data
        .windows(2)
        .any(|w| w[0] == b'#' && w[1].is_ascii_digit());
    (printable && !has_block).then_some(text)
}

pub fn sha256_hex(data: &[u8]) -> String {
    hex(&Sha256::digest(data))
}

fn hex(bytes: &[u8]) -> String {
    use std::fmt::Write as _;
    let mut out = String::with_capacity(bytes.len() * 2);
    for b in bytes {
        let _ = write!(out, "{b:02x}");
    }
    out
}

/// The first 32 bytes, printable ASCII kept and the rest as `\xNN`.
pub fn escape_head(data: &[u8]) -> String {
    data.iter()
        .take(32)
        .flat_map(|&b| std::ascii::escape_default(b))
        .map(char::from)
        .collect()
}

/// RFC 3339 UTC time with microseconds, e.g. `2026-11-21T19:43:30.123456Z`.
pub fn rfc3339_utc(t: SystemTime) -> String {
    crate::time::rfc3339_micros(t)
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::time::Duration;

    #[test]
    fn rfc3339_known_instants() {
        let t = SystemTime::UNIX_EPOCH;
        assert_eq!(rfc3339_utc(t), "1970-01-01T00:00:00.000000Z");
        let t = SystemTime::UNIX_EPOCH + Duration::from_micros(951_782_400_000_001);
        assert_eq!(rfc3339_utc(t), "2000-02-29T00:00:00.000001Z");
        let t = SystemTime::UNIX_EPOCH + Duration::from_secs(1_795_290_210);
        assert_eq!(rfc3339_utc(t), "2026-11-21T19:43:30.000000Z");
    }

    #[test]
    fn text_and_binary_entries() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("io.jsonl");
        let j = Journal::create(&path, true).unwrap();
        let origin = Origin {
            instrument: "awg".into(),
            resource: "TCPIP::h::5025::SOCKET".into(),
        };
        j.message(&origin, "write", &[b"*IDN?", b"\n"], 5);
        j.message(&origin, "read", &[b"#13\x00\x01\x02\n"], 7);
        j.event(&origin, "status_byte", Some(16), 3);
        let lines: Vec<serde_json::Value> = std::fs::read_to_string(&path)
            .unwrap()
            .lines()
            .map(|l| serde_json::from_str(l).unwrap())
            .collect();
        assert_eq!(lines.len(), 3);
        assert_eq!(lines[0]["kind"], "text");
        assert_eq!(lines[0]["text"], "*IDN?\n");
        assert_eq!(lines[1]["kind"], "binary");
        assert_eq!(lines[1]["len"], 7);
        assert_eq!(
            lines[1]["sha256"],
            sha256_hex(b"#13\x00\x01\x02\n").as_str()
        );
        let kept = std::fs::read(lines[1]["file"].as_str().unwrap()).unwrap();
        assert_eq!(kept, b"#13\x00\x01\x02\n");
        assert_eq!(lines[2]["value"], 16);
        assert!(lines[2]["time"].as_str().unwrap().ends_with('Z'));
    }
}
