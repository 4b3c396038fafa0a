//! The signals that stop a measurement: SIGINT (Ctrl-C), SIGTERM and SIGHUP.
//!
//! `Interrupt::listen` replaces the default action of the three signals for the rest of the
//! process: a signal no longer kills radbench mid-capture but is recorded, the measurement's guard
//! puts the bench in its safe state, files already captured are finished, and the command exits
//! with the signal's code (130, 143, 129).

use std::sync::atomic::{AtomicU8, Ordering};
use std::sync::Arc;
use tokio::sync::watch;

/// A stop signal.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum StopSignal {
    Interrupt,
    Terminate,
    HangUp,
}

impl StopSignal {
    pub fn name(self) -> &'static str {
        match self {
            StopSignal::Interrupt => "SIGINT",
            StopSignal::Terminate => "SIGTERM",
            StopSignal::HangUp => "SIGHUP",
        }
    }

    fn code(self) -> u8 {
        match self {
            StopSignal::Interrupt => 1,
            StopSignal::Terminate => 2,
            StopSignal::HangUp => 3,
        }
    }

    fn from_code(code: u8) -> Option<StopSignal> {
        match code {
            1 => Some(StopSignal::Interrupt),
            2 => Some(StopSignal::Terminate),
            3 => Some(StopSignal::HangUp),
            _ => None,
        }
    }
}

/// Listens for the stop signals; cheap to clone.
#[derive(Clone)]
pub struct Interrupt {
    received: Arc<AtomicU8>,
    changed: watch::Receiver<u8>,
    /// Raises a stop from inside the process (the live view's Stop button).
    raise: Arc<watch::Sender<u8>>,
}

impl Interrupt {
    /// Starts listening (inside a tokio runtime). Fails only when the signal handlers cannot be
    /// installed.
    pub fn listen() -> std::io::Result<Interrupt> {
        use tokio::signal::unix::{signal, SignalKind};
        let mut int = signal(SignalKind::interrupt())?;
        let mut term = signal(SignalKind::terminate())?;
        let mut hup = signal(SignalKind::hangup())?;
        let received = Arc::new(AtomicU8::new(0));
        let (tx, rx) = watch::channel(0u8);
        let tx = Arc::new(tx);
        let raise = tx.clone();
        let flag = received.clone();
        tokio::spawn(async move {
            loop {
                let s = tokio::select! {
                    Some(()) = int.recv() => StopSignal::Interrupt,
                    Some(()) = term.recv() => StopSignal::Terminate,
                    Some(()) = hup.recv() => StopSignal::HangUp,
                    else => break,
                };
                // The first signal decides the exit code; later ones only repeat the request.
                let _ = flag.compare_exchange(0, s.code(), Ordering::SeqCst, Ordering::SeqCst);
                let _ = tx.send(s.code());
            }
        });
        Ok(Interrupt {
            received,
            changed: rx,
            raise,
        })
    }

    /// An interrupt that never fires (library callers without signals, tests).
    pub fn never() -> Interrupt {
        let (tx, rx) = watch::channel(0u8);
        // The interrupt holds its sender, so `wait` pends instead of ending.
        Interrupt {
            received: Arc::new(AtomicU8::new(0)),
            changed: rx,
            raise: Arc::new(tx),
        }
    }

    /// Stops the measurement exactly as the signal `s` would (the live view's Stop button raises
    /// SIGINT's stop: safe state first, the files finished, a campaign left resumable, exit 130).
    pub fn raise(&self, s: StopSignal) {
        let _ = self
            .received
            .compare_exchange(0, s.code(), Ordering::SeqCst, Ordering::SeqCst);
        let _ = self.raise.send(s.code());
    }

    /// The first stop signal received so far.
    pub fn received(&self) -> Option<StopSignal> {
        StopSignal::from_code(self.received.load(Ordering::SeqCst))
    }

    /// Resolves when a stop signal arrives (at once when one already did).
    pub async fn wait(&self) -> StopSignal {
        let mut rx = self.changed.clone();
        loop {
            if let Some(s) = self.received() {
                return s;
            }
            if rx.changed().await.is_err() {
                // The listener task ended: no signal can come any more.
                std::future::pending::<()>().await;
            }
        }
    }
}
