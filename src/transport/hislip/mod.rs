//! HiSLIP client (`TCPIP::host::hislipN[,port]::INSTR`): a synchronous channel for data and an
//! asynchronous channel for device clear, status queries and size negotiation.
//!
//! Replies are matched by MessageID: a Data/DataEnd frame carrying an older ID (a reply to a
//! message abandoned after a timeout) is discarded, so a stale reply is never taken as the answer.

pub(crate) mod codec;

pub(crate) use codec::FIRST_MESSAGE_ID;
pub use codec::{encode_frame, msg, Frame, FrameDecoder, Header, HEADER_LEN};

use super::error::LinkError;
use super::io::{connect_tcp, write_parts, LinkOptions, ReadContext, Reassembly};
use bytes::{Bytes, BytesMut};
use tokio::net::TcpStream;

const PROTOCOL: &str = "HiSLIP";
/// The MessageID a server may use for replies not tied to one request.
const ANY_MESSAGE_ID: u32 = 0xFFFF_FFFF;

/// One end of a HiSLIP channel with its own receive buffer and decoder (cancel safe).
struct Channel {
    stream: TcpStream,
    buf: BytesMut,
    decoder: FrameDecoder,
}

impl Channel {
    fn new(stream: TcpStream, limit: u64) -> Self {
        Self {
            stream,
            buf: BytesMut::with_capacity(64 << 10),
            decoder: FrameDecoder::new(limit),
        }
    }

    async fn send(&mut self, frame: &[u8], options: &LinkOptions) -> Result<(), LinkError> {
        write_parts(
            &mut self.stream,
            &[frame],
            "HiSLIP control message",
            options,
        )
        .await
    }

    async fn next(&mut self, ctx: &mut ReadContext<'_>) -> Result<Frame, LinkError> {
        ctx.read_frame(&mut self.stream, &mut self.buf, &mut self.decoder, PROTOCOL)
            .await
    }
}

/// The wire size of a frame, given back to the deadline when the frame is thrown away.
fn wire_len(frame: &Frame) -> u64 {
    HEADER_LEN as u64 + frame.payload.len() as u64
}

pub(crate) struct HislipLink {
    sync: Channel,
    async_: Channel,
    /// The largest payload the server accepts in one Data frame.
    server_max: u64,
    next_id: u32,
    last_sent_id: u32,
    /// Set once a whole response was delivered; reported with the next message (RMT-delivered).
    rmt_delivered: bool,
    pub overlapped: bool,
}

fn fatal(frame: &Frame, op: &'static str) -> LinkError {
    let code = frame.header.control;
    let meaning = if frame.header.msg_type == msg::FATAL_ERROR {
        codec::fatal_error_meaning(code)
    } else {
        codec::error_meaning(code)
    };
    LinkError::Refused {
        protocol: PROTOCOL,
        op,
        code: code.into(),
        meaning,
    }
}

fn unexpected(frame: &Frame, wanted: &str) -> LinkError {
    LinkError::Protocol {
        protocol: PROTOCOL,
        detail: format!(
            "expected {wanted}, got message type {} (control {}, parameter {:#x})",
            frame.header.msg_type, frame.header.control, frame.header.param
        ),
    }
}

impl HislipLink {
    pub(crate) async fn connect(
        host: &str,
        port: u16,
        sub_address: &str,
        options: &LinkOptions,
    ) -> Result<Self, LinkError> {
        let limit = options.max_message_bytes as u64;
        let mut sync = Channel::new(connect_tcp(host, port, PROTOCOL, options).await?, limit);
        let init = codec::encode_frame(
            msg::INITIALIZE,
            0,
            codec::CLIENT_PROTOCOL_AND_VENDOR,
            sub_address.as_bytes(),
        );
        sync.send(&init, options).await?;
        let mut ctx = ReadContext::new("HiSLIP Initialize", options);
        let reply = sync.next(&mut ctx).await?;
        if matches!(reply.header.msg_type, msg::FATAL_ERROR | msg::ERROR) {
            return Err(fatal(&reply, "Initialize"));
        }
        if reply.header.msg_type != msg::INITIALIZE_RESPONSE {
            return Err(unexpected(&reply, "InitializeResponse"));
        }
        let session_id = (reply.header.param & 0xFFFF) as u16;
        let overlapped = reply.header.control & 1 != 0;

        let mut async_ = Channel::new(connect_tcp(host, port, PROTOCOL, options).await?, limit);
        async_
            .send(
                &codec::encode_frame(msg::ASYNC_INITIALIZE, 0, session_id.into(), &[]),
                options,
            )
            .await?;
        let reply = async_.next(&mut ctx).await?;
        if matches!(reply.header.msg_type, msg::FATAL_ERROR | msg::ERROR) {
            return Err(fatal(&reply, "AsyncInitialize"));
        }
        if reply.header.msg_type != msg::ASYNC_INITIALIZE_RESPONSE {
            return Err(unexpected(&reply, "AsyncInitializeResponse"));
        }
        async_
            .send(
                &codec::encode_frame(msg::ASYNC_MAX_MSG_SIZE, 0, 0, &limit.to_be_bytes()),
                options,
            )
            .await?;
        let reply = async_.next(&mut ctx).await?;
        if reply.header.msg_type != msg::ASYNC_MAX_MSG_SIZE_RESPONSE || reply.payload.len() != 8 {
            return Err(unexpected(
                &reply,
                "AsyncMaxMsgSizeResponse with an 8-byte size",
            ));
        }
        let server_max = u64::from_be_bytes(reply.payload[..8].try_into().expect("8 bytes"));
        if server_max == 0 {
            return Err(LinkError::Protocol {
                protocol: PROTOCOL,
                detail: "server announced a maximum message size of 0".into(),
            });
        }
        Ok(Self {
            sync,
            async_,
            server_max,
            next_id: FIRST_MESSAGE_ID,
            last_sent_id: FIRST_MESSAGE_ID,
            rmt_delivered: false,
            overlapped,
        })
    }

    /// Sends one message as Data frames of at most the server's size, the last one DataEnd.
    pub(crate) async fn write_message(
        &mut self,
        parts: &[&[u8]],
        options: &LinkOptions,
    ) -> Result<(), LinkError> {
        let total: u64 = parts.iter().map(|p| p.len() as u64).sum();
        let id = self.next_id;
        let rmt = u8::from(std::mem::take(&mut self.rmt_delivered));
        let chunk = self.server_max.max(1);
        let frames = total.div_ceil(chunk).max(1);
        let mut headers = Vec::with_capacity(frames as usize);
        let mut remaining = total;
        for i in 0..frames {
            let len = remaining.min(chunk);
            remaining -= len;
            let last = i + 1 == frames;
            let kind = if last { msg::DATA_END } else { msg::DATA };
            headers.push(Header::new(kind, rmt, id, len).encode());
        }
        // Interleave headers with (sub-slices of) the caller's parts: no copy of the payload.
        let mut slices: Vec<&[u8]> = Vec::with_capacity(headers.len() + parts.len() * 2);
        let mut part_iter = parts.iter().copied().filter(|p| !p.is_empty());
        let mut current: &[u8] = part_iter.next().unwrap_or(&[]);
        let mut remaining = total;
        for header in &headers {
            slices.push(header);
            let mut need = remaining.min(chunk);
            remaining -= need;
            while need > 0 {
                if current.is_empty() {
                    current = part_iter.next().unwrap_or(&[]);
                }
                let take = (current.len() as u64).min(need) as usize;
                let (head, tail) = current.split_at(take);
                slices.push(head);
                current = tail;
                need -= take as u64;
            }
        }
        write_parts(&mut self.sync.stream, &slices, "HiSLIP write", options).await?;
        self.last_sent_id = id;
        self.next_id = id.wrapping_add(2);
        Ok(())
    }

    /// Reads Data frames up to DataEnd for the last message sent; older replies are dropped.
    pub(crate) async fn read_message(&mut self, options: &LinkOptions) -> Result<Bytes, LinkError> {
        let mut ctx = ReadContext::new("HiSLIP read", options);
        let mut message = Reassembly::new(options.max_message_bytes, PROTOCOL);
        loop {
            let frame = self.sync.next(&mut ctx).await?;
            match frame.header.msg_type {
                msg::DATA | msg::DATA_END => {
                    let id = frame.header.param;
                    if id != self.last_sent_id && id != ANY_MESSAGE_ID {
                        tracing::debug!(id, "HiSLIP: dropped a stale reply frame");
                        ctx.discard(wire_len(&frame));
                        continue;
                    }
                    let end = frame.header.msg_type == msg::DATA_END;
                    message.push(frame.payload)?;
                    if end {
                        self.rmt_delivered = true;
                        return Ok(message.finish());
                    }
                }
                msg::INTERRUPTED => {
                    // What came so far belonged to an abandoned message.
                    let dropped = message.abandon();
                    ctx.discard(dropped as u64 + wire_len(&frame));
                }
                msg::ERROR | msg::FATAL_ERROR => return Err(fatal(&frame, "read")),
                _ => return Err(unexpected(&frame, "Data or DataEnd")),
            }
        }
    }

    /// The device-clear handshake: AsyncDeviceClear, then DeviceClearComplete on the sync channel,
    /// discarding everything there until DeviceClearAcknowledge.
    pub(crate) async fn device_clear(&mut self, options: &LinkOptions) -> Result<(), LinkError> {
        self.async_
            .send(
                &codec::encode_frame(msg::ASYNC_DEVICE_CLEAR, 0, 0, &[]),
                options,
            )
            .await?;
        let mut ctx = ReadContext::new("HiSLIP device clear", options);
        let features = loop {
            let frame = self.async_.next(&mut ctx).await?;
            match frame.header.msg_type {
                msg::ASYNC_DEVICE_CLEAR_ACKNOWLEDGE => break frame.header.control,
                msg::ASYNC_SERVICE_REQUEST | msg::ASYNC_INTERRUPTED => {
                    ctx.discard(wire_len(&frame));
                    continue;
                }
                msg::ERROR | msg::FATAL_ERROR => return Err(fatal(&frame, "device clear")),
                _ => return Err(unexpected(&frame, "AsyncDeviceClearAcknowledge")),
            }
        };
        self.sync
            .send(
                &codec::encode_frame(msg::DEVICE_CLEAR_COMPLETE, features, 0, &[]),
                options,
            )
            .await?;
        loop {
            let frame = self.sync.next(&mut ctx).await?;
            match frame.header.msg_type {
                msg::DEVICE_CLEAR_ACKNOWLEDGE => break,
                msg::FATAL_ERROR => return Err(fatal(&frame, "device clear")),
                // Replies still in flight are thrown away, and earn no time.
                _ => ctx.discard(wire_len(&frame)),
            }
        }
        self.overlapped = features & 1 != 0;
        self.next_id = FIRST_MESSAGE_ID;
        self.last_sent_id = FIRST_MESSAGE_ID;
        self.rmt_delivered = false;
        Ok(())
    }

    /// AsyncStatusQuery: the status byte, without going through the message queue.
    pub(crate) async fn read_stb(&mut self, options: &LinkOptions) -> Result<u8, LinkError> {
        let rmt = u8::from(std::mem::take(&mut self.rmt_delivered));
        self.async_
            .send(
                &codec::encode_frame(msg::ASYNC_STATUS_QUERY, rmt, self.next_id, &[]),
                options,
            )
            .await?;
        let mut ctx = ReadContext::new("HiSLIP status query", options);
        loop {
            let frame = self.async_.next(&mut ctx).await?;
            match frame.header.msg_type {
                msg::ASYNC_STATUS_RESPONSE => return Ok(frame.header.control),
                msg::ASYNC_SERVICE_REQUEST => ctx.discard(wire_len(&frame)),
                msg::ERROR | msg::FATAL_ERROR => return Err(fatal(&frame, "status query")),
                _ => return Err(unexpected(&frame, "AsyncStatusResponse")),
            }
        }
    }
}
