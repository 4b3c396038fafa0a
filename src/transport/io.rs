//! Shared machinery of the network transports: options, size-aware deadlines, progress reports,
//! and the cancel-safe frame reader.
//!
//! Cancel safety: every await here is either `read_buf` into a buffer the transport owns, or a
//! write. A dropped read therefore loses no bytes (the decoder state and the partial frame stay in
//! the transport); a dropped write may leave half a message on the wire, which is why transports
//! mark themselves dirty before writing and recover (clear or reconnect) before the next operation.

use super::error::{CodecError, LinkError};
use bytes::{Buf, Bytes, BytesMut};
use std::io::IoSlice;
use std::sync::Arc;
use std::time::Duration;
use tokio::io::{AsyncRead, AsyncReadExt, AsyncWrite, AsyncWriteExt};
use tokio::time::Instant;

/// A progress report for a long transfer.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Progress {
    pub direction: Direction,
    /// Bytes moved so far in this message.
    pub done: u64,
    /// The message size when known (from a block header or a frame length).
    pub total: Option<u64>,
}

/// Which way bytes flow, seen from radbench.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Direction {
    Write,
    Read,
}

/// Called from the I/O task; keep it cheap (update a progress bar, not a file).
pub type ProgressFn = Arc<dyn Fn(Progress) + Send + Sync>;

/// Connect, read and write timeouts, kept apart, plus the rate that stretches deadlines for big
/// transfers. The rule (docs/io-timeouts.md): a read must end by
/// `start + read + min(counted, max_message_bytes) / min_rate`, where `counted` is the bytes of
/// *this* message received so far. Bytes thrown away (stale replies, frames of other messages) and
/// lengths a header merely announces earn nothing; a write of `n` bytes gets `write + n / min_rate`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Timeouts {
    pub connect: Duration,
    /// Time allowed for a reply to start and for small replies to complete.
    pub read: Duration,
    /// Time allowed for a small message to be accepted.
    pub write: Duration,
    /// The slowest transfer rate (bytes per second) still considered healthy.
    pub min_rate_bytes_per_s: u64,
}

impl Default for Timeouts {
    fn default() -> Self {
        Self {
            connect: Duration::from_secs(5),
            read: Duration::from_secs(10),
            write: Duration::from_secs(10),
            min_rate_bytes_per_s: 10_000_000,
        }
    }
}

impl Timeouts {
    /// The extra time a transfer of `bytes` is allowed beyond the base timeout.
    pub(crate) fn allowance_for(&self, bytes: u64) -> Duration {
        let rate = self.min_rate_bytes_per_s.max(1);
        Duration::from_secs_f64(bytes as f64 / rate as f64)
    }
}

/// The default largest message, either way: 1 GiB (a 32 Mpoint scope trace is 64 MB; `bench io`
/// raises it for bigger test blocks). It also caps the transfer allowance of a read.
pub(crate) const DEFAULT_MAX_MESSAGE_BYTES: usize = 1 << 30;

/// Everything a transport needs besides its address.
#[derive(Clone)]
pub struct LinkOptions {
    pub timeouts: Timeouts,
    /// The largest message accepted or sent; length fields above it are refused before any
    /// allocation.
    pub max_message_bytes: usize,
    /// Called while long messages move, every `progress_step_bytes`.
    pub progress: Option<ProgressFn>,
    pub progress_step_bytes: u64,
    /// Serial settings for `ASRL` resources (from the bench file).
    pub serial: super::serial::SerialSettings,
    /// What a serial link does with the line before its first request (drains it by default).
    pub serial_on_open: super::serial::OnOpen,
    /// Where the ONC-RPC portmapper listens (VXI-11 without an explicit port); 111 on instruments.
    pub portmapper_port: u16,
}

impl Default for LinkOptions {
    fn default() -> Self {
        Self {
            timeouts: Timeouts::default(),
            max_message_bytes: DEFAULT_MAX_MESSAGE_BYTES,
            progress: None,
            progress_step_bytes: 4 << 20,
            serial: Default::default(),
            serial_on_open: Default::default(),
            portmapper_port: crate::address::PORTMAPPER_PORT,
        }
    }
}

impl std::fmt::Debug for LinkOptions {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("LinkOptions")
            .field("timeouts", &self.timeouts)
            .field("max_message_bytes", &self.max_message_bytes)
            .field("progress", &self.progress.is_some())
            .field("progress_step_bytes", &self.progress_step_bytes)
            .field("serial", &self.serial)
            .field("serial_on_open", &self.serial_on_open)
            .field("portmapper_port", &self.portmapper_port)
            .finish()
    }
}

/// Every item `decoder` gives for `chunks` arriving one after the other, or its first error (the
/// codecs' unit tests; the conformance harness is tests/io_fuzz.rs).
#[cfg(test)]
pub(crate) fn decode_chunks<D: Decode>(
    mut decoder: D,
    chunks: &[&[u8]],
) -> Result<Vec<D::Item>, CodecError> {
    let mut buf = BytesMut::new();
    let mut out = Vec::new();
    for chunk in chunks {
        buf.extend_from_slice(chunk);
        while let Some(item) = decoder.decode(&mut buf)? {
            out.push(item);
        }
    }
    Ok(out)
}

/// An incremental decoder: consumes whole frames from the front of `src`, leaves partial ones.
pub trait Decode {
    type Item;
    /// Returns a frame when `src` holds a whole one. May reserve space in `src` for a frame whose
    /// length it has read (after checking the length against its limit).
    fn decode(&mut self, src: &mut BytesMut) -> Result<Option<Self::Item>, CodecError>;
    /// The total size of the frame being decoded, once its header announced it (0 if unknown).
    fn announced(&self) -> u64 {
        0
    }
}

/// One message's worth of reading, with the deadline of [`Timeouts`]: it grows only with the bytes
/// of this message that actually arrived, never with a length a header announces, and bytes the
/// transport throws away ([`ReadContext::discard`]) give their time back.
pub(crate) struct ReadContext<'a> {
    op: &'static str,
    started: Instant,
    timeouts: Timeouts,
    /// Every byte read, for progress reports.
    received: u64,
    /// Bytes read and then thrown away (stale replies, frames of other messages).
    discarded: u64,
    /// Cap on the bytes that earn time: the largest message.
    max_counted: u64,
    /// The receive buffer never grows beyond this (largest message plus framing slack).
    buffer_ceiling: usize,
    expected: u64,
    frame_start: u64,
    progress: Option<&'a ProgressFn>,
    step: u64,
    next_report: u64,
}

impl<'a> ReadContext<'a> {
    pub(crate) fn new(op: &'static str, options: &'a LinkOptions) -> Self {
        Self {
            op,
            started: Instant::now(),
            timeouts: options.timeouts,
            received: 0,
            discarded: 0,
            max_counted: options.max_message_bytes as u64,
            buffer_ceiling: buffer_ceiling(options.max_message_bytes),
            expected: 0,
            frame_start: 0,
            progress: options.progress.as_ref(),
            step: options.progress_step_bytes.max(1),
            next_report: options.progress_step_bytes.max(1),
        }
    }

    /// Replaces the base time (the read timeout), e.g. with the write timeout for the replies to
    /// VXI-11 device_write.
    pub(crate) fn with_base(mut self, base: Duration) -> Self {
        self.timeouts.read = base;
        self
    }

    /// The bytes that earn transfer time: those of this message received so far, at most the
    /// largest message.
    pub(crate) fn counted(&self) -> u64 {
        (self.received - self.discarded).min(self.max_counted)
    }

    pub(crate) fn deadline(&self) -> Instant {
        self.started + self.allowed()
    }

    pub(crate) fn elapsed(&self) -> Duration {
        self.started.elapsed()
    }

    /// The time this read is allowed so far: the read timeout plus the allowance earned.
    pub(crate) fn allowed(&self) -> Duration {
        self.timeouts.read + self.timeouts.allowance_for(self.counted())
    }

    /// The timeout, reported with the time that was allowed (what the user set, plus the
    /// allowance), or the time taken if the peer gave up first.
    pub(crate) fn timeout_error(&self) -> LinkError {
        LinkError::Timeout {
            op: self.op,
            after: self.elapsed().min(self.allowed()),
        }
    }

    pub(crate) fn op(&self) -> &'static str {
        self.op
    }

    /// Time left before the deadline (zero if passed).
    pub(crate) fn remaining(&self) -> Duration {
        self.deadline().saturating_duration_since(Instant::now())
    }

    /// Declares the total message size once known, e.g. from a block header. Used for progress
    /// reports only: a claim earns no time.
    pub(crate) fn expect_total(&mut self, total: u64) {
        self.expected = self.expected.max(total);
    }

    /// Gives back the time earned by `bytes` the transport has thrown away (a stale reply, a
    /// frame that is not part of the message): they do not stretch the deadline.
    pub(crate) fn discard(&mut self, bytes: u64) {
        self.discarded = self.discarded.saturating_add(bytes).min(self.received);
    }

    fn add(&mut self, n: usize) {
        self.received += n as u64;
        if let Some(report) = self.progress {
            if self.received >= self.next_report {
                report(Progress {
                    direction: Direction::Read,
                    done: self.received,
                    total: (self.expected > 0).then_some(self.expected),
                });
                self.next_report = self.received + self.step;
            }
        }
    }

    /// Reads until `decoder` yields a frame. Cancel safe (see the module docs). The buffer grows
    /// as bytes arrive, never beyond the largest message plus framing slack.
    pub(crate) async fn read_frame<S, D>(
        &mut self,
        stream: &mut S,
        buf: &mut BytesMut,
        decoder: &mut D,
        protocol: &'static str,
    ) -> Result<D::Item, LinkError>
    where
        S: AsyncRead + Unpin,
        D: Decode,
    {
        self.frame_start = self.received.saturating_sub(buf.len() as u64);
        loop {
            if let Some(item) = decoder.decode(buf).map_err(LinkError::codec(protocol))? {
                return Ok(item);
            }
            let announced = decoder.announced();
            if announced > 0 {
                self.expect_total(self.frame_start + announced);
            }
            // A frame of announced length already has its room (the decoder reserved it, up to
            // the presize limit): topping up here too would reallocate, and copy, a nearly
            // complete 64 MB frame for the sake of its last few kB.
            let spare = buf.capacity() - buf.len();
            if spare == 0 || (spare < MIN_READ_SPACE && announced == 0) {
                reserve_within(buf, READ_CHUNK, self.buffer_ceiling);
            }
            let n = match tokio::time::timeout_at(self.deadline(), stream.read_buf(buf)).await {
                Err(_) => return Err(self.timeout_error()),
                Ok(Err(source)) => return Err(io_error(self.op, source)),
                Ok(Ok(0)) => return Err(LinkError::Closed { op: self.op }),
                Ok(Ok(n)) => n,
            };
            self.add(n);
        }
    }
}

/// Framing overhead allowed on top of the largest message in a receive buffer: headers, record
/// marks, XDR fields, and the start of the next frame read along with this one.
pub(crate) const FRAMING_SLACK: usize = 64 << 10;

/// The most a receive buffer holds for messages of at most `max_message` bytes.
pub fn buffer_ceiling(max_message: usize) -> usize {
    max_message
        .saturating_add(FRAMING_SLACK)
        .saturating_add(RECLAIM_SLACK)
}

/// Makes room for `additional` more bytes in `buf` without letting its capacity pass `ceiling`
/// (unless `additional` itself needs more): far below the ceiling, the usual amortised doubling;
/// near it, one exact allocation. A message that never ends therefore costs at most its limit,
/// not the 1.5x to 2x a doubling buffer overshoots by.
pub fn reserve_within(buf: &mut BytesMut, additional: usize, ceiling: usize) {
    if buf.capacity() - buf.len() >= additional || buf.try_reclaim(additional) {
        return;
    }
    let needed = buf.len().saturating_add(additional);
    let doubled = buf.capacity().saturating_mul(2).max(needed);
    if doubled <= ceiling / 2 {
        buf.reserve(additional);
    } else {
        // Through the Vec: an unshared buffer is taken without a copy and grown by realloc, which
        // for a large block remaps its pages rather than holding old and new side by side.
        let target = doubled.min(ceiling).max(needed);
        let mut bytes: Vec<u8> = std::mem::take(buf).into();
        bytes.reserve_exact(target - bytes.len());
        // Spare capacity, so Bytes keeps the Vec whole and hands it back unshared: no copy.
        *buf = BytesMut::from(bytes::Bytes::from(bytes));
    }
}

/// A reply of `total` bytes (so far) over the `limit` of the largest message.
pub(crate) fn reply_too_large(protocol: &'static str, total: u64, limit: usize) -> LinkError {
    LinkError::Codec {
        protocol,
        source: CodecError::TooLarge {
            format: protocol,
            announced: total,
            limit: limit as u64,
        },
    }
}

/// Appends one frame's payload to a message assembled from several frames, refusing a message
/// over `limit` bytes (a peer that never sends the last frame) before growing the buffer.
pub(crate) fn append_within(
    message: &mut BytesMut,
    data: &[u8],
    limit: usize,
    protocol: &'static str,
) -> Result<(), LinkError> {
    let total = message.len() as u64 + data.len() as u64;
    if total > limit as u64 {
        return Err(reply_too_large(protocol, total, limit));
    }
    reserve_within(message, data.len(), limit);
    message.extend_from_slice(data);
    Ok(())
}

/// One message put together from the frames that carry it (HiSLIP Data, VICP blocks, VXI-11
/// reads). A message of one frame is passed on as it came, a shared `Bytes` with no copy; only a
/// message of several frames is copied into one buffer, and never past the limit.
pub(crate) struct Reassembly {
    first: Option<Bytes>,
    rest: BytesMut,
    limit: usize,
    protocol: &'static str,
}

impl Reassembly {
    pub(crate) fn new(limit: usize, protocol: &'static str) -> Self {
        Reassembly {
            first: None,
            rest: BytesMut::new(),
            limit,
            protocol,
        }
    }

    /// Adds the next frame's payload; a message past the limit is an error.
    pub(crate) fn push(&mut self, payload: Bytes) -> Result<(), LinkError> {
        match &self.first {
            None if payload.len() > self.limit => Err(reply_too_large(
                self.protocol,
                payload.len() as u64,
                self.limit,
            )),
            None => {
                self.first = Some(payload);
                Ok(())
            }
            Some(head) => {
                if self.rest.is_empty() {
                    append_within(&mut self.rest, head, self.limit, self.protocol)?;
                }
                append_within(&mut self.rest, &payload, self.limit, self.protocol)
            }
        }
    }

    /// Drops what came so far (it belonged to an abandoned message); returns how many bytes.
    pub(crate) fn abandon(&mut self) -> usize {
        let dropped = self
            .first
            .take()
            .map_or(0, |f| f.len())
            .max(self.rest.len());
        self.rest.clear();
        dropped
    }

    /// The whole message.
    pub(crate) fn finish(self) -> Bytes {
        if self.rest.is_empty() {
            self.first.unwrap_or_default()
        } else {
            self.rest.freeze()
        }
    }
}

/// A fixed-size header that announces the length of the payload after it (HiSLIP, VICP).
pub trait FrameHeader: Copy {
    /// The header's size on the wire.
    const LEN: usize;
    /// The protocol's name, for errors.
    const FORMAT: &'static str;
    /// Reads a header from exactly [`LEN`](Self::LEN) bytes.
    fn parse(bytes: &[u8]) -> Result<Self, CodecError>;
    /// The payload length it announces.
    fn payload_len(&self) -> u64;
}

/// A header and its payload.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Framed<H> {
    pub header: H,
    pub payload: Bytes,
}

/// Incremental decoder of header-plus-payload frames with a payload limit: a header is parsed
/// (and its length checked) as soon as its bytes are there, the payload once it is complete.
#[derive(Debug, Clone)]
pub struct FramedDecoder<H> {
    limit: u64,
    pending: Option<H>,
}

impl<H> FramedDecoder<H> {
    pub fn new(limit: u64) -> Self {
        Self {
            limit,
            pending: None,
        }
    }
}

impl<H: FrameHeader> Decode for FramedDecoder<H> {
    type Item = Framed<H>;

    fn decode(&mut self, src: &mut BytesMut) -> Result<Option<Framed<H>>, CodecError> {
        let header = match self.pending {
            Some(h) => h,
            None => {
                if src.len() < H::LEN {
                    return Ok(None);
                }
                let h = H::parse(&src[..H::LEN])?;
                if h.payload_len() > self.limit {
                    return Err(CodecError::TooLarge {
                        format: H::FORMAT,
                        announced: h.payload_len(),
                        limit: self.limit,
                    });
                }
                src.advance(H::LEN);
                self.pending = Some(h);
                h
            }
        };
        let len = header.payload_len() as usize;
        if src.len() < len {
            reserve_announced(src, len - src.len(), self.limit);
            return Ok(None);
        }
        self.pending = None;
        let payload = src.split_to(len).freeze();
        Ok(Some(Framed { header, payload }))
    }

    fn announced(&self) -> u64 {
        self.pending.map_or(0, |h| h.payload_len() + H::LEN as u64)
    }
}

/// Largest reservation made from a length field alone (after its check against the limit): a
/// frame announced larger grows as its bytes actually arrive, so a peer's claim cannot make us
/// reserve more than this up front. Big enough for a 64 MB block in one piece.
pub(crate) const PRESIZE_LIMIT: usize = 128 << 20;

/// Makes room for `wanted` more bytes of a frame whose length a header announced (already
/// checked against the limit), at most `PRESIZE_LIMIT`: the payload is then read straight
/// into place, without regrowth copies.
pub fn reserve_announced(src: &mut BytesMut, wanted: usize, limit: u64) {
    let ceiling = buffer_ceiling(usize::try_from(limit).unwrap_or(usize::MAX));
    let wanted = wanted.min(PRESIZE_LIMIT);
    if src.capacity() - src.len() >= wanted {
        return;
    }
    // A large buffer gets room beyond this frame: once the caller has dropped the frame, the
    // buffer is reclaimed whole for the next one, and the next frame of the same size needs its
    // header (and the start of whatever follows) to fit as well, or the buffer is reallocated and
    // what was already read copied over. Measured: the repeated 64 MB read then touches no fresh
    // pages and makes no copy in user space.
    let wanted = if wanted >= HUGE_PAGE {
        (wanted + RECLAIM_SLACK).min(PRESIZE_LIMIT)
    } else {
        wanted
    };
    reserve_within(src, wanted, ceiling);
    if wanted >= HUGE_PAGE {
        let spare = src.spare_capacity_mut();
        advise_huge_pages(spare.as_mut_ptr().cast(), spare.len());
    }
}

const HUGE_PAGE: usize = 2 << 20;
/// Extra room given to large frame buffers (see [`reserve_announced`]): more than any frame
/// header plus one read's worth of what follows it.
const RECLAIM_SLACK: usize = READ_CHUNK + MIN_READ_SPACE;

/// Asks the kernel for transparent huge pages on the whole 2 MiB pages inside `ptr..ptr+len`
/// (memory this process owns and has not touched yet). A 64 MB receive buffer then costs 32 page
/// faults instead of 16 384, and the kernel's copy into it far fewer TLB misses. Advisory only:
/// contents are unchanged and failure is harmless (THP off, not Linux).
fn advise_huge_pages(ptr: *mut u8, len: usize) {
    #[cfg(target_os = "linux")]
    {
        let start = (ptr as usize).next_multiple_of(HUGE_PAGE);
        let end = (ptr as usize + len) / HUGE_PAGE * HUGE_PAGE;
        if end > start {
            // SAFETY: the range lies inside an allocation we own; MADV_HUGEPAGE changes neither
            // the mapping nor its contents, only how the kernel backs it.
            unsafe {
                libc::madvise(start as *mut libc::c_void, end - start, libc::MADV_HUGEPAGE);
            }
        }
    }
    #[cfg(not(target_os = "linux"))]
    let _ = (ptr, len);
}

const MIN_READ_SPACE: usize = 16 << 10;
const READ_CHUNK: usize = 256 << 10;
/// At most this many slices per writev (the kernel refuses more than IOV_MAX = 1024).
const MAX_IOVECS: usize = 64;
/// Parts at least this long are written on their own, in pieces of [`WRITE_PIECE`].
const BIG_PART: usize = 64 << 10;
/// Large writes go out in pieces of this size so progress can be reported.
const WRITE_PIECE: usize = 8 << 20;

/// Writes `parts` back to back with vectored writes.
async fn write_all_vectored<S: AsyncWrite + Unpin>(
    stream: &mut S,
    parts: &[&[u8]],
) -> std::io::Result<()> {
    let mut slices: Vec<IoSlice<'_>> = parts
        .iter()
        .filter(|p| !p.is_empty())
        .map(|p| IoSlice::new(p))
        .collect();
    let mut pending = &mut slices[..];
    while !pending.is_empty() {
        let upto = pending.len().min(MAX_IOVECS);
        let n = stream.write_vectored(&pending[..upto]).await?;
        if n == 0 {
            return Err(std::io::ErrorKind::WriteZero.into());
        }
        IoSlice::advance_slices(&mut pending, n);
    }
    Ok(())
}

/// Maps an I/O error, recognising a peer that went away.
pub(crate) fn io_error(op: &'static str, source: std::io::Error) -> LinkError {
    use std::io::ErrorKind as K;
    match source.kind() {
        K::UnexpectedEof | K::ConnectionReset | K::ConnectionAborted | K::BrokenPipe => {
            LinkError::Closed { op }
        }
        _ => LinkError::Io { op, source },
    }
}

/// Writes `parts` back to back (no copy into one buffer) before a deadline that grows with size.
pub(crate) async fn write_parts<S: AsyncWrite + Unpin>(
    stream: &mut S,
    parts: &[&[u8]],
    op: &'static str,
    options: &LinkOptions,
) -> Result<(), LinkError> {
    let total: u64 = parts.iter().map(|p| p.len() as u64).sum();
    let allowed = options.timeouts.write + options.timeouts.allowance_for(total);
    let deadline = Instant::now() + allowed;
    let report = options
        .progress
        .as_ref()
        .filter(|_| total >= options.progress_step_bytes);
    let mut done = 0u64;
    let work = async {
        let mut rest = parts;
        while !rest.is_empty() {
            // Runs of small parts (a frame header, the command, a block header) leave in one
            // vectored write, so one TCP segment and one wake-up of the peer: no copy into a
            // joined buffer either.
            let small = rest
                .iter()
                .position(|p| p.len() >= BIG_PART)
                .unwrap_or(rest.len());
            if small > 0 {
                write_all_vectored(stream, &rest[..small])
                    .await
                    .map_err(|e| io_error(op, e))?;
                done += rest[..small].iter().map(|p| p.len() as u64).sum::<u64>();
                rest = &rest[small..];
                continue;
            }
            // A payload goes out in pieces, so progress can be reported. (One vectored write of
            // header and payload measured slower over VICP and no faster elsewhere.)
            for piece in rest[0].chunks(WRITE_PIECE) {
                stream.write_all(piece).await.map_err(|e| io_error(op, e))?;
                done += piece.len() as u64;
                if let Some(report) = report {
                    report(Progress {
                        direction: Direction::Write,
                        done,
                        total: Some(total),
                    });
                }
            }
            rest = &rest[1..];
        }
        stream.flush().await.map_err(|e| io_error(op, e))
    };
    match tokio::time::timeout_at(deadline, work).await {
        Ok(result) => result,
        Err(_) => Err(LinkError::Timeout { op, after: allowed }),
    }
}

/// Connects a TCP stream within the connect timeout, with Nagle off (small commands go out at once).
pub(crate) async fn connect_tcp(
    host: &str,
    port: u16,
    protocol: &'static str,
    options: &LinkOptions,
) -> Result<tokio::net::TcpStream, LinkError> {
    let host_only = host.trim_start_matches('[').trim_end_matches(']');
    let target = format!("{host}:{port}");
    let connect = tokio::net::TcpStream::connect((host_only, port));
    let stream = match tokio::time::timeout(options.timeouts.connect, connect).await {
        Err(_) => {
            return Err(LinkError::Connect {
                target,
                protocol,
                source: std::io::Error::new(
                    std::io::ErrorKind::TimedOut,
                    format!(
                        "no answer within {}",
                        super::error::Rounded(options.timeouts.connect)
                    ),
                ),
            })
        }
        Ok(Err(source)) if source.kind() == std::io::ErrorKind::InvalidInput => {
            return Err(LinkError::Resolve {
                host: host.to_string(),
            })
        }
        Ok(Err(source)) => {
            return Err(LinkError::Connect {
                target,
                protocol,
                source,
            })
        }
        Ok(Ok(s)) => s,
    };
    stream
        .set_nodelay(true)
        .map_err(|e| io_error("connect", e))?;
    Ok(stream)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn deadlines_grow_with_transfer_size() {
        let t = Timeouts {
            min_rate_bytes_per_s: 10_000_000,
            ..Timeouts::default()
        };
        assert_eq!(t.allowance_for(0), Duration::ZERO);
        assert_eq!(t.allowance_for(64_000_000), Duration::from_millis(6400));
        let options = LinkOptions {
            timeouts: t,
            ..LinkOptions::default()
        };
        let mut ctx = ReadContext::new("read", &options);
        let small = ctx.deadline();
        // A header's claim earns nothing: the bytes must arrive.
        ctx.expect_total(100_000_000);
        assert_eq!(ctx.deadline(), small);
        ctx.add(50_000_000);
        assert_eq!(ctx.deadline() - small, Duration::from_secs(5));
        // Bytes thrown away (a stale reply) give their time back.
        ctx.discard(30_000_000);
        assert_eq!(ctx.deadline() - small, Duration::from_secs(2));
        ctx.discard(u64::MAX);
        assert_eq!(ctx.deadline(), small);
    }

    #[test]
    fn the_allowance_is_capped_by_the_largest_message() {
        let options = LinkOptions {
            timeouts: Timeouts {
                min_rate_bytes_per_s: 1_000_000,
                ..Timeouts::default()
            },
            max_message_bytes: 4_000_000,
            ..LinkOptions::default()
        };
        let mut ctx = ReadContext::new("read", &options);
        let small = ctx.deadline();
        ctx.add(usize::MAX / 2);
        assert_eq!(ctx.deadline() - small, Duration::from_secs(4));
    }

    #[test]
    fn buffers_stop_growing_at_their_ceiling() {
        let ceiling = 1 << 20;
        let mut buf = BytesMut::new();
        while buf.len() < ceiling - 4096 {
            reserve_within(&mut buf, 4096, ceiling);
            assert!(buf.capacity() <= ceiling, "{}", buf.capacity());
            let n = buf.capacity() - buf.len();
            buf.extend_from_slice(&vec![0; n.min(4096)]);
        }
        // A request beyond the ceiling still gets what it needs, no more.
        reserve_within(&mut buf, ceiling, ceiling);
        assert!(buf.capacity() >= buf.len() + ceiling);
        assert!(buf.capacity() <= 2 * ceiling);
        let mut message = BytesMut::new();
        append_within(&mut message, &[1; 100], 150, "test").unwrap();
        let err = append_within(&mut message, &[1; 51], 150, "test").unwrap_err();
        assert!(err.to_string().contains("151 bytes"), "{err}");
        assert_eq!(message.len(), 100);
    }

    /// One reply as a socket delivers it: the frame header and a few bytes first (the server
    /// writes headers apart from a large payload), then reads of at most 64 KiB.
    struct Trickle<'a> {
        rest: &'a [u8],
        first: bool,
    }

    impl<'a> Trickle<'a> {
        fn new(reply: &'a [u8]) -> Self {
            Self {
                rest: reply,
                first: true,
            }
        }
    }

    impl AsyncRead for Trickle<'_> {
        fn poll_read(
            mut self: std::pin::Pin<&mut Self>,
            _: &mut std::task::Context<'_>,
            buf: &mut tokio::io::ReadBuf<'_>,
        ) -> std::task::Poll<std::io::Result<()>> {
            let most = if self.first { 26 } else { 64 << 10 };
            self.first = false;
            let n = self.rest.len().min(buf.remaining()).min(most);
            buf.put_slice(&self.rest[..n]);
            self.rest = &self.rest[n..];
            std::task::Poll::Ready(Ok(()))
        }
    }

    /// Counts large allocations made by the current thread, to show a buffer is reused.
    struct CountingAllocator;

    thread_local! {
        static LARGE_ALLOCATIONS: std::cell::Cell<usize> = const { std::cell::Cell::new(0) };
    }

    fn count_if_large(size: usize) {
        if size >= 1 << 20 {
            let _ = LARGE_ALLOCATIONS.try_with(|n| n.set(n.get() + 1));
        }
    }

    // SAFETY: forwards every call unchanged to the system allocator; counting has no effect on
    // the memory handed out.
    unsafe impl std::alloc::GlobalAlloc for CountingAllocator {
        unsafe fn alloc(&self, layout: std::alloc::Layout) -> *mut u8 {
            count_if_large(layout.size());
            std::alloc::System.alloc(layout)
        }
        unsafe fn alloc_zeroed(&self, layout: std::alloc::Layout) -> *mut u8 {
            count_if_large(layout.size());
            std::alloc::System.alloc_zeroed(layout)
        }
        unsafe fn realloc(&self, ptr: *mut u8, layout: std::alloc::Layout, size: usize) -> *mut u8 {
            count_if_large(size);
            std::alloc::System.realloc(ptr, layout, size)
        }
        unsafe fn dealloc(&self, ptr: *mut u8, layout: std::alloc::Layout) {
            std::alloc::System.dealloc(ptr, layout)
        }
    }

    #[global_allocator]
    static ALLOCATOR: CountingAllocator = CountingAllocator;

    /// Large frames in a row, each dropped before the next is read (after a small one, as a
    /// session's `*OPC?` reply would be): once the first large frame has its buffer, the others
    /// land in it. No new allocation, so no fresh pages to clear and no copy of what was
    /// already read (on the bench this cut `radbench bench io`'s page faults by 35 000 and its
    /// CPU time by 15 %).
    #[tokio::test(flavor = "current_thread")]
    async fn a_dropped_large_frame_buffer_is_reused_for_the_next() {
        use crate::transport::hislip::codec::{encode_frame, FrameDecoder};
        // Not a multiple of the 64 KiB reads: a frame ends a few bytes into its last read.
        const LEN: usize = (4 << 20) + 100;
        let payload = vec![0x5a_u8; LEN];
        // One reply per request: nothing of the next frame is in the socket when one ends.
        let small = encode_frame(0x07, 0, 1, b"1\n");
        let large: Vec<Vec<u8>> = (2..=5)
            .map(|param| encode_frame(0x07, 0, param, &payload))
            .collect();
        let options = LinkOptions::default();
        let mut buf = BytesMut::with_capacity(64 << 10);
        let mut decoder = FrameDecoder::new(1 << 30);
        let mut ctx = ReadContext::new("read", &options);
        for (param, wire) in (1..).zip(std::iter::once(&small).chain(&large)) {
            if param == 3 {
                LARGE_ALLOCATIONS.with(|n| n.set(0));
            }
            let frame = ctx
                .read_frame(&mut Trickle::new(wire), &mut buf, &mut decoder, "test")
                .await
                .unwrap();
            assert_eq!(frame.header.param, param);
        }
        assert_eq!(
            LARGE_ALLOCATIONS.with(|n| n.get()),
            0,
            "frames 3 to 5 needed new buffers"
        );
    }
}
