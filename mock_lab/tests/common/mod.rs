//! Helpers shared by the server tests: bounded waits, a loopback instrument, a chunked reader.
#![allow(dead_code)]

use std::future::Future;
use std::sync::Arc;
use std::time::Duration;

use mock_lab::emulator::loopback::Loopback;
use mock_lab::faults::Faults;
use mock_lab::server::{Handler, ServerOptions};

/// Every wait in these tests is bounded by this.
pub const LIMIT: Duration = Duration::from_secs(20);

/// Awaits `fut`, failing the test if it takes longer than [`LIMIT`].
pub async fn bounded<T>(fut: impl Future<Output = T>) -> T {
    tokio::time::timeout(LIMIT, fut)
        .await
        .expect("operation did not finish within the test's time limit")
}

/// A fresh loopback instrument and server options with their own faults.
pub fn instrument() -> (Arc<dyn Handler>, ServerOptions, Arc<Faults>) {
    let faults = Faults::new();
    let handler: Arc<dyn Handler> = Arc::new(Loopback::new());
    (handler, ServerOptions::with_faults(faults.clone()), faults)
}

/// The loopback's `DATA:GEN` bytes, to check blocks end to end.
pub fn expected_block(len: usize, seed: u64) -> Vec<u8> {
    mock_lab::emulator::loopback::pseudo_random_bytes(len, seed)
}

/// IEEE 488.2 definite block header for `len` bytes.
pub fn block_header(len: usize) -> Vec<u8> {
    let digits = len.to_string();
    format!("#{}{}", digits.len(), digits).into_bytes()
}
