//! Layer 3: capability traits (AWG, digitizer, RF front end) and the concrete drivers.
//!
//! | module | what it holds |
//! |---|---|
//! | [`capability`] | the traits [`Awg`], [`Digitizer`], [`RfFrontEnd`] and their plain-data settings |
//! | [`io`] | [`InstrumentIo`]: what drivers need from a session, implemented by `Session` |
//! | [`scripted`] | [`Scripted`]: a fake session for tests that pin exact command sequences |
//! | [`m8195a`] | Keysight M8195A: DCM I/Q + marker, 64 GSa/s / 4, chunked download |
//! | [`lecroy`] | Teledyne LeCroy over VICP or VXI-11: marker-triggered single shot, WAVEDESC, `.trc` |
//! | [`gotmic`] | Gotmic E-band Tx/Rx over serial (project-defined protocol, register map from the catalog) |
//! | [`permit`] | [`RfPermit`]: outputs and RF only with the user's explicit decision |
//! | [`safe_state`] | the safe-state sequence on every exit path |
//! | [`error`] | [`DriverError`] with `kind()` and its exit class |
//!
//! Rules every driver keeps: command spellings in one `commands.rs`; settings checked against the
//! catalog before anything is sent; the error queue read after each configuration batch; what the
//! instrument applied read back and reported.

pub mod capability;
pub mod common;
pub mod error;
pub mod gotmic;
pub mod io;
pub mod lecroy;
pub mod m8195a;
pub mod permit;
pub mod safe_state;
pub mod scripted;

pub use capability::{
    Awg, AwgApplied, AwgSettings, Digitizer, DigitizerApplied, DigitizerSettings, IqCapture,
    IqWaveform, LoadedSegment, ReferenceClock, RfFrontEnd, RfSettings, RfStatus, Slope,
};
pub use error::DriverError;
pub use gotmic::Gotmic;
pub use io::{BoxFuture, InstrumentIo};
pub use lecroy::wavedesc::{Trace, TrcError};
pub use lecroy::Lecroy;
pub use m8195a::M8195a;
pub use permit::RfPermit;
pub use safe_state::{
    install_panic_hook, run_guarded, Outcome, SafeState, SafeStateGuard, SafeStateReport,
};
pub use scripted::{ScriptLog, Scripted};
