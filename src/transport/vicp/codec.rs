//! LeCroy VICP wire format: an 8-byte header `operation u8, version u8 (=1), sequence u8,
//! reserved u8, length u32 BE`, then the block.

use crate::transport::error::CodecError;
use crate::transport::{FrameHeader, Framed, FramedDecoder};

pub const HEADER_LEN: usize = 8;
pub const VERSION: u8 = 1;
const FORMAT: &str = "VICP";

/// Operation flag bits; kept whole so the table reads like the protocol's.
#[allow(dead_code)]
pub mod op {
    pub const DATA: u8 = 0x80;
    pub(crate) const REMOTE: u8 = 0x40;
    pub(crate) const LOCKOUT: u8 = 0x20;
    pub(crate) const CLEAR: u8 = 0x10;
    pub(crate) const SRQ: u8 = 0x08;
    pub(crate) const SERIAL_POLL: u8 = 0x04;
    pub const EOI: u8 = 0x01;
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Header {
    pub op: u8,
    pub version: u8,
    pub seq: u8,
    pub len: u32,
}

/// A header and its payload.
pub type Block = Framed<Header>;

/// Incremental VICP block decoder with a payload limit.
pub type BlockDecoder = FramedDecoder<Header>;

impl FrameHeader for Header {
    const LEN: usize = HEADER_LEN;
    const FORMAT: &'static str = FORMAT;

    fn parse(b: &[u8]) -> Result<Self, CodecError> {
        if b.len() != HEADER_LEN || b[1] != VERSION {
            return Err(CodecError::BadHeader {
                format: FORMAT,
                detail: "header version is not 1",
            });
        }
        Ok(Self {
            op: b[0],
            version: b[1],
            seq: b[2],
            len: u32::from_be_bytes([b[4], b[5], b[6], b[7]]),
        })
    }

    fn payload_len(&self) -> u64 {
        u64::from(self.len)
    }
}

impl Header {
    pub fn new(op: u8, seq: u8, len: u32) -> Self {
        Self {
            op,
            version: VERSION,
            seq,
            len,
        }
    }

    pub fn encode(&self) -> [u8; HEADER_LEN] {
        let l = self.len.to_be_bytes();
        [self.op, self.version, self.seq, 0, l[0], l[1], l[2], l[3]]
    }

    pub fn parse(b: &[u8; HEADER_LEN]) -> Result<Self, CodecError> {
        <Self as FrameHeader>::parse(b)
    }

    pub(crate) fn eoi(&self) -> bool {
        self.op & op::EOI != 0
    }
}

/// The next sequence number: 1..=255, never 0.
pub(crate) fn next_seq(seq: u8) -> u8 {
    if seq == 255 {
        1
    } else {
        seq + 1
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn blocks(chunks: &[&[u8]], limit: u64) -> Result<Vec<Block>, CodecError> {
        crate::transport::io::decode_chunks(BlockDecoder::new(limit), chunks)
    }

    // Golden frames at every split, arbitrary bytes and round trips: the shared codec
    // conformance harness in tests/io_fuzz.rs. Here: encoding, and the errors.

    #[test]
    fn golden_encoding() {
        assert_eq!(
            Header::new(0x81, 5, 3).encode(),
            [0x81, 1, 5, 0, 0, 0, 0, 3]
        );
        assert_eq!(
            Header::new(0x90, 1, 0).encode(),
            [0x90, 1, 1, 0, 0, 0, 0, 0]
        );
    }

    #[test]
    fn sequence_wraps_without_zero() {
        assert_eq!(next_seq(1), 2);
        assert_eq!(next_seq(255), 1);
    }

    #[test]
    fn bad_version_and_oversize_are_errors() {
        assert!(blocks(&[&[0x81, 2, 1, 0, 0, 0, 0, 0]], 64).is_err());
        assert!(matches!(
            blocks(&[&[0x81, 1, 1, 0, 0xFF, 0xFF, 0xFF, 0xFF]], 64),
            Err(CodecError::TooLarge { .. })
        ));
    }
}
