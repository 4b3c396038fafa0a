//! Instrument emulators: state machines behind the protocol servers.
