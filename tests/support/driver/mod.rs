//! What the driver tests share: catalog models, bounded waits, a bench of shared drivers under
//! the safe state, and the AWG's safe-state command sequence.
#![allow(dead_code)]

use std::time::Duration;

use radbench::catalog::{Catalog, InstrumentModel};
use radbench::driver::ERROR_CHECK;
use radbench::driver::{share, Bench, Shared};
use radbench::driver::{Awg, RfFrontEnd, SafeState};

/// Every wait in the driver tests is bounded by this.
pub const LIMIT: Duration = Duration::from_secs(60);

/// What the M8195A driver sends for the safe state: every output off, `:ABOR`, the error queue.
pub const AWG_SAFE_STATE: [&str; 6] = [
    ":OUTP1 OFF",
    ":OUTP2 OFF",
    ":OUTP3 OFF",
    ":OUTP4 OFF",
    ":ABOR",
    ERROR_CHECK,
];

pub async fn bounded<T>(f: impl std::future::Future<Output = T>) -> T {
    tokio::time::timeout(LIMIT, f)
        .await
        .expect("operation did not finish within the test's time limit")
}

/// A built-in catalog model.
pub fn model(key: &str) -> InstrumentModel {
    Catalog::embedded().unwrap().get(key).unwrap().clone()
}

/// An AWG and a transmitter, shared, under one safe state (5 s per step).
pub fn guarded(
    awg: Box<dyn Awg>,
    tx: Option<Box<dyn RfFrontEnd>>,
) -> (SafeState, Shared<dyn Awg>, Option<Shared<dyn RfFrontEnd>>) {
    let awg = share(awg);
    let tx = tx.map(share);
    let safe = SafeState::new(
        Bench {
            tx: tx.clone(),
            rx: None,
            awg: Some(awg.clone()),
        },
        Duration::from_secs(5),
    );
    (safe, awg, tx)
}
