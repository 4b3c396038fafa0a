//! VXI-11 programs, procedures and the XDR layouts of their arguments and results.

use super::rpc::{XdrReader, XdrWriter};
use crate::transport::error::CodecError;
use bytes::Bytes;

pub(crate) const PORTMAP_PROG: u32 = 100_000;
pub(crate) const PORTMAP_VERS: u32 = 2;
pub(crate) const PORTMAP_GETPORT: u32 = 3;
pub(crate) const IPPROTO_TCP: u32 = 6;

pub(crate) const CORE_PROG: u32 = 0x0607AF;
pub(crate) const ABORT_PROG: u32 = 0x0607B0;
pub const VERSION: u32 = 1;

/// Procedure numbers of the core channel; kept whole so the table reads like the spec's.
#[allow(dead_code)]
pub mod proc_ {
    pub(crate) const DEVICE_ABORT: u32 = 1;
    pub(crate) const CREATE_LINK: u32 = 10;
    pub(crate) const DEVICE_WRITE: u32 = 11;
    pub(crate) const DEVICE_READ: u32 = 12;
    pub(crate) const DEVICE_READSTB: u32 = 13;
    pub(crate) const DEVICE_TRIGGER: u32 = 14;
    pub(crate) const DEVICE_CLEAR: u32 = 15;
    pub(crate) const DESTROY_LINK: u32 = 23;
}

pub mod flags {
    pub const END: i32 = 0x08;
}

/// Why a device_read ended; kept whole so the table reads like the spec's.
#[allow(dead_code)]
pub mod reason {
    pub(crate) const REQCNT: i32 = 1;
    pub(crate) const CHR: i32 = 2;
    pub const END: i32 = 4;
}

/// VXI-11 Device_ErrorCode values (VXI-11 specification B.5.2).
pub mod error {
    pub(crate) const NO_ERROR: i32 = 0;
    pub(crate) const SYNTAX_ERROR: i32 = 1;
    pub(crate) const DEVICE_NOT_ACCESSIBLE: i32 = 3;
    pub(crate) const INVALID_LINK: i32 = 4;
    pub(crate) const PARAMETER_ERROR: i32 = 5;
    pub(crate) const CHANNEL_NOT_ESTABLISHED: i32 = 6;
    pub(crate) const NOT_SUPPORTED: i32 = 8;
    pub(crate) const OUT_OF_RESOURCES: i32 = 9;
    pub(crate) const DEVICE_LOCKED: i32 = 11;
    pub(crate) const NO_LOCK_HELD: i32 = 12;
    pub(crate) const IO_TIMEOUT: i32 = 15;
    pub(crate) const IO_ERROR: i32 = 17;
    pub(crate) const INVALID_ADDRESS: i32 = 21;
    pub const ABORT: i32 = 23;
    pub(crate) const CHANNEL_ALREADY_ESTABLISHED: i32 = 29;
}

/// The meaning of a VXI-11 Device_ErrorCode.
pub(crate) fn error_meaning(code: i32) -> &'static str {
    match code {
        error::NO_ERROR => "no error",
        error::SYNTAX_ERROR => "syntax error",
        error::DEVICE_NOT_ACCESSIBLE => "device not accessible",
        error::INVALID_LINK => "invalid link identifier",
        error::PARAMETER_ERROR => "parameter error",
        error::CHANNEL_NOT_ESTABLISHED => "channel not established",
        error::NOT_SUPPORTED => "operation not supported",
        error::OUT_OF_RESOURCES => "out of resources",
        error::DEVICE_LOCKED => "device locked by another link",
        error::NO_LOCK_HELD => "no lock held by this link",
        error::IO_TIMEOUT => "I/O timeout",
        error::IO_ERROR => "I/O error",
        error::INVALID_ADDRESS => "invalid address",
        error::ABORT => "abort",
        error::CHANNEL_ALREADY_ESTABLISHED => "channel already established",
        _ => "unknown error code",
    }
}

/// Portmapper GETPORT arguments.
pub(crate) fn encode_getport(w: &mut XdrWriter, prog: u32, vers: u32) {
    w.u32(prog).u32(vers).u32(IPPROTO_TCP).u32(0);
}

pub(crate) fn encode_create_link(
    w: &mut XdrWriter,
    client_id: i32,
    lock_timeout_ms: u32,
    device: &str,
) {
    w.i32(client_id)
        .bool(false)
        .u32(lock_timeout_ms)
        .opaque(device.as_bytes());
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct CreateLinkResp {
    pub error: i32,
    pub lid: i32,
    pub abort_port: u16,
    pub max_recv_size: u32,
}

pub fn decode_create_link(r: &mut XdrReader) -> Result<CreateLinkResp, CodecError> {
    Ok(CreateLinkResp {
        error: r.i32("Create_LinkResp.error")?,
        lid: r.i32("Create_LinkResp.lid")?,
        abort_port: r.u32("Create_LinkResp.abortPort")? as u16,
        max_recv_size: r.u32("Create_LinkResp.maxRecvSize")?,
    })
}

/// Device_WriteParms up to the opaque length word; the data and its padding follow on the wire.
pub(crate) fn encode_write_head(
    w: &mut XdrWriter,
    lid: i32,
    io_timeout_ms: u32,
    flags: i32,
    len: u32,
) {
    w.i32(lid).u32(io_timeout_ms).u32(0).i32(flags).u32(len);
}

pub fn decode_write_resp(r: &mut XdrReader) -> Result<(i32, u32), CodecError> {
    Ok((
        r.i32("Device_WriteResp.error")?,
        r.u32("Device_WriteResp.size")?,
    ))
}

pub(crate) fn encode_read(w: &mut XdrWriter, lid: i32, request_size: u32, io_timeout_ms: u32) {
    w.i32(lid)
        .u32(request_size)
        .u32(io_timeout_ms)
        .u32(0)
        .i32(0)
        .i32(0);
}

#[derive(Debug, Clone, PartialEq, Eq)]
pub struct ReadResp {
    pub error: i32,
    pub reason: i32,
    pub data: Bytes,
}

pub fn decode_read_resp(r: &mut XdrReader) -> Result<ReadResp, CodecError> {
    Ok(ReadResp {
        error: r.i32("Device_ReadResp.error")?,
        reason: r.i32("Device_ReadResp.reason")?,
        data: r.opaque("Device_ReadResp.data")?,
    })
}

/// Device_GenericParms (readstb, trigger, clear).
pub(crate) fn encode_generic(w: &mut XdrWriter, lid: i32, io_timeout_ms: u32) {
    w.i32(lid).i32(0).u32(0).u32(io_timeout_ms);
}

pub fn decode_readstb_resp(r: &mut XdrReader) -> Result<(i32, u8), CodecError> {
    Ok((
        r.i32("Device_ReadStbResp.error")?,
        r.u32("Device_ReadStbResp.stb")? as u8,
    ))
}

pub fn decode_error(r: &mut XdrReader) -> Result<i32, CodecError> {
    r.i32("Device_Error.error")
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn golden_create_link_and_read() {
        let mut w = XdrWriter::default();
        encode_create_link(&mut w, 7, 10_000, "inst0");
        assert_eq!(
            w.buf,
            [
                0, 0, 0, 7, 0, 0, 0, 0, 0, 0, 0x27, 0x10, 0, 0, 0, 5, b'i', b'n', b's', b't', b'0',
                0, 0, 0
            ]
        );
        let mut r = XdrReader::new(Bytes::from_static(&[
            0, 0, 0, 0, 0, 0, 0, 3, 0, 0, 0x4E, 0x21, 0, 0x10, 0, 0,
        ]));
        assert_eq!(
            decode_create_link(&mut r).unwrap(),
            CreateLinkResp {
                error: 0,
                lid: 3,
                abort_port: 20001,
                max_recv_size: 0x100000
            }
        );
        let mut r = XdrReader::new(Bytes::from_static(&[
            0, 0, 0, 0, 0, 0, 0, 4, 0, 0, 0, 2, b'1', b'\n', 0, 0,
        ]));
        assert_eq!(
            decode_read_resp(&mut r).unwrap(),
            ReadResp {
                error: 0,
                reason: reason::END,
                data: Bytes::from_static(b"1\n")
            }
        );
    }

    #[test]
    fn truncated_results_are_errors() {
        let mut r = XdrReader::new(Bytes::from_static(&[0, 0, 0, 0, 0, 0, 0, 4, 0, 0, 1, 0]));
        assert!(decode_read_resp(&mut r).is_err());
    }
}
