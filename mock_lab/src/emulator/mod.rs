//! Instrument emulators: state machines behind the protocol servers.

pub mod common;
pub mod gotmic;
pub mod lecroy;
pub mod loopback;
pub mod m8195a;
