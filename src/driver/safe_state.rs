//! The bench's safe state, on every exit path (architecture rule 9).
//!
//! [`SafeState`] holds shared handles to the bench's drivers and runs the sequence
//! **Tx RF off, Rx off, AWG outputs off, `:ABOR`**, the three instruments at once (each on its
//! own link, so a silent one does not keep the others on for its timeout). Every step is tried
//! even when another fails, each within a bounded time, and the [`SafeStateReport`] says what
//! happened, in that order.
//!
//! How each exit path reaches it:
//! * normal end and errors: `guard.engage().await` (or `state.engage().await`);
//! * Ctrl-C: [`run_guarded`] races the measurement against the interrupt (the CLI passes
//!   `tokio::signal::ctrl_c()`), drops the measurement future (releasing the driver locks) and
//!   awaits [`SafeState::engage`];
//! * panic: [`install_panic_hook`] makes a quick attempt from the hook (skipping drivers whose lock
//!   the panicking code still holds), and the [`SafeStateGuard`] dropped during unwinding runs the
//!   sequence again once those locks are released;
//! * a guard dropped without [`SafeStateGuard::engage`]: best-effort synchronous run on drop.
//!
//! The synchronous path ([`SafeState::engage_blocking`]) needs a multi-thread tokio runtime to
//! drive the network links while it blocks (radbench's `main` uses one). On a current-thread
//! runtime it cannot block without deadlocking, so it schedules the sequence as a task instead and
//! says so in the report.

use std::sync::Arc;
use std::time::Duration;

use tokio::runtime::{Handle, RuntimeFlavor};
use tokio::sync::Mutex;

use super::capability::{Awg, RfFrontEnd};
use super::safe_report::{SafeStateReport, SafeStep};

/// A driver shared between the measurement and the safe state.
pub type Shared<T> = Arc<Mutex<Box<T>>>;

/// Wraps a driver for sharing.
pub fn share<T: ?Sized>(driver: Box<T>) -> Shared<T> {
    Arc::new(Mutex::new(driver))
}

/// The bench's drivers, as far as the safe state needs them.
#[derive(Default)]
pub struct Bench {
    pub tx: Option<Shared<dyn RfFrontEnd>>,
    pub rx: Option<Shared<dyn RfFrontEnd>>,
    pub awg: Option<Shared<dyn Awg>>,
}

struct Inner {
    bench: Bench,
    step_timeout: Duration,
    runtime: Option<Handle>,
}

/// Runs the safe-state sequence; cheap to clone (the CLI gives one to its Ctrl-C handler and its
/// panic hook).
#[derive(Clone)]
pub struct SafeState {
    inner: Arc<Inner>,
}

/// How long the panic hook waits for a driver lock before leaving that driver to the guard.
const HOOK_LOCK_WAIT: Duration = Duration::from_millis(200);

impl SafeState {
    /// `step_timeout` bounds each step (lock and commands). Call inside the tokio runtime that
    /// runs the drivers, so the synchronous fallback can use it.
    pub fn new(bench: Bench, step_timeout: Duration) -> SafeState {
        SafeState {
            inner: Arc::new(Inner {
                bench,
                step_timeout,
                runtime: Handle::try_current().ok(),
            }),
        }
    }

    /// A guard that runs the sequence when dropped unless [`SafeStateGuard::engage`] ran it.
    pub fn guard(&self) -> SafeStateGuard {
        SafeStateGuard {
            state: self.clone(),
            pending: true,
        }
    }

    /// Runs the sequence: Tx RF off, Rx off, AWG outputs off and `:ABOR`.
    pub async fn engage(&self) -> SafeStateReport {
        self.run(self.inner.step_timeout).await
    }

    async fn run<'a>(&'a self, lock_wait: Duration) -> SafeStateReport {
        let b = &self.inner.bench;
        let limit = self.inner.step_timeout;
        // Each instrument has its own link: all three start at once, so a slow or silent one
        // does not keep the others on for its timeout. The report keeps the sequence's order.
        let front_off = |step: &'static str, rf: &'a Option<Shared<dyn RfFrontEnd>>| async move {
            match rf {
                Some(rf) => Some(SafeStep {
                    step,
                    error: step_result(limit, lock_wait, rf, |d| d.disable()).await,
                }),
                None => None,
            }
        };
        let awg_off = async {
            match &b.awg {
                Some(awg) => Some(SafeStep {
                    step: "AWG outputs off and :ABOR",
                    error: step_result(limit, lock_wait, awg, |d| d.safe_state()).await,
                }),
                None => None,
            }
        };
        let (tx, rx, awg) = tokio::join!(
            front_off("Tx RF off", &b.tx),
            front_off("Rx off", &b.rx),
            awg_off
        );
        let report = SafeStateReport {
            steps: [tx, rx, awg].into_iter().flatten().collect(),
        };
        if report.is_safe() {
            tracing::info!("safe state: {report}");
        } else {
            tracing::error!("safe state incomplete: {report}; switch the bench off by hand");
        }
        report
    }

    /// The sequence from synchronous code (drop, panic hook). See the module docs for when it can
    /// block and when it can only schedule.
    pub fn engage_blocking(&self) -> SafeStateReport {
        self.blocking(self.inner.step_timeout)
    }

    fn blocking(&self, lock_wait: Duration) -> SafeStateReport {
        let this = self.clone();
        match Handle::try_current() {
            Ok(h) if h.runtime_flavor() == RuntimeFlavor::MultiThread => {
                tokio::task::block_in_place(|| h.block_on(this.run(lock_wait)))
            }
            Ok(h) => {
                h.spawn(async move { this.run(lock_wait).await });
                scheduled_only(
                    "the current-thread runtime cannot block; the sequence was scheduled as a task",
                )
            }
            Err(_) => match self.inner.runtime.clone() {
                Some(h) => {
                    let total = self.inner.step_timeout * 4 + Duration::from_secs(1);
                    let (tx, rx) = std::sync::mpsc::channel();
                    let spawned = std::thread::Builder::new()
                        .name("radbench safe state".into())
                        .spawn(move || {
                            let _ = tx.send(h.block_on(this.run(lock_wait)));
                        });
                    match spawned {
                        Ok(_) => rx.recv_timeout(total).unwrap_or_else(|_| {
                            scheduled_only("the sequence did not finish in time (is the runtime still running?)")
                        }),
                        Err(e) => scheduled_only(&format!("cannot start a thread: {e}")),
                    }
                }
                None => scheduled_only("no tokio runtime to drive the instrument links"),
            },
        }
    }
}

fn scheduled_only(why: &str) -> SafeStateReport {
    tracing::warn!("safe state: {why}");
    SafeStateReport {
        steps: vec![SafeStep {
            step: "synchronous safe state",
            error: Some(why.to_string()),
        }],
    }
}

async fn step_result<T: ?Sized + Send>(
    limit: Duration,
    lock_wait: Duration,
    driver: &Shared<T>,
    op: impl for<'a> FnOnce(
        &'a mut Box<T>,
    ) -> super::io::BoxFuture<'a, Result<(), super::error::DriverError>>,
) -> Option<String> {
    let mut guard = match tokio::time::timeout(lock_wait, driver.lock()).await {
        Ok(g) => g,
        Err(_) => {
            return Some(format!(
                "the driver stayed busy for {} (another operation holds it)",
                crate::transport::Rounded(lock_wait)
            ))
        }
    };
    match tokio::time::timeout(limit, op(&mut guard)).await {
        Ok(Ok(())) => None,
        Ok(Err(e)) => Some(e.to_string()),
        Err(_) => Some(format!(
            "no answer within {}",
            crate::transport::Rounded(limit)
        )),
    }
}

/// Runs the safe state when dropped, unless it was run explicitly.
pub struct SafeStateGuard {
    state: SafeState,
    pending: bool,
}

impl SafeStateGuard {
    /// Runs the sequence now (the normal way to end a measurement, successful or not).
    pub async fn engage(mut self) -> SafeStateReport {
        self.pending = false;
        self.state.engage().await
    }
}

impl Drop for SafeStateGuard {
    fn drop(&mut self) {
        if self.pending {
            tracing::warn!(
                "safe-state guard dropped without an explicit safe state; running it now"
            );
            let report = self.state.engage_blocking();
            if !report.is_safe() {
                eprintln!("radbench: safe state on exit: {report}");
            }
        }
    }
}

/// How a guarded measurement ended.
#[derive(Debug)]
pub enum Outcome<T> {
    /// The work ran to completion (successfully or with its own error).
    Finished(T),
    /// The interrupt fired first; the work was dropped where it stood.
    Interrupted,
}

/// Runs `work` until it finishes or `interrupt` fires (the CLI passes `tokio::signal::ctrl_c()`),
/// then runs the safe state in either case. Dropping the work releases the driver locks it held,
/// so the safe state can take them; a link left mid-message is cleared or reopened by the
/// transport before the safe-state commands go out.
pub async fn run_guarded<T, I>(
    state: &SafeState,
    work: impl std::future::Future<Output = T>,
    interrupt: impl std::future::Future<Output = I>,
) -> (Outcome<T>, SafeStateReport) {
    let guard = state.guard();
    let outcome = tokio::select! {
        value = work => Outcome::Finished(value),
        _ = interrupt => {
            tracing::warn!("interrupted: putting the bench in its safe state");
            Outcome::Interrupted
        }
    };
    let report = guard.engage().await;
    (outcome, report)
}

/// The safe state the process-wide panic hook engages (see [`set_panic_safe_state`]).
static PANIC_SAFE_STATE: std::sync::Mutex<Option<SafeState>> = std::sync::Mutex::new(None);

/// Makes a panic run the safe state of the bench connected last (quick attempt; the guard
/// retries during unwinding), then the previous hook. One hook per process: a program that
/// connects again and again (a campaign starts a fresh simulated lab for each step) replaces the
/// state the hook engages instead of piling up hooks that keep old connections alive.
pub(crate) fn set_panic_safe_state(state: SafeState) {
    static INSTALL: std::sync::Once = std::sync::Once::new();
    *PANIC_SAFE_STATE.lock().unwrap_or_else(|p| p.into_inner()) = Some(state);
    INSTALL.call_once(|| {
        let previous = std::panic::take_hook();
        std::panic::set_hook(Box::new(move |info| {
            // try_lock: a panic while the slot is being replaced must not deadlock the hook.
            let state = match PANIC_SAFE_STATE.try_lock() {
                Ok(g) => g.clone(),
                Err(std::sync::TryLockError::Poisoned(p)) => p.into_inner().clone(),
                Err(std::sync::TryLockError::WouldBlock) => None,
            };
            if let Some(state) = state {
                let report = state.blocking(HOOK_LOCK_WAIT);
                eprintln!("radbench: panic: safe state: {report}");
            }
            previous(info);
        }));
    });
}

/// Forgets `state` in the panic hook when it is the one the hook would engage (its bench is being
/// closed: the hook must not keep its connections, e.g. a serial port, open).
pub(crate) fn clear_panic_safe_state(state: &SafeState) {
    let mut slot = PANIC_SAFE_STATE.lock().unwrap_or_else(|p| p.into_inner());
    if slot
        .as_ref()
        .is_some_and(|s| Arc::ptr_eq(&s.inner, &state.inner))
    {
        *slot = None;
    }
}

/// Makes a panic run the safe state (quick attempt; the guard retries during unwinding), then
/// the previous hook.
pub fn install_panic_hook(state: SafeState) {
    let previous = std::panic::take_hook();
    std::panic::set_hook(Box::new(move |info| {
        let report = state.blocking(HOOK_LOCK_WAIT);
        eprintln!("radbench: panic: safe state: {report}");
        previous(info);
    }));
}
