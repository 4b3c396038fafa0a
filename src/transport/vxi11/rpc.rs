//! ONC-RPC v2 over TCP (RFC 5531): record marking with multi-fragment reassembly, XDR primitives,
//! and call/reply headers with AUTH_NONE.

use crate::transport::error::CodecError;
use crate::transport::io::{buffer_ceiling, reserve_announced, reserve_within, Decode};
use bytes::{Buf, Bytes, BytesMut};

const FORMAT: &str = "ONC-RPC record";
const LAST_FRAGMENT: u32 = 0x8000_0000;

/// The RPC protocol version spoken.
pub(crate) const RPC_VERSION: u32 = 2;
/// `msg_type` of a call and of a reply.
pub(crate) const CALL: u32 = 0;
pub(crate) const REPLY: u32 = 1;
/// `reply_stat`: accepted (results or an accept status follow) or denied.
pub(crate) const MSG_ACCEPTED: u32 = 0;
pub(crate) const MSG_DENIED: u32 = 1;
/// The authentication flavour sent in calls.
pub(crate) const AUTH_NONE: u32 = 0;

/// `accept_stat` of an accepted reply.
pub mod accept {
    pub(crate) const SUCCESS: u32 = 0;
    pub(crate) const PROG_UNAVAIL: u32 = 1;
    pub(crate) const PROG_MISMATCH: u32 = 2;
    pub(crate) const PROC_UNAVAIL: u32 = 3;
    pub(crate) const GARBAGE_ARGS: u32 = 4;
    pub(crate) const SYSTEM_ERR: u32 = 5;
}

/// `reject_stat` of a denied reply.
pub(crate) const RPC_MISMATCH: u32 = 0;

/// The 4-byte record-marking header for a fragment of `len` bytes.
pub fn record_mark(len: u32, last: bool) -> [u8; 4] {
    (len & !LAST_FRAGMENT | if last { LAST_FRAGMENT } else { 0 }).to_be_bytes()
}

/// Reassembles records from fragments. A single-fragment record is returned without copying.
#[derive(Debug, Clone)]
pub struct RecordDecoder {
    limit: u64,
    /// Earlier fragments of a multi-fragment record.
    assembled: BytesMut,
    /// The header of the fragment being read: (length, last).
    pending: Option<(u32, bool)>,
}

impl RecordDecoder {
    pub fn new(limit: u64) -> Self {
        Self {
            limit,
            assembled: BytesMut::new(),
            pending: None,
        }
    }
}

impl Decode for RecordDecoder {
    type Item = Bytes;

    fn decode(&mut self, src: &mut BytesMut) -> Result<Option<Bytes>, CodecError> {
        loop {
            let (len, last) = match self.pending {
                Some(p) => p,
                None => {
                    if src.len() < 4 {
                        return Ok(None);
                    }
                    let word = u32::from_be_bytes(src[..4].try_into().expect("4 bytes"));
                    let len = word & !LAST_FRAGMENT;
                    let total = self.assembled.len() as u64 + u64::from(len);
                    if total > self.limit {
                        return Err(CodecError::TooLarge {
                            format: FORMAT,
                            announced: total,
                            limit: self.limit,
                        });
                    }
                    src.advance(4);
                    let p = (len, word & LAST_FRAGMENT != 0);
                    self.pending = Some(p);
                    p
                }
            };
            let len = len as usize;
            if src.len() < len {
                reserve_announced(src, len - src.len(), self.limit);
                return Ok(None);
            }
            self.pending = None;
            let fragment = src.split_to(len);
            if last && self.assembled.is_empty() {
                return Ok(Some(fragment.freeze()));
            }
            // The total was checked against the limit with the fragment's header.
            let ceiling = buffer_ceiling(usize::try_from(self.limit).unwrap_or(usize::MAX));
            reserve_within(&mut self.assembled, fragment.len(), ceiling);
            self.assembled.extend_from_slice(&fragment);
            if last {
                return Ok(Some(std::mem::take(&mut self.assembled).freeze()));
            }
        }
    }

    fn announced(&self) -> u64 {
        self.pending
            .map_or(0, |(len, _)| self.assembled.len() as u64 + u64::from(len))
    }
}

/// Builds XDR: big-endian 4-byte items, opaque data padded to 4 bytes.
#[derive(Debug, Default, Clone)]
pub struct XdrWriter {
    pub buf: Vec<u8>,
}

impl XdrWriter {
    pub fn u32(&mut self, v: u32) -> &mut Self {
        self.buf.extend_from_slice(&v.to_be_bytes());
        self
    }
    pub fn i32(&mut self, v: i32) -> &mut Self {
        self.u32(v as u32)
    }
    pub fn bool(&mut self, v: bool) -> &mut Self {
        self.u32(u32::from(v))
    }
    pub fn opaque(&mut self, data: &[u8]) -> &mut Self {
        self.u32(data.len() as u32);
        self.buf.extend_from_slice(data);
        self.buf.extend_from_slice(&[0u8; 3][..pad(data.len())]);
        self
    }
}

/// Zero bytes that follow opaque data of `len` bytes.
pub fn pad(len: usize) -> usize {
    (4 - len % 4) % 4
}

/// Reads XDR from a record without copying opaque data.
#[derive(Debug, Clone)]
pub struct XdrReader {
    buf: Bytes,
}

impl XdrReader {
    pub fn new(buf: Bytes) -> Self {
        Self { buf }
    }
    pub fn u32(&mut self, field: &'static str) -> Result<u32, CodecError> {
        if self.buf.len() < 4 {
            return Err(CodecError::Xdr { field });
        }
        Ok(self.buf.get_u32())
    }
    pub fn i32(&mut self, field: &'static str) -> Result<i32, CodecError> {
        self.u32(field).map(|v| v as i32)
    }
    pub fn opaque(&mut self, field: &'static str) -> Result<Bytes, CodecError> {
        let len = self.u32(field)? as usize;
        let padded = len.checked_add(pad(len)).ok_or(CodecError::Xdr { field })?;
        if self.buf.len() < padded {
            return Err(CodecError::Xdr { field });
        }
        let data = self.buf.slice(..len);
        self.buf.advance(padded);
        Ok(data)
    }
}

/// The fixed words of a CALL header up to and including the procedure, then AUTH_NONE cred and verf.
pub(crate) fn encode_call_header(w: &mut XdrWriter, xid: u32, prog: u32, vers: u32, proc_: u32) {
    w.u32(xid)
        .u32(CALL)
        .u32(RPC_VERSION)
        .u32(prog)
        .u32(vers)
        .u32(proc_);
    // Credentials and verifier: AUTH_NONE with an empty body.
    w.u32(AUTH_NONE).u32(0).u32(AUTH_NONE).u32(0);
}

/// Why a reply did not carry results.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ReplyFault {
    /// MSG_DENIED (RPC version mismatch or authentication).
    Denied(u32),
    /// MSG_ACCEPTED with a non-SUCCESS accept_stat.
    NotAccepted(u32),
}

impl ReplyFault {
    pub fn code(&self) -> u32 {
        match self {
            ReplyFault::Denied(c) | ReplyFault::NotAccepted(c) => *c,
        }
    }
    pub fn meaning(&self) -> &'static str {
        match self {
            ReplyFault::Denied(RPC_MISMATCH) => "RPC version mismatch",
            ReplyFault::Denied(_) => "authentication refused",
            ReplyFault::NotAccepted(accept::PROG_UNAVAIL) => "program unavailable",
            ReplyFault::NotAccepted(accept::PROG_MISMATCH) => "program version mismatch",
            ReplyFault::NotAccepted(accept::PROC_UNAVAIL) => "procedure unavailable",
            ReplyFault::NotAccepted(accept::GARBAGE_ARGS) => "garbage arguments",
            ReplyFault::NotAccepted(accept::SYSTEM_ERR) => "system error",
            ReplyFault::NotAccepted(_) => "unknown accept status",
        }
    }
}

/// A decoded REPLY: its xid and either a reader at the results or the fault.
#[derive(Debug)]
pub struct Reply {
    pub xid: u32,
    pub outcome: Result<XdrReader, ReplyFault>,
}

/// Decodes the reply header of a record.
pub fn decode_reply(record: Bytes) -> Result<Reply, CodecError> {
    let mut r = XdrReader::new(record);
    let xid = r.u32("xid")?;
    if r.u32("msg_type")? != REPLY {
        return Err(CodecError::BadHeader {
            format: FORMAT,
            detail: "message is not a REPLY",
        });
    }
    match r.u32("reply_stat")? {
        MSG_ACCEPTED => {
            let _flavor = r.u32("verf.flavor")?;
            let _body = r.opaque("verf.body")?;
            match r.u32("accept_stat")? {
                accept::SUCCESS => Ok(Reply {
                    xid,
                    outcome: Ok(r),
                }),
                stat => Ok(Reply {
                    xid,
                    outcome: Err(ReplyFault::NotAccepted(stat)),
                }),
            }
        }
        MSG_DENIED => {
            let stat = r.u32("reject_stat")?;
            Ok(Reply {
                xid,
                outcome: Err(ReplyFault::Denied(stat)),
            })
        }
        _ => Err(CodecError::BadHeader {
            format: FORMAT,
            detail: "reply_stat is neither accepted nor denied",
        }),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn records(chunks: &[&[u8]], limit: u64) -> Result<Vec<Bytes>, CodecError> {
        crate::transport::io::decode_chunks(RecordDecoder::new(limit), chunks)
    }

    // Golden records at every split, arbitrary bytes (records and XDR) and round trips: the
    // shared codec conformance harness in tests/io_fuzz.rs. Here: encoding, and the errors.

    #[test]
    fn record_marks() {
        assert_eq!(record_mark(4, true), [0x80, 0, 0, 4]);
        assert_eq!(record_mark(3, false), [0, 0, 0, 3]);
    }

    #[test]
    fn total_over_limit_is_refused_across_fragments() {
        let wire = [&[0u8, 0, 0, 40][..], &[0; 40], &[0x80, 0, 0, 40]].concat();
        assert!(matches!(
            records(&[&wire], 64),
            Err(CodecError::TooLarge { .. })
        ));
    }

    #[test]
    fn golden_call_and_reply() {
        let mut w = XdrWriter::default();
        encode_call_header(&mut w, 0x1234_5678, 0x0607AF, 1, 10);
        assert_eq!(
            w.buf,
            [
                0x12, 0x34, 0x56, 0x78, 0, 0, 0, 0, 0, 0, 0, 2, 0, 0x06, 0x07, 0xAF, 0, 0, 0, 1, 0,
                0, 0, 10, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0
            ]
        );
        let reply: &[u8] = &[
            0x12, 0x34, 0x56, 0x78, 0, 0, 0, 1, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0,
            0, 0, 7, b'a', b'b', b'c', b'd', b'e', b'f', b'g', 0,
        ];
        let r = decode_reply(Bytes::copy_from_slice(reply)).unwrap();
        assert_eq!(r.xid, 0x1234_5678);
        let mut results = r.outcome.unwrap();
        assert_eq!(&results.opaque("data").unwrap()[..], b"abcdefg");
        let mut w = XdrWriter::default();
        w.opaque(b"inst0");
        assert_eq!(w.buf, [0, 0, 0, 5, b'i', b'n', b's', b't', b'0', 0, 0, 0]);
    }

    #[test]
    fn reply_faults_are_reported() {
        let reply: &[u8] = &[
            0, 0, 0, 9, 0, 0, 0, 1, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 3,
        ];
        let r = decode_reply(Bytes::copy_from_slice(reply)).unwrap();
        assert_eq!(r.outcome.unwrap_err(), ReplyFault::NotAccepted(3));
    }
}
