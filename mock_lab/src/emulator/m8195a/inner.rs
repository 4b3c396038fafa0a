//! The emulator's state behind its lock: the instrument's settings and memory, the IEEE 488.2
//! registers and error queue, and what a test made this unit answer instead of the catalog. A file
//! of its own so that the command table and its handlers need not import their parent.

use super::state::{AwgState, Playback};
use crate::emulator::scpi::error_queue::ErrorQueue;

/// The M8195A's mutable state (one lock for a whole message).
pub(super) struct Inner {
    pub(super) state: AwgState,
    pub(super) errors: ErrorQueue,
    pub(super) esr: u8,
    pub(super) ese: u8,
    pub(super) sre: u8,
    /// What `*OPT?` answers instead of the catalog's options (a unit with other options).
    pub(super) options: Option<Vec<String>>,
    /// What `:FREQ:RAST? MAX` answers instead of the catalog's limit (another unit).
    pub(super) raster_max: Option<f64>,
    /// What the AWG plays, as last built: the scope asks every few milliseconds while it waits
    /// for a trigger, and building it copies the selected segments (megabytes). Cleared by every
    /// message, the only way the state changes.
    pub(super) playback: Option<Playback>,
}
