//! The I/O journal: every exchange on every link as one JSON object per line (format in
//! `docs/io-journal.md`). Text messages are written as text; binary messages (those carrying an
//! IEEE 488.2 block, or not printable UTF-8) as their length and SHA-256, the bytes optionally kept
//! in a file beside the journal.

use bytes::Bytes;
use serde::Serialize;
use sha2::{Digest, Sha256};
use std::collections::VecDeque;
use std::fs::File;
use std::io::{BufWriter, Write};
use std::path::{Path, PathBuf};
use std::sync::{Arc, Condvar, Mutex, MutexGuard};
use std::thread::JoinHandle;
use std::time::{Duration, SystemTime};

/// Messages longer than this are journalled as binary even when they are text.
const MAX_TEXT: usize = 16 << 10;

/// Received blocks at least this long are hashed on the journal's own thread, so the link can
/// go on with the next exchange meanwhile (a scope's 1.6 MB waveform takes ~0.8 ms to hash).
const HASH_ASIDE: usize = 64 << 10;

/// How long [`Journal::flush`] waits for the journal's thread before giving up with a log line.
const FLUSH_WAIT: Duration = Duration::from_secs(60);

/// A shared, cloneable handle to one journal file. Lines are written in exchange order; a large
/// received block's line (and those after it) is written once its hash is done, by a thread of
/// the journal's own. Dropping the last handle (or [`flush`](Self::flush)) waits for them.
#[derive(Clone)]
pub struct Journal {
    handle: Arc<Handle>,
}

/// Owns the hashing thread: the last handle dropped lets it finish and joins it.
struct Handle {
    shared: Arc<Shared>,
    thread: Option<JoinHandle<()>>,
}

struct Shared {
    state: Mutex<State>,
    /// Signalled when a block is queued, when the queue empties and when the journal closes.
    changed: Condvar,
}

struct State {
    out: BufWriter<File>,
    blobs: Option<PathBuf>,
    seq: u64,
    path: PathBuf,
    failed: bool,
    /// Lines not written yet, in order: empty, or a block waiting for its hash first.
    queue: VecDeque<Queued>,
    closed: bool,
}

enum Queued {
    /// A received block, its line still to be completed with its hash (and kept bytes).
    Block { entry: Box<Entry>, data: Bytes },
    /// A finished line that came after such a block.
    Line(String),
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

/// One journal line (the format is `docs/io-journal.md`).
#[derive(Debug, Clone, Serialize, PartialEq, Eq)]
struct Entry {
    seq: u64,
    time: String,
    instrument: String,
    resource: String,
    direction: &'static str,
    kind: &'static str,
    #[serde(skip_serializing_if = "Option::is_none")]
    text: Option<String>,
    #[serde(skip_serializing_if = "Option::is_none")]
    len: Option<u64>,
    #[serde(skip_serializing_if = "Option::is_none")]
    sha256: Option<String>,
    #[serde(skip_serializing_if = "Option::is_none")]
    head: Option<String>,
    #[serde(skip_serializing_if = "Option::is_none")]
    file: Option<String>,
    #[serde(skip_serializing_if = "Option::is_none")]
    value: Option<u64>,
    #[serde(skip_serializing_if = "Option::is_none")]
    error: Option<String>,
    elapsed_us: u64,
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
        let shared = Arc::new(Shared {
            state: Mutex::new(State {
                out: BufWriter::new(file),
                blobs,
                seq: 0,
                path: path.to_path_buf(),
                failed: false,
                queue: VecDeque::new(),
                closed: false,
            }),
            changed: Condvar::new(),
        });
        let thread = {
            let shared = shared.clone();
            std::thread::Builder::new()
                .name("radbench-journal".into())
                .spawn(move || shared.hash_blocks())
                .map_err(err)?
        };
        Ok(Self {
            handle: Arc::new(Handle {
                shared,
                thread: Some(thread),
            }),
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
        self.record(origin, direction, elapsed_us, |entry, blobs| {
            entry.len = Some(total as u64);
            match text {
                Some(text) => {
                    entry.kind = "text";
                    entry.text = Some(text);
                }
                None => Binary::describe(parts, entry.seq, blobs).fill(entry),
            }
            None
        });
    }

    /// Journals a received message. A large one is hashed on the journal's thread while the
    /// caller goes on; its line still comes in order.
    pub fn received(&self, origin: &Origin, data: &Bytes, elapsed_us: u64) {
        if data.len() < HASH_ASIDE {
            return self.message(origin, "read", &[data], elapsed_us);
        }
        self.record(origin, "read", elapsed_us, |entry, _| {
            entry.len = Some(data.len() as u64);
            entry.kind = "binary";
            Some(data.clone())
        });
    }

    /// Journals an event without payload: `connect`, `device_clear`, `status_byte`, `close`...
    pub fn event(&self, origin: &Origin, kind: &'static str, value: Option<u64>, elapsed_us: u64) {
        self.record(origin, "event", elapsed_us, |entry, _| {
            entry.kind = kind;
            entry.value = value;
            None
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
        self.record(origin, direction, elapsed_us, |entry, _| {
            entry.kind = "error";
            entry.error = Some(error.to_string());
            None
        });
    }

    /// Waits until every line journalled so far is in the file.
    pub fn flush(&self) {
        self.handle.shared.drain();
    }

    /// Numbers and fills an entry; `fill` returns the bytes of a block to hash aside.
    fn record(
        &self,
        origin: &Origin,
        direction: &'static str,
        elapsed_us: u64,
        fill: impl FnOnce(&mut Entry, Option<&Path>) -> Option<Bytes>,
    ) {
        let shared = &self.handle.shared;
        let Some(mut state) = shared.lock() else {
            return;
        };
        state.seq += 1;
        let mut entry = Entry {
            seq: state.seq,
            time: rfc3339_utc(SystemTime::now()),
            instrument: origin.instrument.clone(),
            resource: origin.resource.clone(),
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
        match fill(&mut entry, state.blobs.as_deref()) {
            Some(data) => {
                state.queue.push_back(Queued::Block {
                    entry: Box::new(entry),
                    data,
                });
                shared.changed.notify_all();
            }
            None if state.queue.is_empty() => state.write(&entry),
            None => {
                let line = serialise(&entry);
                state.queue.push_back(Queued::Line(line));
            }
        }
    }
}

impl Drop for Handle {
    fn drop(&mut self) {
        if let Some(mut state) = self.shared.lock() {
            state.closed = true;
            self.shared.changed.notify_all();
        }
        if let Some(thread) = self.thread.take() {
            let _ = thread.join();
        }
    }
}

impl Shared {
    fn lock(&self) -> Option<MutexGuard<'_, State>> {
        self.state.lock().ok()
    }

    /// The journal's thread: hashes each queued block without holding the lock, then writes its
    /// line and the lines that waited behind it; ends when the journal closes and all is written.
    fn hash_blocks(&self) {
        let Some(mut state) = self.lock() else { return };
        loop {
            let (data, seq, blobs) = match state.queue.front() {
                Some(Queued::Block { entry, data }) => {
                    (data.clone(), entry.seq, state.blobs.clone())
                }
                Some(Queued::Line(_)) => {
                    state.write_lines();
                    continue;
                }
                None if state.closed => return,
                None => {
                    let Ok(next) = self.changed.wait(state) else {
                        return;
                    };
                    state = next;
                    continue;
                }
            };
            drop(state);
            let described = Binary::describe(&[&data], seq, blobs.as_deref());
            let Some(next) = self.lock() else { return };
            state = next;
            if let Some(Queued::Block { mut entry, .. }) = state.queue.pop_front() {
                described.fill(&mut entry);
                state.write(&entry);
            }
            state.write_lines();
            if state.queue.is_empty() {
                self.changed.notify_all();
            }
        }
    }

    /// Waits (bounded) until the queue is written.
    fn drain(&self) {
        let Some(state) = self.lock() else { return };
        let waited = self
            .changed
            .wait_timeout_while(state, FLUSH_WAIT, |s| !s.queue.is_empty());
        if let Ok((state, timeout)) = waited {
            if timeout.timed_out() {
                tracing::error!(
                    "I/O journal {}: {} lines still unwritten after {FLUSH_WAIT:?}",
                    state.path.display(),
                    state.queue.len()
                );
            }
        }
    }
}

impl State {
    fn write(&mut self, entry: &Entry) {
        let line = serialise(entry);
        self.write_line(&line);
    }

    /// Writes the finished lines at the front of the queue (up to the next block).
    fn write_lines(&mut self) {
        while let Some(Queued::Line(_)) = self.queue.front() {
            if let Some(Queued::Line(line)) = self.queue.pop_front() {
                self.write_line(&line);
            }
        }
    }

    fn write_line(&mut self, line: &str) {
        let written = writeln!(self.out, "{line}").and_then(|_| self.out.flush());
        if let Err(e) = written {
            if !self.failed {
                self.failed = true;
                tracing::error!("I/O journal {} stopped: {e}", self.path.display());
            }
        }
    }
}

fn serialise(entry: &Entry) -> String {
    serde_json::to_string(entry).expect("journal entries serialise")
}

/// What the journal says of a binary message: SHA-256, the first bytes, and the file the bytes
/// were kept in when asked (or why not).
struct Binary {
    sha256: String,
    head: String,
    file: Option<String>,
    error: Option<String>,
}

impl Binary {
    fn describe(parts: &[&[u8]], seq: u64, blobs: Option<&Path>) -> Binary {
        let mut hasher = Sha256::new();
        for part in parts {
            hasher.update(part);
        }
        let mut head = Vec::with_capacity(32);
        for part in parts {
            let take = (32 - head.len()).min(part.len());
            head.extend_from_slice(&part[..take]);
        }
        let mut described = Binary {
            sha256: hex(&hasher.finalize()),
            head: escape_head(&head),
            file: None,
            error: None,
        };
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
                Ok(()) => described.file = Some(file.display().to_string()),
                Err(e) => described.error = Some(format!("binary not kept: {e}")),
            }
        }
        described
    }

    fn fill(self, entry: &mut Entry) {
        entry.kind = "binary";
        entry.sha256 = Some(self.sha256);
        entry.head = Some(self.head);
        entry.file = self.file;
        entry.error = self.error;
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
pub(crate) fn escape_head(data: &[u8]) -> String {
    data.iter()
        .take(32)
        .flat_map(|&b| std::ascii::escape_default(b))
        .map(char::from)
        .collect()
}

/// RFC 3339 UTC time with microseconds, e.g. `2026-11-21T19:43:30.123456Z`.
pub(crate) fn rfc3339_utc(t: SystemTime) -> String {
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
        let lines = lines(&path);
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

    fn lines(path: &Path) -> Vec<serde_json::Value> {
        std::fs::read_to_string(path)
            .unwrap()
            .lines()
            .map(|l| serde_json::from_str(l).unwrap())
            .collect()
    }

    /// Large received blocks are hashed aside; every line still comes in exchange order, each
    /// block with its own hash and kept bytes, and dropping the journal writes them all.
    #[test]
    fn blocks_hashed_aside_keep_their_place() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("io.jsonl");
        let j = Journal::create(&path, true).unwrap();
        let origin = Origin {
            instrument: "scope".into(),
            resource: "VICP::h::INSTR".into(),
        };
        let blocks: Vec<Bytes> = (0..3u8)
            .map(|k| Bytes::from(vec![k; HASH_ASIDE + usize::from(k)]))
            .collect();
        for block in &blocks {
            j.message(&origin, "write", &[b"C1:WF? ALL\n"], 1);
            j.received(&origin, block, 2);
            j.event(&origin, "status_byte", Some(0), 3);
        }
        let copy = j.clone();
        drop(j);
        copy.flush();
        let written = lines(&path);
        assert_eq!(written.len(), 9, "every line is there after flush");
        drop(copy);
        let written = lines(&path);
        assert_eq!(written.len(), 9);
        for (k, line) in written.iter().enumerate() {
            assert_eq!(line["seq"], k as u64 + 1);
        }
        for (k, block) in blocks.iter().enumerate() {
            let line = &written[3 * k + 1];
            assert_eq!(line["kind"], "binary");
            assert_eq!(line["direction"], "read");
            assert_eq!(line["len"], block.len() as u64);
            assert_eq!(line["sha256"], sha256_hex(block).as_str());
            assert_eq!(line["elapsed_us"], 2);
            let kept = std::fs::read(line["file"].as_str().unwrap()).unwrap();
            assert_eq!(&kept[..], &block[..]);
            assert_eq!(written[3 * k + 2]["kind"], "status_byte");
        }
    }

    /// A small reply goes the ordinary way, as text when it is text.
    #[test]
    fn small_replies_are_written_at_once() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("io.jsonl");
        let j = Journal::create(&path, false).unwrap();
        j.received(&Origin::default(), &Bytes::from_static(b"1\n"), 4);
        let written = lines(&path);
        assert_eq!(written.len(), 1, "written before any flush");
        assert_eq!(written[0]["kind"], "text");
        assert_eq!(written[0]["text"], "1\n");
    }
}
