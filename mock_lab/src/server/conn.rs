//! Connection plumbing shared by the TCP servers: accept loops, handler calls on the blocking
//! pool, bounded reads straight into message buffers, and fault-aware reply writing.

use std::future::Future;
use std::io::{self, IoSlice};
use std::net::SocketAddr;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::Arc;
use std::time::Duration;

use tokio::io::{AsyncRead, AsyncReadExt, AsyncWrite, AsyncWriteExt};
use tokio::net::{TcpListener, TcpStream};
use tokio::task::JoinSet;

use bytes::Bytes;

use super::framing::has_terminator;
use super::{pool, Handler, Response};
use crate::faults::{ReplyFate, ReplyPlan};

/// Largest single read request; big blocks arrive in reads of this size, straight into the
/// message buffer (no intermediate copy, no up-front allocation of the announced length).
pub(crate) const READ_CHUNK: usize = 8 << 20;

/// Replies up to this size are coalesced into one write (one TCP segment for small answers).
const COALESCE_LIMIT: usize = 64 << 10;

/// [`listen`] for a protocol whose connections each need only the handler and the options:
/// `serve` runs each one, and how it ended is logged (`io_err` picks out an I/O error, so a
/// client that vanished is not a warning).
pub(crate) async fn listen_with_handler<S, Fut, E>(
    protocol: &'static str,
    addr: SocketAddr,
    handler: Arc<dyn super::Handler>,
    options: super::ServerOptions,
    serve: S,
    io_err: fn(&E) -> Option<&io::Error>,
) -> Result<super::ServerHandle, super::ServerError>
where
    S: Fn(TcpStream, Arc<dyn super::Handler>, super::ServerOptions) -> Fut + Send + Sync + 'static,
    Fut: Future<Output = Result<(), E>> + Send + 'static,
    E: std::fmt::Display + 'static,
{
    listen(protocol, addr, move |stream, peer| {
        let connection = serve(stream, Arc::clone(&handler), options.clone());
        async move { log_end(protocol, peer, connection.await, io_err) }
    })
    .await
}

/// Binds `addr` and serves every connection with `serve` (on its own task) until the returned
/// handle is dropped: the raw-socket, HiSLIP and VICP servers' start.
pub(crate) async fn listen<F, Fut>(
    protocol: &'static str,
    addr: SocketAddr,
    serve: F,
) -> Result<super::ServerHandle, super::ServerError>
where
    F: Fn(TcpStream, SocketAddr) -> Fut + Send + 'static,
    Fut: Future<Output = ()> + Send + 'static,
{
    let listener = super::bind(protocol, addr).await?;
    let local = listener
        .local_addr()
        .map_err(|source| super::ServerError::Start { protocol, source })?;
    let task = tokio::spawn(accept_loop(listener, protocol, serve));
    Ok(super::ServerHandle::new(protocol, local, task))
}

/// Accepts connections forever, running `serve` for each on its own task. Connection tasks live
/// in a [`JoinSet`] owned by the loop, so aborting the loop's task drops every connection.
pub(crate) async fn accept_loop<F, Fut>(listener: TcpListener, protocol: &'static str, serve: F)
where
    F: Fn(TcpStream, SocketAddr) -> Fut,
    Fut: Future<Output = ()> + Send + 'static,
{
    let mut connections = JoinSet::new();
    loop {
        tokio::select! {
            accepted = listener.accept() => match accepted {
                Ok((stream, peer)) => {
                    if let Err(err) = stream.set_nodelay(true) {
                        tracing::debug!(%peer, protocol, "cannot set TCP_NODELAY: {err}");
                    }
                    tracing::debug!(%peer, protocol, "client connected");
                    connections.spawn(serve(stream, peer));
                }
                Err(err) => {
                    // Typically EMFILE: back off briefly instead of spinning.
                    tracing::warn!(protocol, "accept failed: {err}");
                    tokio::time::sleep(std::time::Duration::from_millis(50)).await;
                }
            },
            Some(_) = connections.join_next(), if !connections.is_empty() => {}
        }
    }
}

/// Runs a blocking closure on the blocking pool. `None` when it panicked (logged); the caller
/// then closes its connection, and the server keeps running.
pub(crate) async fn blocking<T: Send + 'static>(
    f: impl FnOnce() -> T + Send + 'static,
) -> Option<T> {
    match tokio::task::spawn_blocking(f).await {
        Ok(value) => Some(value),
        Err(err) => {
            tracing::error!("instrument handler failed: {err}");
            None
        }
    }
}

/// Hands one message to the handler on the blocking pool and returns its responses, each with a
/// 488.2 response terminator (LF outside any block) appended when missing.
pub(crate) async fn call_handler(
    handler: &Arc<dyn Handler>,
    message: Bytes,
) -> Option<Vec<Response>> {
    let handler = Arc::clone(handler);
    let responses = blocking(move || handler.respond(message)).await?;
    Some(responses.into_iter().map(Response::terminated).collect())
}

/// How often a device clear is passed on again to a handler still busy with a message the clear
/// abandoned.
const CLEAR_REPEAT: Duration = Duration::from_millis(50);

/// Runs the handler on `message`, received in clear generation `of` of a link whose current
/// generation is `generation`. A device clear can land between the worker's generation check and
/// the handler starting the message; the handler then missed it (a `SLOW?` would run its full
/// time). So while the message runs and the link has moved on, the clear is passed on again every
/// [`CLEAR_REPEAT`]. Every protocol server with a device clear (VXI-11, HiSLIP, VICP) calls this.
pub(crate) async fn call_clearable(
    handler: &Arc<dyn Handler>,
    message: Bytes,
    generation: &AtomicU64,
    of: u64,
) -> Option<Vec<Response>> {
    let call = call_handler(handler, message);
    tokio::pin!(call);
    let mut tick = tokio::time::interval(CLEAR_REPEAT);
    loop {
        tokio::select! {
            responses = &mut call => return responses,
            _ = tick.tick() => {
                if generation.load(Ordering::SeqCst) != of {
                    let handler = Arc::clone(handler);
                    blocking(move || handler.device_clear()).await;
                }
            }
        }
    }
}

/// Appends the LF response terminator unless the response already ends with one (serial port).
pub(crate) fn terminated(mut response: Vec<u8>) -> Vec<u8> {
    if !has_terminator(&response) {
        response.push(b'\n');
    }
    response
}

/// Reads exactly `n` bytes from `r`, appending them to `dst` in large reads. Memory grows with
/// the bytes that actually arrive, never with what a length field merely announced.
pub(crate) async fn read_exact_append<R: AsyncRead + Unpin>(
    r: &mut R,
    dst: &mut Vec<u8>,
    n: u64,
) -> io::Result<()> {
    let mut left = n;
    // Room for the whole announced length at once (bounded by the pool's presize limit), from
    // recycled memory when there is some: no regrowth copies, no fresh pages to fault in.
    pool::reserve(dst, usize::try_from(n).unwrap_or(usize::MAX));
    while left > 0 {
        let want = left.min(READ_CHUNK as u64);
        dst.reserve(want as usize);
        let got = (&mut *r).take(want).read_buf(dst).await?;
        if got == 0 {
            return Err(io::ErrorKind::UnexpectedEof.into());
        }
        left -= got as u64;
    }
    Ok(())
}

/// Reads and discards exactly `n` bytes (payload of a message being refused).
pub(crate) async fn skip_exact<R: AsyncRead + Unpin>(r: &mut R, n: u64) -> io::Result<()> {
    let copied = tokio::io::copy(&mut (&mut *r).take(n), &mut tokio::io::sink()).await?;
    if copied < n {
        return Err(io::ErrorKind::UnexpectedEof.into());
    }
    Ok(())
}

/// What became of a reply.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Delivery {
    /// Written completely.
    Sent,
    /// Not written (fault: a reply that never comes).
    Swallowed,
    /// Half written; the caller must close the connection now (fault).
    Dropped,
}

/// Writes an encoded reply made of `parts` (headers and payloads, in order) according to `plan`.
pub(crate) async fn write_reply<W: AsyncWrite + Unpin>(
    w: &mut W,
    parts: &[&[u8]],
    plan: ReplyPlan,
) -> io::Result<Delivery> {
    if !plan.delay.is_zero() {
        tokio::time::sleep(plan.delay).await;
    }
    let total: usize = parts.iter().map(|p| p.len()).sum();
    let limit = match plan.fate {
        ReplyFate::Swallow => return Ok(Delivery::Swallowed),
        ReplyFate::DropMidway => total / 2,
        ReplyFate::Deliver => total,
    };
    if plan.byte_segments {
        write_bytewise(w, parts, limit).await?;
    } else if total <= COALESCE_LIMIT {
        let joined: Vec<u8> = parts.concat();
        w.write_all(&joined[..limit]).await?;
    } else {
        write_parts(w, &truncate_parts(parts, limit)).await?;
    }
    w.flush().await?;
    if plan.fate == ReplyFate::DropMidway {
        // Best effort: the peer sees a half message followed by FIN.
        let _ = w.shutdown().await;
        return Ok(Delivery::Dropped);
    }
    Ok(Delivery::Sent)
}

/// The first `limit` bytes of `parts`, as sub-slices.
fn truncate_parts<'a>(parts: &[&'a [u8]], limit: usize) -> Vec<&'a [u8]> {
    let mut left = limit;
    let mut out = Vec::with_capacity(parts.len());
    for part in parts {
        let n = part.len().min(left);
        if n > 0 {
            out.push(&part[..n]);
        }
        left -= n;
    }
    out
}

/// Lengths of the frames that carry `total` bytes, at most `chunk` each (one empty frame when
/// `total` is 0: an empty response still needs its end marker).
pub(crate) fn frame_lengths(total: usize, chunk: usize) -> Vec<usize> {
    let chunk = chunk.max(1);
    let frames = total.div_ceil(chunk).max(1);
    (0..frames)
        .map(|i| (total - i * chunk).min(chunk))
        .collect()
}

/// Each frame header followed by the sub-slices of `parts` its frame carries (frame `i` carries
/// `lens[i]` bytes, see [`frame_lengths`]): the payload is sliced, never copied.
pub(crate) fn interleave<'a, H: AsRef<[u8]>>(
    headers: &'a [H],
    lens: &[usize],
    parts: &'a [Bytes],
) -> Vec<&'a [u8]> {
    let mut slices: Vec<&[u8]> = Vec::with_capacity(headers.len() * 2 + parts.len());
    let mut pieces = parts.iter().map(|p| &p[..]);
    let mut current: &[u8] = &[];
    for (header, &len) in headers.iter().zip(lens) {
        slices.push(header.as_ref());
        let mut need = len;
        while need > 0 {
            if current.is_empty() {
                // The lengths count exactly these pieces: they cannot run out early.
                let Some(next) = pieces.next() else { break };
                current = next;
                continue;
            }
            let (head, tail) = current.split_at(current.len().min(need));
            slices.push(head);
            need -= head.len();
            current = tail;
        }
    }
    slices
}

/// Parts at least this long are written on their own, in pieces of [`WRITE_PIECE`].
const BIG_PART: usize = 64 << 10;
/// Piece size for large payloads. One writev of a whole 64 MB payload measured slower than
/// 8 MB writes on this loopback (the peer starts copying out sooner).
const WRITE_PIECE: usize = 8 << 20;

/// Writes `parts` back to back: runs of small parts (frame and block headers) in one vectored
/// write (one TCP segment, one wake-up of the peer), large payloads in `WRITE_PIECE` writes.
/// Nothing is copied into a joined buffer.
pub(crate) async fn write_parts<W: AsyncWrite + Unpin>(
    w: &mut W,
    parts: &[&[u8]],
) -> io::Result<()> {
    let mut rest = parts;
    while let Some(first) = rest.first() {
        if first.len() >= BIG_PART {
            for piece in first.chunks(WRITE_PIECE) {
                w.write_all(piece).await?;
            }
            rest = &rest[1..];
            continue;
        }
        let small = rest
            .iter()
            .position(|p| p.len() >= BIG_PART)
            .unwrap_or(rest.len());
        write_all_vectored(w, &rest[..small]).await?;
        rest = &rest[small..];
    }
    Ok(())
}

/// At most this many slices per writev (the kernel refuses more than IOV_MAX = 1024).
const MAX_IOVECS: usize = 64;

/// Writes `parts` back to back with vectored writes (no copy into a joined buffer).
pub(crate) async fn write_all_vectored<W: AsyncWrite + Unpin>(
    w: &mut W,
    parts: &[&[u8]],
) -> io::Result<()> {
    let mut slices: Vec<IoSlice<'_>> = parts
        .iter()
        .filter(|p| !p.is_empty())
        .map(|p| IoSlice::new(p))
        .collect();
    let mut pending = &mut slices[..];
    while !pending.is_empty() {
        let upto = pending.len().min(MAX_IOVECS);
        let n = w.write_vectored(&pending[..upto]).await?;
        if n == 0 {
            return Err(io::ErrorKind::WriteZero.into());
        }
        IoSlice::advance_slices(&mut pending, n);
    }
    Ok(())
}

async fn write_bytewise<W: AsyncWrite + Unpin>(
    w: &mut W,
    parts: &[&[u8]],
    limit: usize,
) -> io::Result<()> {
    for &byte in parts.iter().flat_map(|p| p.iter()).take(limit) {
        w.write_all(&[byte]).await?;
        w.flush().await?;
    }
    Ok(())
}

/// True for errors that just mean the client went away.
pub(crate) fn is_disconnect(err: &io::Error) -> bool {
    matches!(
        err.kind(),
        io::ErrorKind::UnexpectedEof
            | io::ErrorKind::ConnectionReset
            | io::ErrorKind::ConnectionAborted
            | io::ErrorKind::BrokenPipe
    )
}

/// Logs how a connection ended: disconnects at debug level, real errors as warnings.
pub(crate) fn log_end<E: std::fmt::Display>(
    protocol: &'static str,
    peer: SocketAddr,
    result: Result<(), E>,
    io_err: impl Fn(&E) -> Option<&io::Error>,
) {
    match result {
        Ok(()) => tracing::debug!(%peer, protocol, "client disconnected"),
        Err(err) => match io_err(&err) {
            Some(io) if is_disconnect(io) => {
                tracing::debug!(%peer, protocol, "client vanished: {err}")
            }
            _ => tracing::warn!(%peer, protocol, "connection closed: {err}"),
        },
    }
}
