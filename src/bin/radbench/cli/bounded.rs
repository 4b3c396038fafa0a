//! One-shot instrument commands (`idn`, `scpi` with its commands on the command line) bounded in
//! total: whatever the instrument does (a half block then silence, replies that never end, a
//! stall after every answer), the command gives up at
//!
//!     --connect-timeout + exchanges × --timeout + 2 s + (bytes received) / --min-rate
//!
//! where `exchanges` is the number of commands (1 for `idn`) and the bytes received count up to
//! `exchanges` × [`MAX_REPLY_BYTES`] (each transport refuses a longer reply, and a peer that
//! floods reply after reply earns no more). Each read has its own
//! bound (docs/io-timeouts.md); the steps around a command (identifying the instrument, reading
//! its error queue, clearing the device after a timeout) each add theirs, and before this bound a
//! half block then a stall kept `scpi` 14 s and more on HiSLIP and VXI-11 with `--timeout 2`.
//!
//! The interactive `scpi` has the same bound for its connection (one exchange: connecting, the
//! identity probe, the error queue emptied) and for each line at the prompt (one exchange, with
//! the reply timeout `\timeout` set); a line past it is abandoned and the device cleared, within
//! `--timeout + 2 s` more, and the prompt goes on.

use radbench::exit::{Classified, ExitClass};
use radbench::transport::{Direction, Progress, ProgressFn};
use std::future::Future;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

/// Most bytes one reply may hold in `idn` and `scpi`: a reply that passes it is refused by the
/// transport, whatever its header announced (memory stays near it).
pub(crate) const MAX_REPLY_BYTES: usize = 64 << 20;

/// What a one-shot command may take beyond its exchanges' reply timeouts: the identity probe,
/// error checks and closing, on an instrument that answers them at once.
pub(crate) const MARGIN: Duration = Duration::from_secs(2);

/// The time a one-shot command may take, growing with the bytes that arrived.
#[derive(Clone)]
pub(crate) struct Budget {
    base: Duration,
    min_rate_bytes_per_s: f64,
    /// The most received bytes that earn time.
    max_earned_bytes: u64,
    /// Bytes received in every message so far.
    received: Arc<AtomicU64>,
    /// The progress of the message being read (a report below it starts a new message).
    current: Arc<Mutex<u64>>,
}

impl Budget {
    /// `connect + exchanges × read + MARGIN`, stretched by the bytes received at `min_rate`.
    pub(crate) fn new(
        connect: Duration,
        read: Duration,
        exchanges: usize,
        min_rate_bytes_per_s: u64,
    ) -> Budget {
        let exchanges = u32::try_from(exchanges.max(1)).unwrap_or(u32::MAX);
        Budget {
            base: connect + read.saturating_mul(exchanges) + MARGIN,
            min_rate_bytes_per_s: min_rate_bytes_per_s.max(1) as f64,
            max_earned_bytes: u64::from(exchanges) * MAX_REPLY_BYTES as u64,
            received: Arc::new(AtomicU64::new(0)),
            current: Arc::new(Mutex::new(0)),
        }
    }

    /// A progress callback that counts the bytes received, then passes the report on.
    pub(crate) fn counting(&self, inner: Option<ProgressFn>) -> ProgressFn {
        let this = self.clone();
        Arc::new(move |p: Progress| {
            if p.direction == Direction::Read {
                let mut current = this.current.lock().unwrap_or_else(|e| e.into_inner());
                let new = if p.done >= *current {
                    p.done - *current
                } else {
                    p.done
                };
                *current = p.done;
                this.received.fetch_add(new, Ordering::Relaxed);
            }
            if let Some(inner) = &inner {
                inner(p);
            }
        })
    }

    /// The time allowed so far.
    pub(crate) fn allowed(&self) -> Duration {
        let bytes = self
            .received
            .load(Ordering::Relaxed)
            .min(self.max_earned_bytes);
        let earned = bytes as f64 / self.min_rate_bytes_per_s;
        self.base + Duration::from_secs_f64(earned.min(86_400.0))
    }

    /// Runs `work` within the budget; past it, `work` is dropped (its connection closed) and the
    /// command fails with exit 3, naming `what` and the time it was allowed.
    pub(crate) async fn run<T>(
        &self,
        what: &str,
        work: impl Future<Output = anyhow::Result<T>>,
    ) -> anyhow::Result<T> {
        match self.run_or_give_up(what, work).await {
            Ok(out) => out,
            Err(gave_up) => Err(gave_up),
        }
    }

    /// [`run`](Self::run), the give-up told apart: `Err` when the time was spent (`work`
    /// dropped mid-exchange, so the caller may clear the device), else `work`'s own result.
    pub(crate) async fn run_or_give_up<T>(
        &self,
        what: &str,
        work: impl Future<Output = anyhow::Result<T>>,
    ) -> Result<anyhow::Result<T>, anyhow::Error> {
        let start = Instant::now();
        tokio::pin!(work);
        loop {
            let deadline = start + self.allowed();
            tokio::select! {
                out = &mut work => return Ok(out),
                () = tokio::time::sleep_until(deadline.into()) => {
                    // Bytes that arrived meanwhile earned more time.
                    if start + self.allowed() > Instant::now() {
                        continue;
                    }
                    return Err(anyhow::Error::new(Classified {
                        class: ExitClass::Instrument,
                        message: format!(
                            "{what}: gave up after {:.1} s in all (--connect-timeout + \
                             --timeout per command + 2 s + the bytes received at --min-rate): \
                             the instrument did not complete the exchange; the connection is \
                             closed",
                            self.allowed().as_secs_f64()
                        ),
                    }));
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_budget_grows_with_the_bytes_of_every_message() {
        let b = Budget::new(Duration::from_secs(1), Duration::from_secs(2), 3, 1_000_000);
        assert_eq!(b.allowed(), Duration::from_secs(9));
        let count = b.counting(None);
        let read = |done| Progress {
            direction: Direction::Read,
            done,
            total: None,
        };
        count(read(1_000_000));
        count(read(3_000_000));
        // A new message starts below the last report.
        count(read(2_000_000));
        count(Progress {
            direction: Direction::Write,
            done: 50_000_000,
            total: None,
        });
        assert_eq!(b.allowed(), Duration::from_secs(14));
        // A flood earns at most one capped reply per exchange.
        count(read(1 << 40));
        let most = 3.0 * MAX_REPLY_BYTES as f64 / 1e6;
        assert_eq!(
            b.allowed(),
            Duration::from_secs(9) + Duration::from_secs_f64(most)
        );
    }

    #[tokio::test]
    async fn work_past_the_budget_is_dropped_with_exit_3() {
        let b = Budget::new(Duration::ZERO, Duration::from_millis(100), 1, 1);
        let b = Budget {
            base: Duration::from_millis(100),
            ..b
        };
        let t = Instant::now();
        let err = b
            .run("TCPIP::x::SOCKET", async {
                tokio::time::sleep(Duration::from_secs(30)).await;
                anyhow::Ok(())
            })
            .await
            .unwrap_err();
        assert!(t.elapsed() < Duration::from_secs(5));
        let c = err.downcast_ref::<Classified>().unwrap();
        assert_eq!(c.class, ExitClass::Instrument);
        assert!(
            c.message.contains("gave up after 0.1 s in all"),
            "{}",
            c.message
        );
        let ok = b.run("x", async { anyhow::Ok(7) }).await.unwrap();
        assert_eq!(ok, 7);
    }
}
