//! Instrument emulators: state machines behind the protocol servers.
//!
//! `SCOPES` is the one table of the scopes the lab can serve as `scope` (`--scope-model`, a
//! campaign's `[bench] scope_model`): each one's name, catalog key, transports and emulator.
//! Adding a scope family: its folder here, one `pub mod` line and one row in `SCOPES`. Its rows
//! are public as [`crate::lab::ScopeModel::ALL`].

pub mod gotmic;
pub mod keysight_uxr;
pub mod lecroy;
pub mod loopback;
pub mod m8195a;
pub(crate) mod received_log;
pub(crate) mod scpi;

use crate::lab::{ScopeEmulator, ScopeModel};
use crate::server::launch::Transport;
use std::sync::Arc;

/// Every scope the lab can serve, the default first. The first transport of each is the one
/// radbench's `--scope-transport vicp` (the default) reaches it on.
pub(crate) const SCOPES: [ScopeModel; 2] = [
    ScopeModel {
        name: "lecroy",
        catalog_key: "lecroy-labmaster10zi-a",
        about: "Teledyne LeCroy LabMaster 10 Zi-A (VICP or VXI-11), saves `.trc` files beside the \
                SigMF",
        transports: &[Transport::Vicp, Transport::Vxi11],
        emulator: ScopeEmulator::BenchLecroy,
    },
    ScopeModel {
        name: "keysight-uxr",
        catalog_key: "keysight-uxr0334a",
        about: "Keysight Infiniium UXR0334A (HiSLIP or VXI-11), saves the SigMF recording only",
        transports: &[Transport::Hislip, Transport::Vxi11],
        emulator: ScopeEmulator::Build(|source| {
            Ok(Arc::new(keysight_uxr::KeysightUxr::embedded_with(source)?))
        }),
    },
];
