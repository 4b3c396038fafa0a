//! LeCroy VICP client (`VICP::host[,port]`): each message is one or more blocks, the last with EOI.
//!
//! Sequence numbers (1..=255, never 0) go up after each message sent; the scope stamps its reply
//! blocks with the number of the command that caused them, so a block carrying an older number (a
//! reply to a command abandoned after a timeout) is discarded. Device clear is a header with the
//! CLEAR flag.

pub(crate) mod codec;

pub(crate) use codec::next_seq;
pub use codec::{op, Block, BlockDecoder, Header, HEADER_LEN, VERSION};

use super::error::LinkError;
use super::io::{connect_tcp, write_parts, LinkOptions, ReadContext, Reassembly};
use bytes::{Bytes, BytesMut};
use tokio::net::TcpStream;

const PROTOCOL: &str = "VICP";

pub(crate) struct VicpLink {
    stream: TcpStream,
    buf: BytesMut,
    decoder: BlockDecoder,
    seq: u8,
    last_sent_seq: u8,
}

impl VicpLink {
    pub(crate) async fn connect(
        host: &str,
        port: u16,
        options: &LinkOptions,
    ) -> Result<Self, LinkError> {
        let stream = connect_tcp(host, port, PROTOCOL, options).await?;
        Ok(Self {
            stream,
            buf: BytesMut::with_capacity(64 << 10),
            decoder: BlockDecoder::new(options.max_message_bytes as u64),
            seq: 1,
            last_sent_seq: 0,
        })
    }

    pub(crate) async fn write_message(
        &mut self,
        parts: &[&[u8]],
        options: &LinkOptions,
    ) -> Result<(), LinkError> {
        let total: u64 = parts.iter().map(|p| p.len() as u64).sum();
        let Ok(len) = u32::try_from(total) else {
            return Err(LinkError::MessageTooLarge {
                size: total,
                limit: u32::MAX.into(),
            });
        };
        let header = Header::new(op::DATA | op::EOI, self.seq, len).encode();
        let mut slices: Vec<&[u8]> = Vec::with_capacity(parts.len() + 1);
        slices.push(&header);
        slices.extend_from_slice(parts);
        write_parts(&mut self.stream, &slices, "VICP write", options).await?;
        self.last_sent_seq = self.seq;
        self.seq = next_seq(self.seq);
        Ok(())
    }

    pub(crate) async fn read_message(&mut self, options: &LinkOptions) -> Result<Bytes, LinkError> {
        let mut ctx = ReadContext::new("VICP read", options);
        let mut message = Reassembly::new(options.max_message_bytes, PROTOCOL);
        loop {
            let block = ctx
                .read_frame(&mut self.stream, &mut self.buf, &mut self.decoder, PROTOCOL)
                .await?;
            let h = block.header;
            let stale = h.seq != 0 && self.last_sent_seq != 0 && h.seq != self.last_sent_seq;
            if h.op & op::DATA == 0 || stale {
                if stale {
                    tracing::debug!(seq = h.seq, "VICP: dropped a stale reply block");
                }
                // Thrown away, so it earns the deadline no time.
                ctx.discard(HEADER_LEN as u64 + block.payload.len() as u64);
                continue;
            }
            message.push(block.payload)?;
            if h.eoi() {
                return Ok(message.finish());
            }
        }
    }

    /// Sends a CLEAR header; replies still in flight carry old sequence numbers and are dropped.
    pub(crate) async fn device_clear(&mut self, options: &LinkOptions) -> Result<(), LinkError> {
        let header = Header::new(op::DATA | op::CLEAR, self.seq, 0).encode();
        write_parts(&mut self.stream, &[&header], "VICP device clear", options).await?;
        // The next command gets a new number, so replies to earlier ones are recognised as stale
        // (the decoder keeps its place in the stream: a half-received block is finished, not lost).
        Ok(())
    }

    /// Serial poll in band (the VICP 1 way): a header with the
    /// SERIAL_POLL flag, answered by a one-byte EOI block carrying the status byte. Portable and
    /// in order with the data stream. (VICP 1a devices also offer an out-of-band poll, the urgent
    /// TCP byte `S`; it is not used: urgent data proved unreliable under load on loopback.)
    pub(crate) async fn read_stb(&mut self, options: &LinkOptions) -> Result<u8, LinkError> {
        let header = Header::new(op::SERIAL_POLL, self.seq, 0).encode();
        write_parts(&mut self.stream, &[&header], "VICP serial poll", options).await?;
        self.last_sent_seq = self.seq;
        self.seq = next_seq(self.seq);
        let reply = self.read_message(options).await?;
        match reply.as_ref() {
            [stb] => Ok(*stb),
            other => Err(LinkError::Protocol {
                protocol: PROTOCOL,
                detail: format!(
                    "serial poll answered with {} bytes instead of one status byte",
                    other.len()
                ),
            }),
        }
    }
}
