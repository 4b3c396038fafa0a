//! Reading one message: the deadline that grows only with bytes that arrived, progress reports,
//! and the cancel-safe frame reader.

use super::buffers::{buffer_ceiling, reserve_within, MIN_READ_SPACE, READ_CHUNK};
use super::decode::Decode;
use super::options::{Direction, LinkOptions, Progress, ProgressFn, Timeouts};
use super::write::io_error;
use crate::transport::error::LinkError;
use bytes::BytesMut;
use std::time::Duration;
use tokio::io::{AsyncRead, AsyncReadExt};
use tokio::time::Instant;

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
            // SAFETY: the caller's contract, passed on to the system allocator unchanged.
            unsafe { std::alloc::System.alloc(layout) }
        }
        unsafe fn alloc_zeroed(&self, layout: std::alloc::Layout) -> *mut u8 {
            count_if_large(layout.size());
            // SAFETY: the caller's contract, passed on to the system allocator unchanged.
            unsafe { std::alloc::System.alloc_zeroed(layout) }
        }
        unsafe fn realloc(&self, ptr: *mut u8, layout: std::alloc::Layout, size: usize) -> *mut u8 {
            count_if_large(size);
            // SAFETY: the caller's contract, passed on to the system allocator unchanged.
            unsafe { std::alloc::System.realloc(ptr, layout, size) }
        }
        unsafe fn dealloc(&self, ptr: *mut u8, layout: std::alloc::Layout) {
            // SAFETY: the caller's contract, passed on to the system allocator unchanged.
            unsafe { std::alloc::System.dealloc(ptr, layout) }
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
        use crate::transport::hislip::{encode_frame, FrameDecoder};
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
