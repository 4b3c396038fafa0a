//! Instrument emulators: state machines behind the protocol servers.

pub mod gotmic;
pub mod keysight_uxr;
pub mod lecroy;
pub mod loopback;
pub mod m8195a;
pub(crate) mod received_log;
pub(crate) mod scpi;
