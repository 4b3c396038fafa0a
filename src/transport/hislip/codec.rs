//! HiSLIP (IVI-6.1) wire format: a 16-byte big-endian header `"HS", type u8, control u8,
//! parameter u32, payload length u64`, then the payload.

use crate::transport::error::CodecError;
use crate::transport::io::{FrameHeader, Framed, FramedDecoder};

pub const HEADER_LEN: usize = 16;
const FORMAT: &str = "HiSLIP";

/// HiSLIP message types; kept whole (some only name what a server may send) so the table
/// reads like the spec's.
#[allow(dead_code)]
pub mod msg {
    pub(crate) const INITIALIZE: u8 = 0;
    pub const INITIALIZE_RESPONSE: u8 = 1;
    pub(crate) const FATAL_ERROR: u8 = 2;
    pub(crate) const ERROR: u8 = 3;
    pub const DATA: u8 = 6;
    pub const DATA_END: u8 = 7;
    pub(crate) const DEVICE_CLEAR_COMPLETE: u8 = 8;
    pub(crate) const DEVICE_CLEAR_ACKNOWLEDGE: u8 = 9;
    pub(crate) const TRIGGER: u8 = 12;
    pub(crate) const INTERRUPTED: u8 = 13;
    pub(crate) const ASYNC_INTERRUPTED: u8 = 14;
    pub(crate) const ASYNC_MAX_MSG_SIZE: u8 = 15;
    pub const ASYNC_MAX_MSG_SIZE_RESPONSE: u8 = 16;
    pub(crate) const ASYNC_INITIALIZE: u8 = 17;
    pub const ASYNC_INITIALIZE_RESPONSE: u8 = 18;
    pub(crate) const ASYNC_DEVICE_CLEAR: u8 = 19;
    pub(crate) const ASYNC_SERVICE_REQUEST: u8 = 20;
    pub(crate) const ASYNC_STATUS_QUERY: u8 = 21;
    pub(crate) const ASYNC_STATUS_RESPONSE: u8 = 22;
    pub(crate) const ASYNC_DEVICE_CLEAR_ACKNOWLEDGE: u8 = 23;
}

/// The meaning of a FatalError control code.
pub(crate) fn fatal_error_meaning(code: u8) -> &'static str {
    match code {
        0 => "unidentified error",
        1 => "poorly formed message header",
        2 => "attempt to use connection without both channels established",
        3 => "invalid initialization sequence",
        4 => "server refused connection due to maximum number of clients exceeded",
        5 => "secure connection failed",
        _ => "unknown fatal error code",
    }
}

/// The meaning of an Error control code.
pub(crate) fn error_meaning(code: u8) -> &'static str {
    match code {
        0 => "unidentified error",
        1 => "unrecognized message type",
        2 => "unrecognized control code",
        3 => "unrecognized vendor defined message",
        4 => "message too large",
        5 => "authentication failed",
        _ => "unknown error code",
    }
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Header {
    pub msg_type: u8,
    pub control: u8,
    pub param: u32,
    pub len: u64,
}

/// A header and its payload.
pub type Frame = Framed<Header>;

/// Incremental HiSLIP frame decoder with a payload limit.
pub type FrameDecoder = FramedDecoder<Header>;

impl FrameHeader for Header {
    const LEN: usize = HEADER_LEN;
    const FORMAT: &'static str = FORMAT;

    fn parse(bytes: &[u8]) -> Result<Self, CodecError> {
        if bytes.len() != HEADER_LEN || &bytes[0..2] != b"HS" {
            return Err(CodecError::BadHeader {
                format: FORMAT,
                detail: "missing the \"HS\" prologue",
            });
        }
        let be =
            |r: std::ops::Range<usize>| bytes[r].iter().fold(0u64, |v, &b| v << 8 | u64::from(b));
        Ok(Self {
            msg_type: bytes[2],
            control: bytes[3],
            param: be(4..8) as u32,
            len: be(8..16),
        })
    }

    fn payload_len(&self) -> u64 {
        self.len
    }
}

impl Header {
    pub fn new(msg_type: u8, control: u8, param: u32, len: u64) -> Self {
        Self {
            msg_type,
            control,
            param,
            len,
        }
    }

    pub fn encode(&self) -> [u8; HEADER_LEN] {
        let mut out = [0u8; HEADER_LEN];
        out[0] = b'H';
        out[1] = b'S';
        out[2] = self.msg_type;
        out[3] = self.control;
        out[4..8].copy_from_slice(&self.param.to_be_bytes());
        out[8..16].copy_from_slice(&self.len.to_be_bytes());
        out
    }

    pub fn parse(bytes: &[u8; HEADER_LEN]) -> Result<Self, CodecError> {
        <Self as FrameHeader>::parse(bytes)
    }
}

/// Encodes a whole message with a small payload (control messages).
pub fn encode_frame(msg_type: u8, control: u8, param: u32, payload: &[u8]) -> Vec<u8> {
    let mut out = Vec::with_capacity(HEADER_LEN + payload.len());
    out.extend_from_slice(&Header::new(msg_type, control, param, payload.len() as u64).encode());
    out.extend_from_slice(payload);
    out
}

/// Initialize parameter: protocol version 1.0 and the vendor ID "RB" (radbench).
pub(crate) const CLIENT_PROTOCOL_AND_VENDOR: u32 = (1 << 24) | ((b'R' as u32) << 8) | b'B' as u32;
/// The first MessageID a client uses, and again after a device clear.
pub(crate) const FIRST_MESSAGE_ID: u32 = 0xFFFF_FF00;

#[cfg(test)]
mod tests {
    use super::*;
    use crate::transport::Decode;
    use bytes::BytesMut;

    fn frames(chunks: &[&[u8]], limit: u64) -> Result<Vec<Frame>, CodecError> {
        crate::transport::io::decode_chunks(FrameDecoder::new(limit), chunks)
    }

    // Golden frames at every split, arbitrary bytes and round trips: the shared codec
    // conformance harness in tests/io_fuzz.rs. Here: encoding, and the errors.

    #[test]
    fn golden_encoding() {
        assert_eq!(
            encode_frame(msg::DATA_END, 1, FIRST_MESSAGE_ID, b"1\n"),
            [b'H', b'S', 7, 1, 0xFF, 0xFF, 0xFF, 0x00, 0, 0, 0, 0, 0, 0, 0, 2, b'1', b'\n']
        );
        assert_eq!(
            encode_frame(msg::INITIALIZE, 0, CLIENT_PROTOCOL_AND_VENDOR, b"hislip0"),
            [
                &[b'H', b'S', 0, 0, 1, 0, b'R', b'B', 0, 0, 0, 0, 0, 0, 0, 7][..],
                b"hislip0"
            ]
            .concat()
        );
    }

    #[test]
    fn oversized_and_bad_prologue_are_errors() {
        let big = Header::new(msg::DATA, 0, 0, u64::MAX).encode();
        assert!(matches!(
            frames(&[&big], 1 << 20),
            Err(CodecError::TooLarge { .. })
        ));
        let mut bad = encode_frame(msg::DATA_END, 1, FIRST_MESSAGE_ID, b"1\n");
        bad[0] = b'X';
        assert!(matches!(
            frames(&[&bad], 1024),
            Err(CodecError::BadHeader { .. })
        ));
    }

    #[test]
    fn a_huge_announced_frame_reserves_at_most_the_presize_limit() {
        use crate::transport::io::PRESIZE_LIMIT;
        let mut dec = FrameDecoder::new(4 << 30);
        let mut buf = BytesMut::from(&Header::new(msg::DATA_END, 0, 0, 3 << 30).encode()[..]);
        assert!(dec.decode(&mut buf).unwrap().is_none());
        assert!(buf.capacity() >= PRESIZE_LIMIT && buf.capacity() < PRESIZE_LIMIT + 4096);
    }
}
