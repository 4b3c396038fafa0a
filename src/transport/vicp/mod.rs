//! LeCroy VICP client (`VICP::host[,port]`): each message is one or more blocks, the last with EOI.
//!
//! Sequence numbers (1..=255, never 0) go up after each message sent; the scope stamps its reply
//! blocks with the number of the command that caused them, so a block carrying an older number (a
//! reply to a command abandoned after a timeout) is discarded. Device clear is a header with the
//! CLEAR flag.

pub mod codec;

use self::codec::{next_seq, op, BlockDecoder, Header};
use super::error::LinkError;
use super::io::{connect_tcp, io_error, write_parts, LinkOptions, ReadContext};
use bytes::{Bytes, BytesMut};
use tokio::net::TcpStream;

const PROTOCOL: &str = "VICP";

pub struct VicpLink {
    stream: TcpStream,
    buf: BytesMut,
    decoder: BlockDecoder,
    seq: u8,
    last_sent_seq: u8,
}

impl VicpLink {
    pub async fn connect(host: &str, port: u16, options: &LinkOptions) -> Result<Self, LinkError> {
        let stream = connect_tcp(host, port, PROTOCOL, options).await?;
        Ok(Self {
            stream,
            buf: BytesMut::with_capacity(64 << 10),
            decoder: BlockDecoder::new(options.max_message_bytes as u64),
            seq: 1,
            last_sent_seq: 0,
        })
    }

    pub async fn write_message(
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

    pub async fn read_message(&mut self, options: &LinkOptions) -> Result<Bytes, LinkError> {
        let mut ctx = ReadContext::new("VICP read", options);
        let mut first: Option<Bytes> = None;
        let mut rest = BytesMut::new();
        loop {
            let block = ctx
                .read_frame(&mut self.stream, &mut self.buf, &mut self.decoder, PROTOCOL)
                .await?;
            let h = block.header;
            if h.op & op::DATA == 0 {
                continue;
            }
            if h.seq != 0 && self.last_sent_seq != 0 && h.seq != self.last_sent_seq {
                tracing::debug!(seq = h.seq, "VICP: dropped a stale reply block");
                continue;
            }
            match &first {
                None => first = Some(block.payload),
                Some(head) => {
                    if rest.is_empty() {
                        rest.extend_from_slice(head);
                    }
                    rest.extend_from_slice(&block.payload);
                }
            }
            if h.eoi() {
                return Ok(if rest.is_empty() {
                    first.unwrap_or_default()
                } else {
                    rest.freeze()
                });
            }
        }
    }

    /// Sends a CLEAR header; replies still in flight carry old sequence numbers and are dropped.
    pub async fn device_clear(&mut self, options: &LinkOptions) -> Result<(), LinkError> {
        let header = Header::new(op::DATA | op::CLEAR, self.seq, 0).encode();
        write_parts(&mut self.stream, &[&header], "VICP device clear", options).await?;
        // The next command gets a new number, so replies to earlier ones are recognised as stale
        // (the decoder keeps its place in the stream: a half-received block is finished, not lost).
        Ok(())
    }

    /// Serial poll in band (the VICP 1 way, still answered by 1a devices): a header with the
    /// SERIAL_POLL flag, answered by a one-byte EOI block carrying the status byte. Portable and
    /// in order with the data stream; the default.
    pub async fn read_stb(&mut self, options: &LinkOptions) -> Result<u8, LinkError> {
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

    /// Serial poll, VICP version 1a: the out-of-band byte `S` is answered by one out-of-band byte,
    /// the status byte. The answer is polled for (1 ms steps) rather than awaited through the
    /// reactor: Linux reports urgent data inconsistently through epoll, and a poll is rare.
    /// Only on Linux.
    #[cfg(any(target_os = "linux", target_os = "android"))]
    pub async fn read_stb_out_of_band(&mut self, options: &LinkOptions) -> Result<u8, LinkError> {
        use std::io::ErrorKind as K;
        use std::mem::MaybeUninit;
        const OP: &str = "VICP serial poll";
        const STEP: std::time::Duration = std::time::Duration::from_millis(1);
        let started = tokio::time::Instant::now();
        let deadline = started + options.timeouts.read;
        let timeout = || LinkError::Timeout {
            op: OP,
            after: started.elapsed(),
        };
        loop {
            match socket2::SockRef::from(&self.stream).send_out_of_band(b"S") {
                Ok(_) => break,
                Err(e) if e.kind() == K::WouldBlock => {
                    tokio::time::timeout_at(deadline, self.stream.writable())
                        .await
                        .map_err(|_| timeout())?
                        .map_err(|e| io_error(OP, e))?;
                }
                Err(e) => return Err(io_error(OP, e)),
            }
        }
        loop {
            let mut byte = [MaybeUninit::new(0u8)];
            match socket2::SockRef::from(&self.stream).recv_out_of_band(&mut byte) {
                // SAFETY: the byte was initialised by `MaybeUninit::new` above and written by recv.
                Ok(1) => return Ok(unsafe { byte[0].assume_init() }),
                Ok(_) => return Err(LinkError::Closed { op: OP }),
                // EAGAIN: announced but not arrived; EINVAL: no urgent data noted yet.
                Err(e) if e.kind() == K::WouldBlock || e.raw_os_error() == Some(libc_einval()) => {
                    if tokio::time::Instant::now() >= deadline {
                        return Err(timeout());
                    }
                    tokio::time::sleep(STEP).await;
                }
                Err(e) => return Err(io_error(OP, e)),
            }
        }
    }
}

/// EINVAL on Linux (asm-generic errno), without a libc dependency.
#[cfg(any(target_os = "linux", target_os = "android"))]
const fn libc_einval() -> i32 {
    22
}
