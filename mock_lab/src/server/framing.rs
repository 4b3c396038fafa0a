//! IEEE 488.2 program-message framing, shared by every server.
//!
//! On a raw socket a message ends at LF (a CR right before it is dropped), but a LF inside a
//! definite-length block (`#<d><len><bytes>`) is data, not a terminator, and so is a LF inside a
//! quoted string's neighbourhood of `#`. The [`Splitter`] finds message boundaries incrementally:
//! it remembers where it stopped scanning, and it skips the payload of a definite block in one
//! step, so a 64 MB block costs no per-byte work. An indefinite block (`#0`) runs to the next LF
//! on a raw socket; on END-delimited transports (VXI-11, HiSLIP, VICP) it runs to the END.
//!
//! Pure code: no I/O. The servers feed it their receive buffers.

use bytes::Bytes;
use thiserror::Error;

use super::pool;

/// Why a byte stream cannot be framed into messages.
#[derive(Debug, Error, PartialEq, Eq)]
pub(crate) enum FramingError {
    /// A definite block announces more bytes than the server accepts in one message.
    #[error("a #-block announces {announced} bytes but this server accepts at most {max} bytes per message; send smaller blocks or raise the server's max message size")]
    BlockTooLarge {
        /// Bytes the block header announced (plus what precedes it in the message).
        announced: u64,
        /// The configured maximum message size.
        max: usize,
    },
    /// More than the maximum message size arrived without a terminator.
    #[error("more than {max} bytes arrived without a message terminator (LF); terminate messages with LF or raise the server's max message size")]
    MessageTooLarge {
        /// The configured maximum message size.
        max: usize,
    },
}

/// One complete message found at the start of the buffer.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) struct Frame {
    /// Length of the message without its terminator (LF or CR LF).
    pub message_len: usize,
    /// Bytes to remove from the buffer (message plus terminator).
    pub consumed: usize,
}

/// Where the scanner is inside the current message.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Scan {
    /// Plain program text; `quote` is the open quote character, if any.
    Text { quote: Option<u8> },
    /// Just saw `#` outside quotes.
    Hash,
    /// Reading the `digits_left` length digits of a definite block.
    LengthDigits { digits_left: u8, len: u64 },
    /// Inside a definite block's payload.
    Block { left: u64 },
    /// Inside an indefinite (`#0`) block.
    Indefinite,
}

/// Incremental, block-aware message splitter.
#[derive(Debug, Clone)]
pub(crate) struct Splitter {
    max_message: usize,
    end_delimited: bool,
    scan: Scan,
    scanned: usize,
    /// Offset just past the last block payload byte; a CR before this offset is data.
    data_end: usize,
}

impl Splitter {
    /// A splitter for a raw socket: LF ends a message, also after a `#0` block.
    pub(crate) fn new(max_message: usize) -> Splitter {
        Splitter {
            max_message,
            end_delimited: false,
            scan: Scan::Text { quote: None },
            scanned: 0,
            data_end: 0,
        }
    }

    /// A splitter for a transport whose END marks the message end: a `#0` block runs to the END.
    pub(crate) fn end_delimited(max_message: usize) -> Splitter {
        Splitter {
            end_delimited: true,
            ..Splitter::new(max_message)
        }
    }

    /// How many more bytes the current definite block still needs (a hint for read sizes).
    pub(crate) fn block_bytes_pending(&self) -> u64 {
        match self.scan {
            Scan::Block { left } => left,
            _ => 0,
        }
    }

    /// Scans `buf` (which must start with the current message and keep every byte passed
    /// before) and returns the first complete message, if any. After `Some`, the caller must drop
    /// `frame.consumed` bytes from the front of its buffer before the next call.
    pub(crate) fn next_frame(&mut self, buf: &[u8]) -> Result<Option<Frame>, FramingError> {
        let mut pos = self.scanned;
        while pos < buf.len() {
            match self.scan {
                Scan::Block { left } => {
                    let avail = (buf.len() - pos) as u64;
                    let step = left.min(avail);
                    pos += step as usize;
                    self.scan = if step == left {
                        self.data_end = pos;
                        Scan::Text { quote: None }
                    } else {
                        Scan::Block { left: left - step }
                    };
                }
                Scan::Text { quote } => {
                    let rest = &buf[pos..];
                    let Some(off) = rest.iter().position(|&b| is_special(b, quote)) else {
                        pos = buf.len();
                        break;
                    };
                    pos += off;
                    let byte = buf[pos];
                    pos += 1;
                    match byte {
                        b'\n' => return Ok(Some(self.finish_frame(buf, pos))),
                        b'#' => self.scan = Scan::Hash,
                        q if quote == Some(q) => self.scan = Scan::Text { quote: None },
                        q => self.scan = Scan::Text { quote: Some(q) },
                    }
                }
                Scan::Hash => {
                    let byte = buf[pos];
                    match byte {
                        b'0' => {
                            pos += 1;
                            self.scan = Scan::Indefinite;
                        }
                        b'1'..=b'9' => {
                            pos += 1;
                            self.scan = Scan::LengthDigits {
                                digits_left: byte - b'0',
                                len: 0,
                            };
                        }
                        // Not a block after all: rescan this byte as text.
                        _ => self.scan = Scan::Text { quote: None },
                    }
                }
                Scan::LengthDigits { digits_left, len } => {
                    let byte = buf[pos];
                    if !byte.is_ascii_digit() {
                        // Malformed block header: treat it as text and let the parser complain.
                        self.scan = Scan::Text { quote: None };
                        continue;
                    }
                    pos += 1;
                    let len = len * 10 + u64::from(byte - b'0');
                    if digits_left > 1 {
                        self.scan = Scan::LengthDigits {
                            digits_left: digits_left - 1,
                            len,
                        };
                        continue;
                    }
                    let announced = pos as u64 + len;
                    if announced > self.max_message as u64 {
                        return Err(FramingError::BlockTooLarge {
                            announced,
                            max: self.max_message,
                        });
                    }
                    self.scan = if len == 0 {
                        self.data_end = pos;
                        Scan::Text { quote: None }
                    } else {
                        Scan::Block { left: len }
                    };
                }
                Scan::Indefinite => {
                    if self.end_delimited {
                        pos = buf.len();
                        break;
                    }
                    match buf[pos..].iter().position(|&b| b == b'\n') {
                        Some(off) => {
                            pos += off + 1;
                            return Ok(Some(self.finish_frame(buf, pos)));
                        }
                        None => pos = buf.len(),
                    }
                }
            }
        }
        self.scanned = pos;
        if pos > self.max_message && !matches!(self.scan, Scan::Block { .. }) {
            return Err(FramingError::MessageTooLarge {
                max: self.max_message,
            });
        }
        Ok(None)
    }

    /// For END-delimited transports: the message that ends at the END of `buf` (everything the
    /// splitter has not returned as a frame). A final LF (or CR LF) outside a block is the
    /// 488.2 terminator and is not part of the message. Resets the splitter.
    pub(crate) fn finish_at_end(&mut self, buf: &[u8]) -> usize {
        let mut len = buf.len();
        let in_block = matches!(self.scan, Scan::Block { .. } | Scan::LengthDigits { .. });
        if !in_block && len > 0 && buf[len - 1] == b'\n' && len > self.data_end {
            len -= 1;
            if len > 0 && buf[len - 1] == b'\r' && len > self.data_end {
                len -= 1;
            }
        }
        self.reset();
        len
    }

    fn finish_frame(&mut self, buf: &[u8], consumed: usize) -> Frame {
        let mut message_len = consumed - 1;
        if message_len > self.data_end && message_len > 0 && buf[message_len - 1] == b'\r' {
            message_len -= 1;
        }
        self.reset();
        Frame {
            message_len,
            consumed,
        }
    }

    fn reset(&mut self) {
        self.scan = Scan::Text { quote: None };
        self.scanned = 0;
        self.data_end = 0;
    }
}

fn is_special(byte: u8, quote: Option<u8>) -> bool {
    match quote {
        Some(q) => byte == q || byte == b'\n',
        None => matches!(byte, b'\n' | b'#' | b'"' | b'\''),
    }
}

/// Splits one END-delimited transport message into program messages: a LF outside blocks inside
/// it separates messages (`*RST\n*IDN?\n` is two), the final terminator is dropped, and a
/// trailing unterminated part is the last message. Empty messages are dropped. The messages are
/// views of `data` (no copy).
pub(crate) fn split_end_message(
    data: Bytes,
    max_message: usize,
) -> Result<Vec<Bytes>, FramingError> {
    let mut splitter = Splitter::end_delimited(max_message);
    let mut out = Vec::new();
    let mut start = 0;
    while let Some(frame) = splitter.next_frame(&data[start..])? {
        if frame.message_len > 0 {
            out.push(data.slice(start..start + frame.message_len));
        }
        start += frame.consumed;
    }
    let len = splitter.finish_at_end(&data[start..]);
    if len > 0 {
        out.push(data.slice(start..start + len));
    }
    Ok(out)
}

/// For a message arriving in several chunks (HiSLIP Data, VXI-11 device_write, VICP blocks):
/// when the first chunk holds a `#N` block header, reserve the rest of the block at once (the
/// announced length was checked against `max` first) instead of growing chunk by chunk.
pub(crate) fn reserve_for_block(input: &mut Vec<u8>, max: usize) {
    let mut splitter = Splitter::end_delimited(max);
    if let Ok(None) = splitter.next_frame(input) {
        let pending = splitter.block_bytes_pending() as usize;
        if pending > 0 {
            pool::reserve(input, pending + 2);
        }
    }
}

/// True when `response` already ends with a LF that is not part of a block, i.e. it carries its
/// own 488.2 response terminator.
pub(crate) fn has_terminator(response: &[u8]) -> bool {
    if response.last() != Some(&b'\n') {
        return false;
    }
    let mut splitter = Splitter::new(usize::MAX);
    let mut start = 0;
    loop {
        match splitter.next_frame(&response[start..]) {
            Ok(Some(frame)) => {
                start += frame.consumed;
                if start == response.len() {
                    return true;
                }
            }
            _ => return false,
        }
    }
}

/// The largest payload a definite-length block can carry: its length field has at most 9 digits.
pub(crate) const MAX_DEFINITE_BLOCK: usize = 999_999_999;

/// Encodes an IEEE 488.2 definite-length block header (`#<d><len>`) for a payload of `len`
/// bytes; `None` over [`MAX_DEFINITE_BLOCK`], which no digit count can express.
pub(crate) fn block_header(len: usize) -> Option<Vec<u8>> {
    if len > MAX_DEFINITE_BLOCK {
        return None;
    }
    let digits = len.to_string();
    let mut header = Vec::with_capacity(2 + digits.len());
    header.push(b'#');
    header.push(b'0' + digits.len() as u8);
    header.extend_from_slice(digits.as_bytes());
    Some(header)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn split_all(stream: &[u8], max: usize) -> Result<Vec<Vec<u8>>, FramingError> {
        let mut splitter = Splitter::new(max);
        let mut out = Vec::new();
        let mut start = 0;
        while let Some(frame) = splitter.next_frame(&stream[start..])? {
            out.push(stream[start..start + frame.message_len].to_vec());
            start += frame.consumed;
        }
        Ok(out)
    }

    /// Feeds the stream in two parts split at `at`, as a socket might deliver it.
    fn split_in_two(stream: &[u8], at: usize) -> Vec<Vec<u8>> {
        let mut splitter = Splitter::new(1 << 20);
        let mut buf: Vec<u8> = Vec::new();
        let mut out = Vec::new();
        for part in [&stream[..at], &stream[at..]] {
            buf.extend_from_slice(part);
            while let Some(frame) = splitter.next_frame(&buf).unwrap() {
                out.push(buf[..frame.message_len].to_vec());
                buf.drain(..frame.consumed);
            }
        }
        out
    }

    const GOLDEN: &[u8] = b"*IDN?\r\nDATA #15a\nb\r\n\nc\r\nECHO \"#9\"\nDATA #0xy\r\n";

    fn golden_messages() -> Vec<Vec<u8>> {
        vec![
            b"*IDN?".to_vec(),
            b"DATA #15a\nb\r\n".to_vec(),
            b"c".to_vec(),
            b"ECHO \"#9\"".to_vec(),
            b"DATA #0xy".to_vec(),
        ]
    }

    #[test]
    fn golden_stream_splits_into_messages() {
        assert_eq!(split_all(GOLDEN, 1 << 20).unwrap(), golden_messages());
    }

    #[test]
    fn every_split_position_gives_the_same_messages() {
        for at in 0..=GOLDEN.len() {
            assert_eq!(split_in_two(GOLDEN, at), golden_messages(), "split at {at}");
        }
    }

    #[test]
    fn block_ending_in_cr_keeps_its_cr() {
        let msgs = split_all(b"DATA #12a\r\n", 100).unwrap();
        assert_eq!(msgs, vec![b"DATA #12a\r".to_vec()]);
    }

    #[test]
    fn oversized_block_is_refused_before_its_payload_arrives() {
        let err = split_all(b"DATA #9999999999", 1000).unwrap_err();
        assert!(matches!(err, FramingError::BlockTooLarge { max: 1000, .. }));
    }

    #[test]
    fn endless_text_is_refused() {
        let err = split_all(&[b'a'; 200], 100).unwrap_err();
        assert_eq!(err, FramingError::MessageTooLarge { max: 100 });
    }

    #[test]
    fn end_message_drops_final_terminator_but_not_block_bytes() {
        assert_eq!(
            split_end_message(Bytes::from_static(b"*IDN?\r\n"), 100).unwrap(),
            vec![b"*IDN?".to_vec()]
        );
        assert_eq!(
            split_end_message(Bytes::from_static(b"DATA #12\r\n"), 100).unwrap(),
            vec![b"DATA #12\r\n".to_vec()]
        );
        assert_eq!(
            split_end_message(Bytes::from_static(b"*RST\n*IDN?"), 100).unwrap(),
            vec![b"*RST".to_vec(), b"*IDN?".to_vec()]
        );
        assert_eq!(
            split_end_message(Bytes::from_static(b"DATA #0a\nb\n"), 100).unwrap(),
            vec![b"DATA #0a\nb".to_vec()]
        );
    }

    #[test]
    fn terminator_detection_respects_blocks() {
        assert!(has_terminator(b"1\n"));
        assert!(!has_terminator(b"1"));
        assert!(!has_terminator(b"#11\n"));
        assert!(has_terminator(b"#11\n\n"));
    }

    #[test]
    fn reservation_follows_the_announced_block() {
        let mut input = b"DATA #41000ab".to_vec();
        reserve_for_block(&mut input, 1 << 20);
        assert!(input.capacity() >= 13 + 998);
        let mut huge = b"DATA #9999999999".to_vec();
        reserve_for_block(&mut huge, 1000);
        assert!(huge.capacity() < 1000, "over the limit: nothing reserved");
    }

    #[test]
    fn block_header_encodes_digit_count() {
        assert_eq!(block_header(0), Some(b"#10".to_vec()));
        assert_eq!(block_header(1_000_000), Some(b"#71000000".to_vec()));
        assert_eq!(block_header(999_999_999), Some(b"#9999999999".to_vec()));
        assert_eq!(block_header(1_000_000_000), None);
    }

    proptest::proptest! {
        #[test]
        fn arbitrary_bytes_never_panic(bytes in proptest::collection::vec(proptest::num::u8::ANY, 0..512), max in 1usize..600) {
            let _ = split_all(&bytes, max);
            let _ = split_end_message(Bytes::from(bytes.clone()), max);
            let _ = has_terminator(&bytes);
        }
    }
}
