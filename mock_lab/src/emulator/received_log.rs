//! A bounded in-memory log of what an emulator received, readable by tests, mirrored to tracing.

use std::collections::VecDeque;
use std::sync::Mutex;

/// One received message as text: binary blocks are summarised (`#<len bytes>`) and long text is cut.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct LogEntry {
    /// Running number of the message since the emulator was created (never reset by `clear`).
    pub seq: u64,
    /// The message, readable.
    pub text: String,
    /// Its size on the wire in bytes.
    pub bytes: usize,
}

/// The received-message log. Holds the newest `capacity` entries.
#[derive(Debug)]
pub struct ReceivedLog {
    instrument: &'static str,
    capacity: usize,
    inner: Mutex<(u64, VecDeque<LogEntry>)>,
}

/// Longest text kept per entry, in characters.
const MAX_TEXT: usize = 400;

impl ReceivedLog {
    pub fn new(instrument: &'static str, capacity: usize) -> Self {
        ReceivedLog {
            instrument,
            capacity: capacity.max(1),
            inner: Mutex::new((0, VecDeque::new())),
        }
    }

    /// Records one received message and returns its readable form.
    pub fn record(&self, data: &[u8]) -> String {
        let text = summarise(data);
        tracing::debug!(instrument = self.instrument, bytes = data.len(), message = %text, "received");
        let mut guard = self.inner.lock().unwrap_or_else(|e| e.into_inner());
        let (seq, entries) = &mut *guard;
        if entries.len() == self.capacity {
            entries.pop_front();
        }
        entries.push_back(LogEntry {
            seq: *seq,
            text: text.clone(),
            bytes: data.len(),
        });
        *seq += 1;
        text
    }

    /// The kept entries, oldest first.
    pub fn entries(&self) -> Vec<LogEntry> {
        let guard = self.inner.lock().unwrap_or_else(|e| e.into_inner());
        guard.1.iter().cloned().collect()
    }

    /// Just the texts, oldest first.
    pub fn texts(&self) -> Vec<String> {
        self.entries().into_iter().map(|e| e.text).collect()
    }

    pub fn clear(&self) {
        self.inner
            .lock()
            .unwrap_or_else(|e| e.into_inner())
            .1
            .clear();
    }
}

/// Readable form of a message: printable ASCII kept, `#N` definite blocks replaced by their size,
/// other bytes escaped, trailing CR/LF dropped, cut at `MAX_TEXT` characters.
pub(crate) fn summarise(data: &[u8]) -> String {
    // The terminator is cut from the text only: a block may end in CR or LF bytes of its own.
    let text_end = trim_terminator(data).len();
    let mut out = String::new();
    let mut i = 0;
    while i < text_end && out.len() < MAX_TEXT {
        if data[i] == b'#' {
            if let Some((header_len, payload_len)) = super::scpi::message::block_header(&data[i..])
            {
                // An indefinite block (`#0`) runs to the terminator, a definite one may hold it.
                let end = if data[i + 1] == b'0' {
                    text_end
                } else {
                    data.len()
                };
                let available = end - i - header_len;
                out.push_str(&format!("#<{} bytes>", payload_len.min(available)));
                i += header_len + payload_len.min(available);
                continue;
            }
        }
        let b = data[i];
        if (0x20..0x7f).contains(&b) {
            out.push(b as char);
        } else {
            out.push_str(&format!("\\x{b:02x}"));
        }
        i += 1;
    }
    if i < text_end {
        out.push_str("...");
    }
    out
}

fn trim_terminator(mut data: &[u8]) -> &[u8] {
    while let [rest @ .., b'\n' | b'\r'] = data {
        data = rest;
    }
    data
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn blocks_are_summarised_and_the_log_is_bounded() {
        let log = ReceivedLog::new("test", 2);
        log.record(b"*IDN?\n");
        log.record(b":TRAC1:DATA 1,0,#14\x01\n\x02\x03\r\n");
        log.record(b"\x00bin");
        let entries = log.entries();
        assert_eq!(entries.len(), 2);
        assert_eq!(entries[0].seq, 1);
        assert_eq!(entries[0].text, ":TRAC1:DATA 1,0,#<4 bytes>");
        assert_eq!(entries[1].text, "\\x00bin");
        assert_eq!(summarise(b"DATA #12\r\n\r\n"), "DATA #<2 bytes>");
        assert_eq!(summarise(b"DATA #0ab\r\n"), "DATA #<2 bytes>");
    }
}
