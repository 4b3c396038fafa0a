//! How long the doctor may take and how it ends early: each wait is bounded, all of them
//! together by [`CHECKS_TOTAL`] (a [`Deadline`]), and a stop signal outside the marker check ends
//! it with [`stopped`].

use crate::driver::DriverError;
use crate::measure::bench::interrupt::StopSignal;
use crate::measure::error::MeasureError;
use std::time::Duration;

/// Longest wait for one instrument to be reached and identified.
pub(super) const OPEN_TIMEOUT: Duration = Duration::from_secs(5);
/// The most all the checks may take together, whatever the instruments do (a stall after every
/// answer, replies that never end): each wait is cut to what is left of it, and a check that
/// finds nothing left is skipped. The safe state after the marker check is not cut (at most
/// `SAFE_STEP_TIMEOUT` a step). docs/doctor.md.
pub(super) const CHECKS_TOTAL: Duration = Duration::from_secs(40);

/// When the doctor's checks must be done ([`CHECKS_TOTAL`] from the start).
#[derive(Debug, Clone, Copy)]
pub(super) struct Deadline(tokio::time::Instant);

impl Deadline {
    pub(super) fn start() -> Deadline {
        Deadline(tokio::time::Instant::now() + CHECKS_TOTAL)
    }

    /// `wait`, or what is left before the deadline when that is less.
    pub(super) fn bound(self, wait: Duration) -> Duration {
        wait.min(
            self.0
                .saturating_duration_since(tokio::time::Instant::now()),
        )
    }
}

/// An open with a bound: `Err` text when it fails or takes too long.
pub(super) async fn bounded<T>(
    deadline: Deadline,
    work: impl std::future::Future<Output = Result<T, DriverError>>,
) -> Result<T, String> {
    let wait = deadline.bound(OPEN_TIMEOUT);
    match tokio::time::timeout(wait, work).await {
        Ok(Ok(v)) => Ok(v),
        Ok(Err(e)) => Err(e.to_string()),
        Err(_) => Err(format!(
            "no identity within {} s (the link opened but the instrument did not answer)",
            seconds(wait)
        )),
    }
}

/// A wait in seconds as the checklist says it (`5`, `2.5`).
pub(super) fn seconds(wait: Duration) -> String {
    format!("{}", (wait.as_secs_f64() * 10.0).round() / 10.0)
}

/// The doctor stopped by `signal` outside the marker check (whose own guard reports its safe
/// state): nothing is switched on.
pub fn stopped(signal: StopSignal) -> MeasureError {
    MeasureError::Interrupted {
        signal,
        report: "nothing is switched on; the checks after the signal were not run".into(),
    }
}
