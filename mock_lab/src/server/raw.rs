//! Raw SCPI socket server (the instrument's port 5025).
//!
//! A message ends at LF outside `#N` blocks (CR LF accepted); responses get a LF. Messages are
//! handled one after another per connection, in the order they arrived.

use std::io;
use std::net::SocketAddr;
use std::sync::Arc;

use thiserror::Error;
use tokio::io::AsyncReadExt;
use tokio::net::TcpStream;

use super::conn::{self, Delivery, READ_CHUNK};
use super::framing::{FramingError, Splitter};
use super::{pool, Handler, ServerError, ServerHandle, ServerOptions};

const PROTOCOL: &str = "raw";

/// Why a raw-socket connection ended abnormally.
#[derive(Debug, Error)]
pub(crate) enum RawError {
    /// Socket error.
    #[error("socket error: {0}")]
    Io(#[from] io::Error),
    /// The client sent something that cannot be framed.
    #[error("{0}")]
    Framing(#[from] FramingError),
}

/// Starts a raw-socket server on `addr` serving `handler`.
pub async fn serve(
    addr: SocketAddr,
    handler: Arc<dyn Handler>,
    options: ServerOptions,
) -> Result<ServerHandle, ServerError> {
    conn::listen_with_handler(
        PROTOCOL,
        addr,
        handler,
        options,
        serve_connection,
        |e| match e {
            RawError::Io(io) => Some(io),
            _ => None,
        },
    )
    .await
}

async fn serve_connection(
    stream: TcpStream,
    handler: Arc<dyn Handler>,
    options: ServerOptions,
) -> Result<(), RawError> {
    let (mut reader, mut writer) = stream.into_split();
    let mut splitter = Splitter::new(options.max_message_size);
    let mut buf: Vec<u8> = Vec::with_capacity(64 << 10);
    loop {
        while let Some(frame) = splitter.next_frame(&buf)? {
            // Hand the buffer itself to the handler; only bytes after the message are copied.
            let rest = buf.split_off(frame.consumed);
            let mut message = std::mem::replace(&mut buf, rest);
            message.truncate(frame.message_len);
            if message.is_empty() {
                continue;
            }
            let Some(responses) = conn::call_handler(&handler, message.into()).await else {
                return Ok(());
            };
            for response in responses {
                let plan = options.faults.plan_reply();
                let parts: Vec<&[u8]> = response.parts().iter().map(|p| &p[..]).collect();
                if conn::write_reply(&mut writer, &parts, plan).await? == Delivery::Dropped {
                    return Ok(());
                }
            }
        }
        // Inside a block the splitter knows how much is coming (already checked against the
        // maximum message size): reserve it once (recycled memory when there is some) instead
        // of growing by doubling.
        let pending = splitter.block_bytes_pending();
        if pending > 0 {
            pool::reserve(&mut buf, pending as usize + 2);
        }
        let want = pending.clamp(64 << 10, READ_CHUNK as u64);
        buf.reserve(want as usize);
        let got = (&mut reader).take(want).read_buf(&mut buf).await?;
        if got == 0 {
            return Ok(());
        }
    }
}
