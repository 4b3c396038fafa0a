//! HiSLIP message codec (IVI-6.1): a 16-byte big-endian header `"HS", type u8, control u8,
//! parameter u32, payload length u64`, then the payload. Pure functions, no I/O.

use thiserror::Error;

/// Header length in bytes.
pub const HEADER_LEN: usize = 16;
/// Every header starts with these two bytes.
pub(crate) const PROLOGUE: [u8; 2] = *b"HS";

/// Message type codes of the HiSLIP specification; kept whole (some only name what a client
/// may send) so the table reads like the spec's.
#[allow(dead_code)]
pub(crate) mod kind {
    pub(crate) const INITIALIZE: u8 = 0;
    pub(crate) const INITIALIZE_RESPONSE: u8 = 1;
    pub(crate) const FATAL_ERROR: u8 = 2;
    pub(crate) const ERROR: u8 = 3;
    pub(crate) const ASYNC_LOCK: u8 = 4;
    pub(crate) const ASYNC_LOCK_RESPONSE: u8 = 5;
    pub(crate) const DATA: u8 = 6;
    pub(crate) const DATA_END: u8 = 7;
    pub(crate) const DEVICE_CLEAR_COMPLETE: u8 = 8;
    pub(crate) const DEVICE_CLEAR_ACKNOWLEDGE: u8 = 9;
    pub(crate) const ASYNC_REMOTE_LOCAL_CONTROL: u8 = 10;
    pub(crate) const ASYNC_REMOTE_LOCAL_RESPONSE: u8 = 11;
    pub(crate) const TRIGGER: u8 = 12;
    pub(crate) const INTERRUPTED: u8 = 13;
    pub(crate) const ASYNC_INTERRUPTED: u8 = 14;
    pub(crate) const ASYNC_MAX_MSG_SIZE: u8 = 15;
    pub(crate) const ASYNC_MAX_MSG_SIZE_RESPONSE: u8 = 16;
    pub(crate) const ASYNC_INITIALIZE: u8 = 17;
    pub(crate) const ASYNC_INITIALIZE_RESPONSE: u8 = 18;
    pub(crate) const ASYNC_DEVICE_CLEAR: u8 = 19;
    pub(crate) const ASYNC_SERVICE_REQUEST: u8 = 20;
    pub(crate) const ASYNC_STATUS_QUERY: u8 = 21;
    pub(crate) const ASYNC_STATUS_RESPONSE: u8 = 22;
    pub(crate) const ASYNC_DEVICE_CLEAR_ACKNOWLEDGE: u8 = 23;
    pub(crate) const ASYNC_LOCK_INFO: u8 = 24;
    pub(crate) const ASYNC_LOCK_INFO_RESPONSE: u8 = 25;
}

/// FatalError control codes (the specification's whole table).
#[allow(dead_code)]
pub(crate) mod fatal {
    pub(crate) const UNIDENTIFIED: u8 = 0;
    pub(crate) const POORLY_FORMED_HEADER: u8 = 1;
    pub(crate) const CHANNELS_NOT_ESTABLISHED: u8 = 2;
    pub(crate) const INVALID_INIT_SEQUENCE: u8 = 3;
}

/// Error (non-fatal) control codes.
pub(crate) mod nonfatal {
    pub(crate) const UNRECOGNIZED_MESSAGE_TYPE: u8 = 1;
    pub(crate) const UNRECOGNIZED_CONTROL_CODE: u8 = 2;
    pub(crate) const MESSAGE_TOO_LARGE: u8 = 4;
}

/// A HiSLIP protocol violation or a link failure.
#[derive(Debug, Error)]
pub enum HislipError {
    /// The header does not start with "HS".
    #[error("HiSLIP header must start with \"HS\", got {0:02x?}; the peer is out of sync or not speaking HiSLIP")]
    BadPrologue([u8; 2]),
    /// A payload longer than the server accepts.
    #[error("HiSLIP payload of {len} bytes exceeds the maximum of {max} bytes; split the message (AsyncMaxMsgSize tells the limit)")]
    PayloadTooLarge {
        /// Announced payload length.
        len: u64,
        /// Accepted maximum.
        max: u64,
    },
    /// The first message on a connection was neither Initialize nor AsyncInitialize.
    #[error(
        "a HiSLIP connection must start with Initialize or AsyncInitialize, got message type {0}"
    )]
    InvalidInitSequence(u8),
    /// AsyncInitialize named a session the server does not know.
    #[error("AsyncInitialize names session {0}, which does not exist; send Initialize on the synchronous channel first")]
    UnknownSession(u16),
    /// The client reported a fatal error.
    #[error("the client sent FatalError code {0}")]
    ClientFatal(u8),
    /// Socket error.
    #[error("socket error: {0}")]
    Io(#[from] std::io::Error),
}

/// A decoded message header.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Header {
    /// Message type (see `kind`).
    pub kind: u8,
    /// Control code.
    pub control: u8,
    /// Message parameter.
    pub param: u32,
    /// Payload length that follows the header.
    pub payload_len: u64,
}

impl Header {
    /// A header for `kind` with the given fields.
    pub fn new(kind: u8, control: u8, param: u32, payload_len: u64) -> Header {
        Header {
            kind,
            control,
            param,
            payload_len,
        }
    }

    /// The 16 wire bytes.
    pub fn encode(&self) -> [u8; HEADER_LEN] {
        let mut out = [0u8; HEADER_LEN];
        out[..2].copy_from_slice(&PROLOGUE);
        out[2] = self.kind;
        out[3] = self.control;
        out[4..8].copy_from_slice(&self.param.to_be_bytes());
        out[8..16].copy_from_slice(&self.payload_len.to_be_bytes());
        out
    }

    /// Decodes 16 wire bytes, checking the prologue.
    pub fn decode(bytes: &[u8; HEADER_LEN]) -> Result<Header, HislipError> {
        if bytes[..2] != PROLOGUE {
            return Err(HislipError::BadPrologue([bytes[0], bytes[1]]));
        }
        Ok(Header {
            kind: bytes[2],
            control: bytes[3],
            param: u32::from_be_bytes([bytes[4], bytes[5], bytes[6], bytes[7]]),
            payload_len: u64::from_be_bytes([
                bytes[8], bytes[9], bytes[10], bytes[11], bytes[12], bytes[13], bytes[14],
                bytes[15],
            ]),
        })
    }

    /// Checks the payload length against `max` (before anything is allocated for it).
    pub fn check_payload(&self, max: u64) -> Result<(), HislipError> {
        if self.payload_len > max {
            return Err(HislipError::PayloadTooLarge {
                len: self.payload_len,
                max,
            });
        }
        Ok(())
    }
}

/// A decoded message: header, payload, bytes consumed from the buffer.
pub type Decoded<'a> = (Header, &'a [u8], usize);

/// One whole message: header plus payload, encoded.
pub(crate) fn encode_message(kind: u8, control: u8, param: u32, payload: &[u8]) -> Vec<u8> {
    let mut out = Vec::with_capacity(HEADER_LEN + payload.len());
    out.extend_from_slice(&Header::new(kind, control, param, payload.len() as u64).encode());
    out.extend_from_slice(payload);
    out
}

/// Decodes the first whole message in `buf`: `Ok(None)` until all of it has arrived. Returns the
/// header, the payload and the bytes consumed. The length is checked against `max_payload`
/// before the payload is looked at.
#[cfg(test)]
pub(crate) fn decode_message(
    buf: &[u8],
    max_payload: u64,
) -> Result<Option<Decoded<'_>>, HislipError> {
    let Some(head) = buf.first_chunk::<HEADER_LEN>() else {
        // Fail early on a wrong prologue even before the header is complete.
        if buf.iter().zip(PROLOGUE.iter()).any(|(a, b)| a != b) {
            let mut got = [0u8; 2];
            got[..buf.len().min(2)].copy_from_slice(&buf[..buf.len().min(2)]);
            return Err(HislipError::BadPrologue(got));
        }
        return Ok(None);
    };
    let header = Header::decode(head)?;
    header.check_payload(max_payload)?;
    let end = HEADER_LEN as u64 + header.payload_len;
    if (buf.len() as u64) < end {
        return Ok(None);
    }
    Ok(Some((header, &buf[HEADER_LEN..end as usize], end as usize)))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// pyvisa-py's Initialize: version 1.0, vendor "xx", sub-address "hislip0".
    const GOLDEN_INIT: &[u8] = b"HS\x00\x00\x01\x00xx\x00\x00\x00\x00\x00\x00\x00\x07hislip0";

    #[test]
    fn golden_initialize_decodes() {
        let (h, payload, used) = decode_message(GOLDEN_INIT, 1024).unwrap().unwrap();
        assert_eq!(h, Header::new(kind::INITIALIZE, 0, 0x0100_7878, 7));
        assert_eq!(payload, b"hislip0");
        assert_eq!(used, GOLDEN_INIT.len());
        assert_eq!(
            encode_message(h.kind, h.control, h.param, payload),
            GOLDEN_INIT
        );
    }

    #[test]
    fn golden_data_end_encodes() {
        let bytes = encode_message(kind::DATA_END, 1, 0xFFFF_FF00, b"*IDN?\n");
        assert_eq!(
            bytes,
            b"HS\x07\x01\xff\xff\xff\x00\x00\x00\x00\x00\x00\x00\x00\x06*IDN?\n".to_vec()
        );
    }

    #[test]
    fn every_split_waits_for_the_whole_message() {
        let mut stream = GOLDEN_INIT.to_vec();
        stream.extend_from_slice(&encode_message(kind::DATA_END, 0, 7, b"#15ab\ncd"));
        for at in 0..stream.len() {
            let mut buf = stream[..at].to_vec();
            let mut got = Vec::new();
            while let Some((h, p, used)) = decode_message(&buf, 1024).unwrap() {
                got.push((h, p.to_vec()));
                buf.drain(..used);
            }
            buf.extend_from_slice(&stream[at..]);
            while let Some((h, p, used)) = decode_message(&buf, 1024).unwrap() {
                got.push((h, p.to_vec()));
                buf.drain(..used);
            }
            assert_eq!(got.len(), 2, "split at {at}");
            assert_eq!(got[1].1, b"#15ab\ncd");
            assert!(buf.is_empty());
        }
    }

    #[test]
    fn oversized_payload_is_refused_from_the_header() {
        let header = Header::new(kind::DATA, 0, 0, u64::MAX).encode();
        assert!(matches!(
            decode_message(&header, 1 << 20),
            Err(HislipError::PayloadTooLarge { .. })
        ));
    }

    #[test]
    fn bad_prologue_is_refused() {
        assert!(matches!(
            decode_message(b"XS", 10),
            Err(HislipError::BadPrologue(_))
        ));
    }

    proptest::proptest! {
        #[test]
        fn arbitrary_bytes_never_panic(bytes in proptest::collection::vec(proptest::num::u8::ANY, 0..64)) {
            let _ = decode_message(&bytes, 32);
        }
    }
}
