//! Message framing for links without a message-end signal (raw socket, serial): a message ends at
//! the terminator byte (newline), except inside an IEEE 488.2 definite block `#<d><len><bytes>`,
//! whose payload is skipped by its length (it may contain newlines), or inside a quoted string,
//! where a `#` does not start a block.
//!
//! An indefinite block `#0<bytes>` is defined by IEEE 488.2 to end at NL^END. A raw socket has no
//! END, so the first newline after `#0` ends the message: such payloads must not contain a newline
//! (the sender refuses them; see [`LinkError::IndefiniteBlockWithNewline`](super::LinkError)).

use super::error::CodecError;
use super::io::{reserve_announced, Decode};
use bytes::{Bytes, BytesMut};

/// Splits a byte stream into terminator-ended messages, block-aware. The frame includes the
/// terminator.
#[derive(Debug, Clone)]
pub struct TerminatedDecoder {
    terminator: u8,
    limit: usize,
    /// Bytes of the current message already scanned.
    scanned: usize,
    state: Scan,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Scan {
    Text {
        in_string: bool,
    },
    /// Just saw `#` outside a string.
    Hash,
    /// Reading `left` more length digits of a definite block.
    Digits {
        left: u8,
        len: u64,
    },
    /// Inside a definite block whose payload ends at this offset.
    Body {
        end: usize,
    },
}

const FORMAT: &str = "newline-terminated";

impl TerminatedDecoder {
    pub fn new(terminator: u8, limit: usize) -> Self {
        Self {
            terminator,
            limit,
            scanned: 0,
            state: Scan::Text { in_string: false },
        }
    }

    /// Forgets a partial message (after a reconnect).
    pub fn reset(&mut self) {
        self.scanned = 0;
        self.state = Scan::Text { in_string: false };
    }

    fn too_large(&self, announced: u64) -> CodecError {
        CodecError::TooLarge {
            format: FORMAT,
            announced,
            limit: self.limit as u64,
        }
    }
}

impl Decode for TerminatedDecoder {
    type Item = Bytes;

    fn decode(&mut self, src: &mut BytesMut) -> Result<Option<Bytes>, CodecError> {
        while self.scanned < src.len() {
            match self.state {
                Scan::Body { end } => {
                    if src.len() < end {
                        self.scanned = src.len();
                        return Ok(None);
                    }
                    self.scanned = end;
                    self.state = Scan::Text { in_string: false };
                }
                Scan::Text { in_string } => {
                    let start = self.scanned;
                    let bytes = &src[start..];
                    // Fast path: find the first byte that matters.
                    let hit = bytes
                        .iter()
                        .position(|&b| b == self.terminator || b == b'"' || b == b'#');
                    let Some(offset) = hit else {
                        self.scanned = src.len();
                        break;
                    };
                    let at = start + offset;
                    let b = src[at];
                    self.scanned = at + 1;
                    if b == self.terminator {
                        // However it arrived (in one read or many), a message over the limit is
                        // refused, never handed on.
                        if at + 1 > self.limit {
                            return Err(self.too_large(at as u64 + 1));
                        }
                        let frame = src.split_to(at + 1).freeze();
                        self.reset();
                        return Ok(Some(frame));
                    } else if b == b'"' {
                        self.state = Scan::Text {
                            in_string: !in_string,
                        };
                    } else if !in_string {
                        self.state = Scan::Hash;
                    }
                }
                Scan::Hash => {
                    let b = src[self.scanned];
                    match b {
                        b'1'..=b'9' => {
                            self.scanned += 1;
                            self.state = Scan::Digits {
                                left: b - b'0',
                                len: 0,
                            };
                        }
                        b'0' => {
                            // Indefinite block: it runs to the terminator.
                            self.scanned += 1;
                            self.state = Scan::Text { in_string: false };
                        }
                        // Not a block (`#H1F` numbers, a lone `#`): rescan this byte as text.
                        _ => self.state = Scan::Text { in_string: false },
                    }
                }
                Scan::Digits { left, len } => {
                    let b = src[self.scanned];
                    if !b.is_ascii_digit() {
                        // Not a block after all; rescan as text.
                        self.state = Scan::Text { in_string: false };
                        continue;
                    }
                    self.scanned += 1;
                    let len = len * 10 + u64::from(b - b'0');
                    if left > 1 {
                        self.state = Scan::Digits {
                            left: left - 1,
                            len,
                        };
                    } else {
                        let end = self.scanned as u64 + len;
                        if end > self.limit as u64 {
                            return Err(self.too_large(end));
                        }
                        let end = end as usize;
                        if src.len() < end {
                            // Room for the payload plus its terminator, read straight in.
                            reserve_announced(src, end + 2 - src.len(), self.limit as u64);
                        }
                        self.state = Scan::Body { end };
                    }
                }
            }
        }
        if src.len() > self.limit {
            return Err(self.too_large(src.len() as u64));
        }
        Ok(None)
    }

    fn announced(&self) -> u64 {
        match self.state {
            Scan::Body { end } => end as u64,
            _ => 0,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn decode_all(chunks: &[&[u8]], limit: usize) -> Result<Vec<Bytes>, CodecError> {
        crate::transport::io::decode_chunks(TerminatedDecoder::new(b'\n', limit), chunks)
    }

    // Golden frames at every split, arbitrary bytes and round trips: the shared codec
    // conformance harness in tests/io_fuzz.rs.

    #[test]
    fn block_over_the_limit_is_refused_before_allocating() {
        let err = decode_all(&[b"#9999999999"], 1 << 20).unwrap_err();
        assert!(matches!(err, CodecError::TooLarge { .. }));
    }

    #[test]
    fn text_without_terminator_over_the_limit_is_refused() {
        let err = decode_all(&[&[b'a'; 100]], 64).unwrap_err();
        assert!(matches!(err, CodecError::TooLarge { .. }));
    }
}
