//! What the drivers last did to the bench's RF, per instrument, for the live view: an instrument
//! counts as on from the moment its driver sends the enable (before the read-back confirms it)
//! until a switch-off it sent succeeded. Nothing is asked of the instruments for it.

use std::collections::BTreeMap;
use std::sync::Mutex;

static STATE: Mutex<BTreeMap<String, bool>> = Mutex::new(BTreeMap::new());

/// Records that `instrument`'s driver switched RF (or the AWG's outputs) on or off.
pub(crate) fn set(instrument: &str, on: bool) {
    let mut state = STATE.lock().unwrap_or_else(|p| p.into_inner());
    state.insert(instrument.to_string(), on);
}

/// Records that `instrument` is connected (off until its driver says otherwise).
pub(crate) fn connected(instrument: &str) {
    let mut state = STATE.lock().unwrap_or_else(|p| p.into_inner());
    state.entry(instrument.to_string()).or_insert(false);
}

/// Every instrument a driver connected or switched in this process, and whether it is on.
pub fn snapshot() -> Vec<(String, bool)> {
    let state = STATE.lock().unwrap_or_else(|p| p.into_inner());
    state.iter().map(|(k, v)| (k.clone(), *v)).collect()
}
