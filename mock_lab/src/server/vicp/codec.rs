//! VICP block codec (LeCroy): an 8-byte header `operation, version 1, sequence, reserved,
//! length u32 big-endian`, then the payload. Pure functions, no I/O.

use thiserror::Error;

/// Header length in bytes.
pub const HEADER_LEN: usize = 8;
/// The only header version in use.
pub const VERSION: u8 = 1;

/// Operation bits (byte 0), every bit of the header's table.
#[allow(dead_code)]
pub(crate) mod op {
    pub(crate) const DATA: u8 = 0x80;
    pub(crate) const REMOTE: u8 = 0x40;
    pub(crate) const LOCKOUT: u8 = 0x20;
    pub(crate) const CLEAR: u8 = 0x10;
    pub(crate) const SRQ: u8 = 0x08;
    pub(crate) const SERIAL_POLL: u8 = 0x04;
    pub(crate) const EOI: u8 = 0x01;
}

/// A VICP protocol violation or a link failure.
#[derive(Debug, Error)]
pub enum VicpError {
    /// Header version other than 1.
    #[error(
        "VICP header version must be 1, got {0}; the peer is out of sync or not speaking VICP"
    )]
    BadVersion(u8),
    /// A block longer than the server accepts.
    #[error("VICP block of {len} bytes (message so far {so_far}) exceeds the maximum message size of {max} bytes")]
    TooLarge {
        /// Announced block length.
        len: u32,
        /// Bytes of the message already received.
        so_far: usize,
        /// Accepted maximum.
        max: usize,
    },
    /// Socket error.
    #[error("socket error: {0}")]
    Io(#[from] std::io::Error),
}

/// A decoded block header.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Header {
    /// Operation bits (see `op`).
    pub op: u8,
    /// Sequence number (1..=255 in VICP 1a, 0 from old clients).
    pub seq: u8,
    /// Payload length.
    pub len: u32,
}

impl Header {
    /// The 8 wire bytes.
    pub fn encode(&self) -> [u8; HEADER_LEN] {
        let l = self.len.to_be_bytes();
        [self.op, VERSION, self.seq, 0, l[0], l[1], l[2], l[3]]
    }

    /// Decodes 8 wire bytes, checking the version.
    pub fn decode(b: &[u8; HEADER_LEN]) -> Result<Header, VicpError> {
        if b[1] != VERSION {
            return Err(VicpError::BadVersion(b[1]));
        }
        Ok(Header {
            op: b[0],
            seq: b[2],
            len: u32::from_be_bytes([b[4], b[5], b[6], b[7]]),
        })
    }
}

/// A decoded block: header, payload, bytes consumed from the buffer.
pub type Decoded<'a> = (Header, &'a [u8], usize);

/// Decodes the first whole block in `buf`: `Ok(None)` until all of it has arrived. The length
/// is checked against `max` before the payload is looked at.
#[cfg(test)]
pub(crate) fn decode_block(buf: &[u8], max: usize) -> Result<Option<Decoded<'_>>, VicpError> {
    if buf.len() >= 2 && buf[1] != VERSION {
        return Err(VicpError::BadVersion(buf[1]));
    }
    let Some(head) = buf.first_chunk::<HEADER_LEN>() else {
        return Ok(None);
    };
    let header = Header::decode(head)?;
    if header.len as usize > max {
        return Err(VicpError::TooLarge {
            len: header.len,
            so_far: 0,
            max,
        });
    }
    let end = HEADER_LEN + header.len as usize;
    if buf.len() < end {
        return Ok(None);
    }
    Ok(Some((header, &buf[HEADER_LEN..end], end)))
}

/// The next sequence number after `seq` in the 1..=255 ring (0 is never used).
pub fn next_seq(seq: u8) -> u8 {
    if seq == 255 {
        1
    } else {
        seq + 1
    }
}

/// The sequence number before `seq` in the 1..=255 ring.
pub(crate) fn previous_seq(seq: u8) -> u8 {
    if seq <= 1 {
        255
    } else {
        seq - 1
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// pyvicp's `*IDN?` command: DATA|EOI, version 1, sequence 1, 5 bytes.
    const GOLDEN_IDN: &[u8] = b"\x81\x01\x01\x00\x00\x00\x00\x05*IDN?";
    /// pyvicp's device clear: DATA|CLEAR, no payload.
    const GOLDEN_CLEAR: &[u8] = b"\x90\x01\x02\x00\x00\x00\x00\x00";

    #[test]
    fn golden_blocks_decode_and_encode() {
        let (h, payload, used) = decode_block(GOLDEN_IDN, 100).unwrap().unwrap();
        assert_eq!(
            h,
            Header {
                op: op::DATA | op::EOI,
                seq: 1,
                len: 5
            }
        );
        assert_eq!((payload, used), (&b"*IDN?"[..], GOLDEN_IDN.len()));
        assert_eq!(&h.encode()[..], &GOLDEN_IDN[..8]);
        let (h, _, _) = decode_block(GOLDEN_CLEAR, 100).unwrap().unwrap();
        assert_eq!(h.op & op::CLEAR, op::CLEAR);
    }

    #[test]
    fn every_split_waits_for_the_whole_block() {
        let stream = [GOLDEN_IDN, GOLDEN_CLEAR].concat();
        for at in 0..=stream.len() {
            let mut buf = stream[..at].to_vec();
            let mut got = Vec::new();
            while let Some((h, p, used)) = decode_block(&buf, 100).unwrap() {
                got.push((h, p.to_vec()));
                buf.drain(..used);
            }
            buf.extend_from_slice(&stream[at..]);
            while let Some((h, p, used)) = decode_block(&buf, 100).unwrap() {
                got.push((h, p.to_vec()));
                buf.drain(..used);
            }
            assert_eq!(got.len(), 2, "split at {at}");
            assert_eq!(got[0].1, b"*IDN?");
        }
    }

    #[test]
    fn limits_and_versions_are_checked_from_the_header() {
        assert!(matches!(
            decode_block(b"\x81\x01\x01\x00\xff\xff\xff\xff", 1000),
            Err(VicpError::TooLarge { .. })
        ));
        assert!(matches!(
            decode_block(b"\x81\x02", 1000),
            Err(VicpError::BadVersion(2))
        ));
    }

    #[test]
    fn sequence_numbers_skip_zero() {
        assert_eq!(next_seq(255), 1);
        assert_eq!(previous_seq(1), 255);
        assert_eq!(next_seq(7), 8);
    }

    proptest::proptest! {
        #[test]
        fn arbitrary_bytes_never_panic(bytes in proptest::collection::vec(proptest::num::u8::ANY, 0..64)) {
            let _ = decode_block(&bytes, 16);
        }
    }
}
