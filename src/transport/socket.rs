//! Raw socket (`TCPIP::host::port::SOCKET`): messages end at a newline outside binary blocks.
//!
//! A raw socket has no device clear and no status byte. The only way to be sure no stale reply
//! follows a timeout is a fresh connection, so [`SocketLink::device_clear`] reconnects; the status
//! byte is read by the session with `*STB?`. Nor does it number replies: whatever arrived before a
//! request is thrown away when the request is sent, so an unread reply is never taken for its
//! answer.

use super::error::LinkError;
use super::framing::TerminatedDecoder;
use super::io::{connect_tcp, write_parts, LinkOptions, ReadContext};
use bytes::{Bytes, BytesMut};
use tokio::net::TcpStream;

const PROTOCOL: &str = "socket";
/// At most this much unread input is thrown away before one request.
const DISCARD_LIMIT: usize = 1 << 20;

pub(crate) struct SocketLink {
    host: String,
    port: u16,
    stream: TcpStream,
    buf: BytesMut,
    decoder: TerminatedDecoder,
}

impl SocketLink {
    pub(crate) async fn connect(
        host: &str,
        port: u16,
        options: &LinkOptions,
    ) -> Result<Self, LinkError> {
        let stream = connect_tcp(host, port, PROTOCOL, options).await?;
        Ok(Self {
            host: host.to_string(),
            port,
            stream,
            buf: BytesMut::with_capacity(64 << 10),
            decoder: TerminatedDecoder::new(b'\n', options.max_message_bytes),
        })
    }

    pub(crate) async fn write_message(
        &mut self,
        parts: &[&[u8]],
        options: &LinkOptions,
    ) -> Result<(), LinkError> {
        self.discard_unread();
        write_parts(&mut self.stream, parts, "write", options).await
    }

    /// Bytes that arrived before a request cannot be its reply (a reply nobody read, to a command
    /// that answers): they are thrown away, from the buffer and from the socket, without waiting.
    fn discard_unread(&mut self) {
        self.decoder.reset();
        let mut thrown = self.buf.len();
        self.buf.clear();
        let mut scratch = [0u8; 4096];
        // Bounded, so a peer that never stops talking cannot hold the write up.
        while thrown < DISCARD_LIMIT {
            match self.stream.try_read(&mut scratch) {
                Ok(n) if n > 0 => thrown += n,
                _ => break,
            }
        }
        if thrown > 0 {
            tracing::debug!(thrown, "socket: dropped unread bytes before a request");
        }
    }

    pub(crate) async fn read_message(&mut self, options: &LinkOptions) -> Result<Bytes, LinkError> {
        let mut ctx = ReadContext::new("read", options);
        ctx.read_frame(&mut self.stream, &mut self.buf, &mut self.decoder, PROTOCOL)
            .await
    }

    /// Reopens the connection: the only clear a raw socket has.
    pub(crate) async fn device_clear(&mut self, options: &LinkOptions) -> Result<(), LinkError> {
        let fresh = Self::connect(&self.host, self.port, options).await?;
        *self = fresh;
        Ok(())
    }
}
