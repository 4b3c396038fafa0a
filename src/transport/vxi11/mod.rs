//! VXI-11 client (`TCPIP::host[,port]::inst0::INSTR`): ONC-RPC over TCP to the core channel, found
//! through the portmapper unless the resource gives the port; the abort channel on the port
//! returned by create_link.
//!
//! Replies are matched by xid: a reply to a call abandoned after a timeout is discarded. When a
//! call is still outstanding at the next device clear, the client first sends device_abort on the
//! abort channel so the server gives up the blocked read.

pub(crate) mod messages;
pub(crate) mod rpc;

pub use messages::{
    decode_create_link, decode_error, decode_read_resp, decode_readstb_resp, decode_write_resp,
    error, flags, proc_, reason, CreateLinkResp, ReadResp, VERSION,
};
pub(crate) use rpc::encode_call_header;
pub use rpc::{
    accept, decode_reply, pad, record_mark, RecordDecoder, Reply, ReplyFault, XdrReader, XdrWriter,
};

use super::error::LinkError;
use super::io::{connect_tcp, write_parts, LinkOptions, ReadContext, Reassembly};
use bytes::{Bytes, BytesMut};
use std::time::Duration;
use tokio::net::TcpStream;

const PROTOCOL: &str = "VXI-11";
/// Bounds on the bytes asked for per device_read. Within them the link's maxRecvSize is asked for:
/// the instrument said it handles that much, and one reply per message means no reassembly copy.
const MIN_READ_REQUEST: usize = 64 << 10;
const MAX_READ_REQUEST: usize = 1 << 30;
/// Headroom over io_timeout for the server's own reply to arrive.
const REPLY_GRACE: Duration = Duration::from_millis(500);

/// An RPC connection: one TCP stream, its record decoder, and xid bookkeeping.
struct RpcChannel {
    stream: TcpStream,
    buf: BytesMut,
    decoder: RecordDecoder,
    xid: u32,
    /// A call whose reply has not been read yet.
    outstanding: Option<u32>,
}

impl RpcChannel {
    fn new(stream: TcpStream, limit: u64) -> Self {
        // A reproducible but per-process starting xid.
        let xid = std::process::id().wrapping_mul(0x9E37_79B9);
        Self {
            stream,
            buf: BytesMut::with_capacity(64 << 10),
            decoder: RecordDecoder::new(limit),
            xid,
            outstanding: None,
        }
    }

    fn next_xid(&mut self) -> u32 {
        self.xid = self.xid.wrapping_add(1);
        self.xid
    }

    /// Sends a call whose arguments are `args` followed by `data` (already padded by the caller).
    #[allow(clippy::too_many_arguments)]
    async fn send(
        &mut self,
        prog: u32,
        vers: u32,
        proc_: u32,
        args: &[u8],
        data: &[&[u8]],
        op: &'static str,
        options: &LinkOptions,
    ) -> Result<u32, LinkError> {
        let xid = self.next_xid();
        let mut head = XdrWriter::default();
        encode_call_header(&mut head, xid, prog, vers, proc_);
        head.buf.extend_from_slice(args);
        let data_len: usize = data.iter().map(|d| d.len()).sum();
        let record_len = head.buf.len() + data_len;
        let mark = record_mark(record_len as u32, true);
        let mut slices: Vec<&[u8]> = Vec::with_capacity(data.len() + 2);
        slices.push(&mark);
        slices.push(&head.buf);
        slices.extend_from_slice(data);
        self.outstanding = Some(xid);
        write_parts(&mut self.stream, &slices, op, options).await?;
        Ok(xid)
    }

    /// Reads replies until the one for `xid`; earlier (stale) replies are dropped.
    async fn receive(
        &mut self,
        xid: u32,
        op: &'static str,
        ctx: &mut ReadContext<'_>,
    ) -> Result<XdrReader, LinkError> {
        loop {
            let record = ctx
                .read_frame(&mut self.stream, &mut self.buf, &mut self.decoder, PROTOCOL)
                .await?;
            let wire_len = record.len() as u64 + 4;
            let reply = rpc::decode_reply(record).map_err(LinkError::codec(PROTOCOL))?;
            if reply.xid != xid {
                tracing::debug!(xid = reply.xid, "VXI-11: dropped a stale reply");
                // Thrown away, so it earns the deadline no time.
                ctx.discard(wire_len);
                continue;
            }
            self.outstanding = None;
            return reply.outcome.map_err(|fault| LinkError::Refused {
                protocol: PROTOCOL,
                op,
                code: fault.code(),
                meaning: fault.meaning(),
            });
        }
    }

    async fn call(
        &mut self,
        prog: u32,
        proc_: u32,
        args: &[u8],
        op: &'static str,
        options: &LinkOptions,
        ctx: &mut ReadContext<'_>,
    ) -> Result<XdrReader, LinkError> {
        let xid = self
            .send(prog, messages::VERSION, proc_, args, &[], op, options)
            .await?;
        self.receive(xid, op, ctx).await
    }
}

fn device_error(op: &'static str, code: i32) -> Result<(), LinkError> {
    match code {
        messages::error::NO_ERROR => Ok(()),
        messages::error::IO_TIMEOUT => Err(LinkError::Timeout {
            op,
            after: Duration::ZERO,
        }),
        _ => Err(LinkError::Refused {
            protocol: PROTOCOL,
            op,
            code: code as u32,
            meaning: messages::error_meaning(code),
        }),
    }
}

fn codec(e: crate::transport::error::CodecError) -> LinkError {
    LinkError::codec(PROTOCOL)(e)
}

fn ms(d: Duration) -> u32 {
    d.as_millis().min(u128::from(u32::MAX)) as u32
}

pub(crate) struct Vxi11Link {
    host: String,
    core: RpcChannel,
    link: CreateLinkResp,
}

impl Vxi11Link {
    pub(crate) async fn connect(
        host: &str,
        port: Option<u16>,
        device: &str,
        options: &LinkOptions,
    ) -> Result<Self, LinkError> {
        let limit = options.max_message_bytes as u64 + 4096;
        let core_port = match port {
            Some(p) => p,
            None => Self::getport(host, options).await?,
        };
        let mut core = RpcChannel::new(
            connect_tcp(host, core_port, PROTOCOL, options).await?,
            limit,
        );
        let mut args = XdrWriter::default();
        let client_id = (std::process::id() & 0x7FFF_FFFF) as i32;
        messages::encode_create_link(&mut args, client_id, 0, device);
        let mut ctx = ReadContext::new("VXI-11 create_link", options);
        let mut r = core
            .call(
                messages::CORE_PROG,
                proc_::CREATE_LINK,
                &args.buf,
                "create_link",
                options,
                &mut ctx,
            )
            .await?;
        let link = messages::decode_create_link(&mut r).map_err(codec)?;
        device_error("create_link", link.error)?;
        Ok(Self {
            host: host.to_string(),
            core,
            link,
        })
    }

    /// Asks the portmapper (port 111 unless the options say otherwise) for the core channel's
    /// TCP port.
    async fn getport(host: &str, options: &LinkOptions) -> Result<u16, LinkError> {
        let stream = connect_tcp(host, options.portmapper_port, "portmapper", options).await?;
        let mut pm = RpcChannel::new(stream, 1024);
        let mut args = XdrWriter::default();
        messages::encode_getport(&mut args, messages::CORE_PROG, messages::VERSION);
        let mut ctx = ReadContext::new("portmapper GETPORT", options);
        let xid = pm
            .send(
                messages::PORTMAP_PROG,
                messages::PORTMAP_VERS,
                messages::PORTMAP_GETPORT,
                &args.buf,
                &[],
                "GETPORT",
                options,
            )
            .await?;
        let mut r = pm.receive(xid, "GETPORT", &mut ctx).await?;
        let port = r.u32("GETPORT result").map_err(codec)?;
        match u16::try_from(port) {
            Ok(p) if p > 0 => Ok(p),
            _ => Err(LinkError::Protocol {
                protocol: "portmapper",
                detail: format!(
                    "no VXI-11 core program registered on {host} (port {port}); give the port explicitly as TCPIP::{host},PORT::inst0::INSTR"
                )})}
    }

    pub(crate) async fn write_message(
        &mut self,
        parts: &[&[u8]],
        options: &LinkOptions,
    ) -> Result<(), LinkError> {
        let total: usize = parts.iter().map(|p| p.len()).sum();
        // At least 1024 (VXI-11 minimum); at most 1 GiB so a record fits the 31-bit mark.
        let chunk = (self.link.max_recv_size as usize).clamp(1024, 1 << 30);
        let io_timeout = ms(options.timeouts.write);
        // Walk the parts in chunks of at most maxRecvSize, END on the last.
        let mut offset = 0usize;
        loop {
            let len = (total - offset).min(chunk);
            let last = offset + len == total;
            let slices = slice_range(parts, offset, len);
            let mut args = XdrWriter::default();
            let flag = if last { flags::END } else { 0 };
            messages::encode_write_head(&mut args, self.link.lid, io_timeout, flag, len as u32);
            let padding = [0u8; 3];
            let mut data = slices;
            data.push(&padding[..pad(len)]);
            let xid = self
                .core
                .send(
                    messages::CORE_PROG,
                    messages::VERSION,
                    proc_::DEVICE_WRITE,
                    &args.buf,
                    &data,
                    "device_write",
                    options,
                )
                .await?;
            // Each chunk's reply gets its own clock, started once the chunk is out: the chunk's
            // own transfer time is bounded by write_parts.
            let mut ctx = ReadContext::new("VXI-11 device_write", options)
                .with_base(options.timeouts.write + REPLY_GRACE);
            let mut r = self.core.receive(xid, "device_write", &mut ctx).await?;
            let (error, size) = messages::decode_write_resp(&mut r).map_err(codec)?;
            device_error("device_write", error)?;
            let accepted = (size as usize).min(len);
            if accepted == 0 && len > 0 {
                return Err(LinkError::Protocol {
                    protocol: PROTOCOL,
                    detail: "device_write accepted 0 bytes".into(),
                });
            }
            offset += accepted;
            if offset >= total {
                return Ok(());
            }
        }
    }

    pub(crate) async fn read_message(&mut self, options: &LinkOptions) -> Result<Bytes, LinkError> {
        let mut ctx = ReadContext::new("VXI-11 device_read", options)
            .with_base(options.timeouts.read + REPLY_GRACE);
        let mut message = Reassembly::new(options.max_message_bytes, PROTOCOL);
        let mut received = 0usize;
        loop {
            let budget = options.max_message_bytes.saturating_sub(received).max(1);
            let preferred =
                (self.link.max_recv_size as usize).clamp(MIN_READ_REQUEST, MAX_READ_REQUEST);
            let request = budget.min(preferred) as u32;
            let io_timeout = ms(ctx.remaining().saturating_sub(REPLY_GRACE));
            let mut args = XdrWriter::default();
            messages::encode_read(&mut args, self.link.lid, request, io_timeout);
            let mut r = self
                .core
                .call(
                    messages::CORE_PROG,
                    proc_::DEVICE_READ,
                    &args.buf,
                    "device_read",
                    options,
                    &mut ctx,
                )
                .await?;
            let resp = messages::decode_read_resp(&mut r).map_err(codec)?;
            if resp.error == messages::error::IO_TIMEOUT {
                // The server gave up after the io_timeout it was given: the read timeout (and
                // any allowance), without the grace kept for its reply. That is what is reported,
                // not the time measured here, which the server's clock can undercut by a
                // fraction of a millisecond (it starts when the request arrives).
                return Err(LinkError::Timeout {
                    op: ctx.op(),
                    after: ctx.allowed().saturating_sub(REPLY_GRACE),
                });
            }
            device_error("device_read", resp.error)?;
            received += resp.data.len();
            message.push(resp.data)?;
            if resp.reason & (reason::END | reason::CHR) != 0 {
                return Ok(message.finish());
            }
        }
    }

    async fn generic(
        &mut self,
        proc_: u32,
        op: &'static str,
        options: &LinkOptions,
    ) -> Result<XdrReader, LinkError> {
        let mut args = XdrWriter::default();
        messages::encode_generic(&mut args, self.link.lid, ms(options.timeouts.read));
        let mut ctx = ReadContext::new(op, options).with_base(options.timeouts.read + REPLY_GRACE);
        self.core
            .call(messages::CORE_PROG, proc_, &args.buf, op, options, &mut ctx)
            .await
    }

    /// device_clear, preceded by device_abort on the abort channel when a call is still pending.
    pub(crate) async fn device_clear(&mut self, options: &LinkOptions) -> Result<(), LinkError> {
        if self.core.outstanding.is_some() {
            if let Err(e) = self.abort(options).await {
                tracing::warn!("VXI-11 device_abort failed: {e}");
            }
        }
        let mut r = self
            .generic(proc_::DEVICE_CLEAR, "device_clear", options)
            .await?;
        let error = messages::decode_error(&mut r).map_err(codec)?;
        device_error("device_clear", error)
    }

    /// device_abort on the abort channel: makes the server end a blocked device_read/write.
    pub(crate) async fn abort(&mut self, options: &LinkOptions) -> Result<(), LinkError> {
        let stream = connect_tcp(&self.host, self.link.abort_port, PROTOCOL, options).await?;
        let mut channel = RpcChannel::new(stream, 1024);
        let mut args = XdrWriter::default();
        args.i32(self.link.lid);
        let mut ctx = ReadContext::new("VXI-11 device_abort", options);
        let mut r = channel
            .call(
                messages::ABORT_PROG,
                proc_::DEVICE_ABORT,
                &args.buf,
                "device_abort",
                options,
                &mut ctx,
            )
            .await?;
        let error = messages::decode_error(&mut r).map_err(codec)?;
        device_error("device_abort", error)
    }

    pub(crate) async fn read_stb(&mut self, options: &LinkOptions) -> Result<u8, LinkError> {
        let mut r = self
            .generic(proc_::DEVICE_READSTB, "device_readstb", options)
            .await?;
        let (error, stb) = messages::decode_readstb_resp(&mut r).map_err(codec)?;
        device_error("device_readstb", error)?;
        Ok(stb)
    }

    /// destroy_link; the connection closes when the link is dropped.
    pub(crate) async fn close(&mut self, options: &LinkOptions) -> Result<(), LinkError> {
        let mut args = XdrWriter::default();
        args.i32(self.link.lid);
        let mut ctx = ReadContext::new("VXI-11 destroy_link", options);
        let mut r = self
            .core
            .call(
                messages::CORE_PROG,
                proc_::DESTROY_LINK,
                &args.buf,
                "destroy_link",
                options,
                &mut ctx,
            )
            .await?;
        let error = messages::decode_error(&mut r).map_err(codec)?;
        device_error("destroy_link", error)
    }
}

/// The sub-slices of `parts` covering bytes `offset..offset+len` of their concatenation.
fn slice_range<'a>(parts: &[&'a [u8]], mut offset: usize, mut len: usize) -> Vec<&'a [u8]> {
    let mut out = Vec::new();
    for part in parts {
        if len == 0 {
            break;
        }
        if offset >= part.len() {
            offset -= part.len();
            continue;
        }
        let take = (part.len() - offset).min(len);
        out.push(&part[offset..offset + take]);
        len -= take;
        offset = 0;
    }
    out
}

#[cfg(test)]
mod tests {
    use super::slice_range;

    #[test]
    fn slice_range_walks_across_parts() {
        let parts: [&[u8]; 3] = [b"abc", b"", b"defgh"];
        let joined: Vec<u8> = parts.concat();
        for offset in 0..=joined.len() {
            for len in 0..=(joined.len() - offset) {
                let got: Vec<u8> = slice_range(&parts, offset, len).concat();
                assert_eq!(got, &joined[offset..offset + len]);
            }
        }
    }
}
