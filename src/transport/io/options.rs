//! What a link is opened with: timeouts (with the allowance that grows with a transfer's size),
//! the largest message, progress reports.

use std::sync::Arc;
use std::time::Duration;

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
const DEFAULT_MAX_MESSAGE_BYTES: usize = 1 << 30;

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
    pub serial: crate::transport::SerialSettings,
    /// What a serial link does with the line before its first request (drains it by default).
    pub serial_on_open: crate::transport::OnOpen,
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
