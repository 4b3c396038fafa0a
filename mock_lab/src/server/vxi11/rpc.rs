//! ONC RPC v2 over TCP (RFC 5531): record marking, call headers and reply headers. Pure code,
//! plus one async function that reads a whole record from a stream.

use thiserror::Error;
use tokio::io::{AsyncRead, AsyncReadExt};

use super::xdr::{XdrError, XdrReader, XdrWriter};
use crate::server::conn;

/// Bit 31 of a record-marking header: this fragment is the last of its record.
pub const LAST_FRAGMENT: u32 = 0x8000_0000;
/// Credentials and verifiers are at most this long (RFC 5531).
const MAX_AUTH: usize = 400;

/// The RPC protocol version this server speaks.
pub const RPC_VERSION: u32 = 2;
/// `msg_type` of a call and of a reply.
pub const CALL: u32 = 0;
pub const REPLY: u32 = 1;
/// `reply_stat`: accepted (results or an accept status follow) or denied.
pub const MSG_ACCEPTED: u32 = 0;
pub const MSG_DENIED: u32 = 1;
/// `reject_stat` of a denied reply: the RPC version is not supported.
pub const RPC_MISMATCH: u32 = 0;
/// The authentication flavour of the verifier this server sends.
pub const AUTH_NONE: u32 = 0;

/// Accept status of an accepted reply.
pub(crate) mod accept {
    pub(crate) const SUCCESS: u32 = 0;
    pub(crate) const PROG_UNAVAIL: u32 = 1;
    pub(crate) const PROG_MISMATCH: u32 = 2;
    pub(crate) const PROC_UNAVAIL: u32 = 3;
    pub(crate) const GARBAGE_ARGS: u32 = 4;
}

/// A malformed RPC message or a link failure.
#[derive(Debug, Error)]
pub(crate) enum RpcError {
    /// A record longer than the server accepts.
    #[error("RPC record of {len} bytes exceeds the maximum of {max} bytes; write smaller chunks (create_link reports maxRecvSize)")]
    RecordTooLarge {
        /// Bytes the record would have.
        len: u64,
        /// Accepted maximum.
        max: usize,
    },
    /// The message is not an RPC call.
    #[error("expected an RPC CALL (message type 0), got message type {0}")]
    NotACall(u32),
    /// The XDR body is malformed.
    #[error("malformed RPC message: {0}")]
    Xdr(#[from] XdrError),
    /// Socket error.
    #[error("socket error: {0}")]
    Io(#[from] std::io::Error),
}

/// Splits a record-marking header into (last fragment?, fragment length).
pub(crate) fn decode_fragment_header(word: [u8; 4]) -> (bool, u32) {
    let v = u32::from_be_bytes(word);
    (v & LAST_FRAGMENT != 0, v & !LAST_FRAGMENT)
}

/// The record-marking header for a one-fragment record of `len` bytes.
pub(crate) fn fragment_header(len: usize) -> [u8; 4] {
    (LAST_FRAGMENT | len as u32).to_be_bytes()
}

/// Reads one whole record (all fragments), refusing records longer than `max` before reading
/// their bytes. `Ok(None)` on a clean end of stream between records.
pub(crate) async fn read_record<R: AsyncRead + Unpin>(
    r: &mut R,
    max: usize,
) -> Result<Option<Vec<u8>>, RpcError> {
    let mut record = Vec::new();
    loop {
        let mut word = [0u8; 4];
        match r.read_exact(&mut word).await {
            Ok(_) => {}
            Err(e) if e.kind() == std::io::ErrorKind::UnexpectedEof && record.is_empty() => {
                return Ok(None)
            }
            Err(e) => return Err(e.into()),
        }
        let (last, len) = decode_fragment_header(word);
        let total = record.len() as u64 + u64::from(len);
        if total > max as u64 {
            return Err(RpcError::RecordTooLarge { len: total, max });
        }
        conn::read_exact_append(r, &mut record, u64::from(len)).await?;
        if last {
            return Ok(Some(record));
        }
    }
}

/// The part of a call header the server dispatches on.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Call {
    /// Transaction id, echoed in the reply.
    pub xid: u32,
    /// RPC protocol version (must be 2).
    pub rpc_version: u32,
    /// Program number.
    pub program: u32,
    /// Program version.
    pub version: u32,
    /// Procedure number.
    pub procedure: u32,
}

/// Decodes a call header; the reader is left at the procedure's arguments.
pub(crate) fn decode_call(r: &mut XdrReader<'_>) -> Result<Call, RpcError> {
    let xid = r.u32()?;
    let msg_type = r.u32()?;
    if msg_type != CALL {
        return Err(RpcError::NotACall(msg_type));
    }
    let rpc_version = r.u32()?;
    let program = r.u32()?;
    let version = r.u32()?;
    let procedure = r.u32()?;
    for _ in 0..2 {
        let _flavor = r.u32()?;
        r.opaque(MAX_AUTH)?;
    }
    Ok(Call {
        xid,
        rpc_version,
        program,
        version,
        procedure,
    })
}

/// Starts an accepted reply (MSG_ACCEPTED, AUTH_NONE verifier) with `status`; the caller
/// appends the results for SUCCESS. PROG_MISMATCH carries the supported version range.
pub(crate) fn accepted_reply(xid: u32, status: u32, versions: (u32, u32)) -> XdrWriter {
    let mut w = XdrWriter::new();
    w.u32(xid)
        .u32(REPLY)
        .u32(MSG_ACCEPTED)
        .u32(AUTH_NONE)
        .u32(0)
        .u32(status);
    if status == accept::PROG_MISMATCH {
        w.u32(versions.0).u32(versions.1);
    }
    w
}

/// A denied reply for an RPC version other than 2 (RPC_MISMATCH, supported 2..2).
pub(crate) fn rpc_mismatch_reply(xid: u32) -> XdrWriter {
    let mut w = XdrWriter::new();
    w.u32(xid)
        .u32(REPLY)
        .u32(MSG_DENIED)
        .u32(RPC_MISMATCH)
        .u32(RPC_VERSION)
        .u32(RPC_VERSION);
    w
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A GETPORT call to the portmapper for VXI-11 core, TCP (as pyvisa-py sends it).
    pub(crate) const GOLDEN_GETPORT: &[u8] = &[
        0x80, 0, 0, 56, // record mark: last fragment, 56 bytes
        0, 0, 0, 7, 0, 0, 0, 0, 0, 0, 0, 2, // xid 7, CALL, rpcvers 2
        0, 1, 0x86, 0xA0, 0, 0, 0, 2, 0, 0, 0, 3, // prog 100000, vers 2, proc 3
        0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, // cred, verf AUTH_NONE
        0, 0x06, 0x07, 0xAF, 0, 0, 0, 1, 0, 0, 0, 6, 0, 0, 0, 0, // 0x0607AF v1 TCP port 0
    ];

    #[test]
    fn golden_call_decodes() {
        let (last, len) = decode_fragment_header(GOLDEN_GETPORT[..4].try_into().unwrap());
        assert!(last);
        assert_eq!(len as usize, GOLDEN_GETPORT.len() - 4);
        let mut r = XdrReader::new(&GOLDEN_GETPORT[4..]);
        let call = decode_call(&mut r).unwrap();
        assert_eq!(
            call,
            Call {
                xid: 7,
                rpc_version: 2,
                program: 100_000,
                version: 2,
                procedure: 3
            }
        );
        assert_eq!(r.u32().unwrap(), 0x0607AF);
    }

    #[test]
    fn golden_reply_encodes() {
        let mut w = accepted_reply(7, accept::SUCCESS, (0, 0));
        w.u32(1024);
        assert_eq!(
            w.buf,
            [0, 0, 0, 7, 0, 0, 0, 1, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 4, 0]
        );
        assert_eq!(fragment_header(28), [0x80, 0, 0, 28]);
    }

    /// Feeds a stream in two reads split at every position.
    struct Split<'a> {
        parts: Vec<&'a [u8]>,
    }

    impl AsyncRead for Split<'_> {
        fn poll_read(
            mut self: std::pin::Pin<&mut Self>,
            _: &mut std::task::Context<'_>,
            buf: &mut tokio::io::ReadBuf<'_>,
        ) -> std::task::Poll<std::io::Result<()>> {
            while let Some(first) = self.parts.first_mut() {
                if first.is_empty() {
                    self.parts.remove(0);
                    continue;
                }
                let n = first.len().min(buf.remaining());
                buf.put_slice(&first[..n]);
                *first = &first[n..];
                break;
            }
            std::task::Poll::Ready(Ok(()))
        }
    }

    #[tokio::test]
    async fn records_reassemble_from_fragments_split_anywhere() {
        // The same call in two fragments: 10 bytes, then the rest with the last bit.
        let body = &GOLDEN_GETPORT[4..];
        let mut stream = vec![0, 0, 0, 10];
        stream.extend_from_slice(&body[..10]);
        stream.extend_from_slice(&fragment_header(body.len() - 10));
        stream.extend_from_slice(&body[10..]);
        for at in 0..=stream.len() {
            let mut r = Split {
                parts: vec![&stream[..at], &stream[at..]],
            };
            let record = read_record(&mut r, 1024).await.unwrap().unwrap();
            assert_eq!(record, body, "split at {at}");
        }
    }

    #[tokio::test]
    async fn oversized_record_is_refused_from_its_header() {
        let stream = [0x80, 0xFF, 0xFF, 0xFF];
        let mut r = Split {
            parts: vec![&stream],
        };
        assert!(matches!(
            read_record(&mut r, 1024).await,
            Err(RpcError::RecordTooLarge { .. })
        ));
    }

    proptest::proptest! {
        #[test]
        fn arbitrary_bodies_never_panic(bytes in proptest::collection::vec(proptest::num::u8::ANY, 0..128)) {
            let mut r = XdrReader::new(&bytes);
            let _ = decode_call(&mut r);
            let _ = decode_fragment_header([bytes.first().copied().unwrap_or(0), 0, 0, 0]);
        }
    }
}
