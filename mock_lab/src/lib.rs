//! mock_lab: a simulated 80 GHz radar bench that speaks the real wire protocols.
//!
//! It shares no code with radbench on purpose: two independent implementations of each protocol
//! catch the mistakes shared code would hide. Both read the instrument facts in `instruments/`.
//!
//! | module | what it holds |
//! |---|---|
//! | [`bench`](mod@bench) | the emulators wired together: AWG marker -> scope trigger, AWG -> Tx -> scene -> Rx -> scope |
//! | [`catalog`] | its own reader of the instrument files in `instruments/` (limits, identities, registers) |
//! | [`server`] | protocol servers: raw socket, VXI-11 (+ portmapper), HiSLIP, VICP, serial pty |
//! | `control` | the scene control channel (JSON lines): move, add, remove targets, change SNR |
//! | [`emulator`] | instrument state machines: M8195A, LeCroy scope, Gotmic Tx/Rx |
//! | [`faults`] | injected faults: delays, 1-byte segments, dropped connections, missing replies |
//! | [`lab`] | the whole simulated lab on 127.0.0.1: every instrument on its transports, plus the control channel |
//! | [`scene`] | the physics: what the scope sees given the AWG, the front ends and the targets |

#![warn(unreachable_pub)]

pub mod bench;
pub mod catalog;
pub(crate) mod control;
pub mod emulator;
pub mod faults;
pub mod lab;
pub mod offline;
pub mod scene;
pub mod server;
