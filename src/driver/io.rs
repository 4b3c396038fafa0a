//! What a driver needs from a session, as an object-safe trait.
//!
//! Drivers hold a `Box<dyn InstrumentIo>`: a real [`Session`] on the bench, a
//! `Scripted` fake (feature `testing`) in tests that pin the exact command sequence of an
//! operation. Keeping the surface this small (write, query, blocks, error queue, device clear) is
//! what makes the fake honest: a driver cannot reach around it.

use std::future::Future;
use std::pin::Pin;
use std::sync::atomic::{AtomicU64, Ordering};
use std::time::Duration;

use crate::address::Resource;
use crate::catalog::{InstrumentModel, TimeoutPolicy};
use crate::session::{Block, BlockForm, DeviceError, Session, SessionError, SessionOptions};
use crate::transport::{Journal, LinkOptions, Timeouts};

/// A boxed, sendable future: what the object-safe traits of this layer return.
pub type BoxFuture<'a, T> = Pin<Box<dyn Future<Output = T> + Send + 'a>>;

/// The operations drivers use. Commands are single program messages without a newline.
pub trait InstrumentIo: Send {
    /// The resource this talks to, for messages (e.g. `TCPIP::127.0.0.1::5025::SOCKET`).
    fn resource_text(&self) -> String;
    /// The transport protocol (`socket`, `vxi11`, `hislip`, `vicp`, `serial`, `scripted`).
    fn protocol(&self) -> &'static str;
    /// Sends one command.
    fn write<'a>(&'a mut self, command: &'a str) -> BoxFuture<'a, Result<(), SessionError>>;
    /// Sends a query and returns its reply without the terminator.
    fn query<'a>(&'a mut self, query: &'a str) -> BoxFuture<'a, Result<String, SessionError>>;
    /// Like [`query`](Self::query) but waits up to `timeout` for the reply to start (a scope's
    /// `WAIT`, a long `*OPC?`).
    fn query_with_timeout<'a>(
        &'a mut self,
        query: &'a str,
        timeout: Duration,
    ) -> BoxFuture<'a, Result<String, SessionError>>;
    /// Sends `header` followed by `payload` as a definite-length block (`#<d><len><bytes>`).
    fn write_block<'a>(
        &'a mut self,
        header: &'a str,
        payload: &'a [u8],
    ) -> BoxFuture<'a, Result<(), SessionError>>;
    /// Sends a query whose reply carries a block, and returns the block.
    fn query_block<'a>(&'a mut self, query: &'a str) -> BoxFuture<'a, Result<Block, SessionError>>;
    /// Drains the instrument's error queue (empty when it has nothing to report).
    fn errors(&mut self) -> BoxFuture<'_, Result<Vec<DeviceError>, SessionError>>;
    /// IEEE 488.2 device clear.
    fn device_clear(&mut self) -> BoxFuture<'_, Result<(), SessionError>>;
}

impl InstrumentIo for Session {
    fn resource_text(&self) -> String {
        self.resource().to_string()
    }

    fn protocol(&self) -> &'static str {
        self.resource().protocol()
    }

    fn write<'a>(&'a mut self, command: &'a str) -> BoxFuture<'a, Result<(), SessionError>> {
        Box::pin(Session::write(self, command))
    }

    fn query<'a>(&'a mut self, query: &'a str) -> BoxFuture<'a, Result<String, SessionError>> {
        Box::pin(Session::query(self, query))
    }

    fn query_with_timeout<'a>(
        &'a mut self,
        query: &'a str,
        timeout: Duration,
    ) -> BoxFuture<'a, Result<String, SessionError>> {
        Box::pin(Session::query_within(self, query, timeout))
    }

    fn write_block<'a>(
        &'a mut self,
        header: &'a str,
        payload: &'a [u8],
    ) -> BoxFuture<'a, Result<(), SessionError>> {
        Box::pin(Session::write_block(
            self,
            header,
            payload,
            BlockForm::Definite,
        ))
    }

    fn query_block<'a>(&'a mut self, query: &'a str) -> BoxFuture<'a, Result<Block, SessionError>> {
        Box::pin(Session::query_block(self, query))
    }

    fn errors(&mut self) -> BoxFuture<'_, Result<Vec<DeviceError>, SessionError>> {
        Box::pin(Session::errors(self))
    }

    fn device_clear(&mut self) -> BoxFuture<'_, Result<(), SessionError>> {
        Box::pin(Session::device_clear(self))
    }
}

/// The read timeout of every link opened from now on, in place of the catalog models' `[timeouts]
/// read_ms` (milliseconds; 0: each model's own). Set once by the command line's `--timeout`.
static READ_TIMEOUT_MS: AtomicU64 = AtomicU64::new(0);

/// Gives every instrument link opened from now on `read` as its read timeout (the time a reply
/// may take to start), in place of each catalog model's `[timeouts] read_ms`: the command line's
/// `--timeout`, for an instrument slower than its catalog entry says.
pub fn set_read_timeout(read: Duration) {
    let ms = u64::try_from(read.as_millis()).unwrap_or(u64::MAX).max(1);
    READ_TIMEOUT_MS.store(ms, Ordering::Relaxed);
}

/// Link timeouts from a catalog model's timeout policy: connect, read and write as given (the
/// read timeout [`set_read_timeout`]'s when set), and the per-megabyte allowance turned into the
/// slowest healthy transfer rate.
pub(crate) fn timeouts_from_catalog(policy: &TimeoutPolicy) -> Timeouts {
    let min_rate = 1_000_000_000u64
        .checked_div(policy.per_megabyte_ms)
        .unwrap_or(u64::MAX);
    let read_ms = match READ_TIMEOUT_MS.load(Ordering::Relaxed) {
        0 => policy.read_ms,
        ms => ms,
    };
    Timeouts {
        connect: Duration::from_millis(policy.connect_ms),
        read: Duration::from_millis(read_ms),
        write: Duration::from_millis(policy.write_ms),
        min_rate_bytes_per_s: min_rate.max(1),
    }
}

/// Headroom over a model's largest data message, for headers, prefixes and text replies. A
/// digitizer's record header is within it (LeCroy's WAVEDESC: 346 bytes; its catalog check
/// allows at most 64 KiB), so the session needs no family's layout (no import of `open`).
pub(crate) const MESSAGE_HEADROOM_BYTES: usize = 1 << 20;

/// The longest line of a line-protocol module (`[protocol]`): its replies are tens of bytes.
pub(crate) const LINE_MESSAGE_BYTES: usize = 64 << 10;

/// The largest message a driver exchanges with `model`, from its catalog limits, so a peer that
/// never ends a message is stopped early (docs/io-timeouts.md): for an AWG, one download chunk
/// (two bytes per sample when the marker is interleaved); for a digitizer, one channel's record
/// in 16-bit words plus its sequence's trigger times; each plus `MESSAGE_HEADROOM_BYTES` (which
/// holds the record's header). A line-protocol
/// module gets `LINE_MESSAGE_BYTES`; anything else the link's default.
pub fn max_message_bytes(model: &InstrumentModel) -> usize {
    let default = LinkOptions::default().max_message_bytes;
    if model.protocol.is_some() {
        return LINE_MESSAGE_BYTES.min(default);
    }
    let data = if let Some(awg) = &model.awg {
        let granularity = awg
            .dividers
            .iter()
            .map(|d| d.granularity)
            .max()
            .unwrap_or(1);
        Some(
            awg.download_chunk_samples
                .max(granularity)
                .saturating_mul(2),
        )
    } else {
        model.digitizer.as_ref().map(|d| {
            // A sequence adds one TRIGTIME entry (two f64) per segment.
            d.max_points_per_channel
                .saturating_mul(2)
                .saturating_add(u64::from(d.max_sequence_segments).saturating_mul(16))
        })
    };
    match data {
        Some(bytes) => usize::try_from(bytes)
            .unwrap_or(usize::MAX)
            .saturating_add(MESSAGE_HEADROOM_BYTES)
            .min(default),
        None => default,
    }
}

/// Session options for a model: its timeouts, its largest message ([`max_message_bytes`]) and
/// `error_query` (the SCPI error queue for SCPI instruments; drivers of instruments without one
/// never call [`InstrumentIo::errors`]).
pub fn session_options(model: &InstrumentModel, error_query: &str) -> SessionOptions {
    SessionOptions {
        link: LinkOptions {
            timeouts: timeouts_from_catalog(&model.timeouts),
            max_message_bytes: max_message_bytes(model),
            ..LinkOptions::default()
        },
        error_query: error_query.to_string(),
        ..SessionOptions::default()
    }
}

/// Opens a session to `resource` with the model's timeouts and message limit, journalled under
/// `instrument`.
///
/// # Errors
///
/// [`SessionError`] when the link cannot be opened (refused, unreachable, or timed out).
pub async fn open_session(
    resource: Resource,
    model: &InstrumentModel,
    error_query: &str,
    journal: Option<Journal>,
    instrument: &str,
) -> Result<Session, SessionError> {
    Session::open(
        resource,
        session_options(model, error_query),
        journal,
        instrument,
    )
    .await
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn per_megabyte_allowance_becomes_a_rate() {
        let policy = TimeoutPolicy {
            connect_ms: 1000,
            read_ms: 2000,
            write_ms: 3000,
            per_megabyte_ms: 500,
            operation_complete_ms: 60_000,
        };
        let t = timeouts_from_catalog(&policy);
        assert_eq!(t.read, Duration::from_millis(2000));
        assert_eq!(t.min_rate_bytes_per_s, 2_000_000);
        // One megabyte is allowed exactly the catalog's per-megabyte time.
        assert_eq!(t.allowance_for(1_000_000), Duration::from_millis(500));
    }

    #[test]
    fn message_limits_follow_the_catalog() {
        let catalog = crate::catalog::Catalog::embedded().unwrap();
        let awg = catalog.get("keysight-m8195a").unwrap();
        // 512 000 samples a chunk, sample and marker byte each: 1 024 000 bytes, plus headroom.
        assert_eq!(max_message_bytes(awg), 1_024_000 + (1 << 20));
        let scope = catalog.get("lecroy-labmaster10zi-a").unwrap();
        // 32 Mpoints in 16-bit words and a TRIGTIME entry of 16 bytes for each of 15 000
        // sequence segments, plus headroom (the 346-byte WAVEDESC is inside it).
        assert_eq!(max_message_bytes(scope), 64_000_000 + 240_000 + (1 << 20));
        let tx = catalog.get("gotmic-eband-tx").unwrap();
        assert_eq!(max_message_bytes(tx), 64 << 10);
        assert_eq!(
            session_options(scope, "CMR?").link.max_message_bytes,
            max_message_bytes(scope)
        );
    }
}
