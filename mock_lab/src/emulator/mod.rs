//! Instrument emulators: state machines behind the protocol servers.
//!
//! `scopes::SCOPES` is the one table of the scopes the lab can serve as `scope` (`--scope-model`, a
//! campaign's `[bench] scope_model`): each one's name, catalog key, transports and emulator.
//! Adding a scope family: its folder here, one `pub mod` line and one row in `SCOPES`. Its rows
//! are public as [`crate::lab::ScopeModel::ALL`].

pub mod gotmic;
pub mod keysight_uxr;
pub mod lecroy;
pub mod loopback;
pub mod m8195a;
pub(crate) mod received_log;
pub(crate) mod scopes;
pub(crate) mod scpi;
