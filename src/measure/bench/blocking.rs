//! Heavy, synchronous work (DSP, file writing) run off the async runtime's workers.

use crate::measure::error::MeasureError;

/// Runs heavy, synchronous work (DSP, file writing) off the async runtime's workers.
pub(crate) async fn off_runtime<T, F>(work: F) -> Result<T, MeasureError>
where
    F: FnOnce() -> T + Send + 'static,
    T: Send + 'static,
{
    tokio::task::spawn_blocking(work)
        .await
        .map_err(|e| MeasureError::Worker(e.to_string()))
}
