//! Layer 3: capability traits (AWG, digitizer, RF front end) and the concrete drivers.
//!
//! | module | what it holds |
//! |---|---|
//! | `capability` | the traits [`Awg`], [`Digitizer`], [`RfFrontEnd`] and their plain-data settings |
//! | `io` | [`InstrumentIo`]: what drivers need from a session, implemented by `Session`; session options from the catalog |
//! | `scpi` | [`Scpi`]: send, ask, typed asks, per-call timeouts, the error-queue check after a batch |
//! | `identity` | `*IDN?` checked against the catalog model |
//! | `ask` | one bounded query on a fresh session (`doctor --verify-catalog`) |
//! | `instrument_limits` | the catalog limits `doctor --verify-catalog` reads, per family (`:FREQ:RAST? MAX`, `:TRAC1:FREE?`, `C1:VDIV`, `MSIZ`) |
//! | `limits` | settings checked against the catalog's limits before anything is sent |
//! | `scripted` | `Scripted`: a fake session for tests that pin exact command sequences (feature `testing`) |
//! | `trace` | [`ChannelTrace`]: what a digitizer returns, in no vendor's terms (codes, scaling, timing, segments) |
//! | `fault` | `FaultyIo`: seeded client-side faults (timeouts, lost replies, drops, delays) around any [`InstrumentIo`], for reliability tests (feature `testing`) |
//! | `m8195a` | Keysight M8195A: DCM I/Q + marker, 64 GSa/s / 4, chunked download |
//! | `lecroy` | Teledyne LeCroy over VICP or VXI-11: marker-triggered single shot or sequence, WAVEDESC, `.trc` |
//! | `scope_core` | what every scope driver shares: settings checked against the limits, segment bookkeeping, the `Digitizer` impl around a family's own commands |
//! | `keysight_uxr` | Keysight Infiniium UXR-class over HiSLIP or VXI-11: `:WAVeform` WORD blocks, marker-triggered single shot or segmented memory |
//! | `family` | `DriverFamily`: the closed set of driver families, one table row each (kinds, `[vendor]` check, the doctor's words) |
//! | `open` | instruments opened from data: the catalog's `driver` family to a boxed capability, AWG planning |
//! | `gotmic` | Gotmic E-band Tx/Rx over serial (project-defined protocol, register map from the catalog) |
//! | `permit` | [`RfPermit`]: outputs and RF only with the user's explicit decision |
//! | `safe_state` | the safe-state sequence on every exit path |
//! | `safe_report` | what the sequence did, step by step |
//! | `error` | [`DriverError`] with `kind()` and its exit class |
//!
//! Rules every driver keeps: command spellings in one `commands.rs`; settings checked against the
//! catalog before anything is sent; the error queue read after each configuration batch; what the
//! instrument applied read back and reported.
//!
//! # A measurement, in driver calls
//!
//! ```text
//! let permit = RfPermit::granted_by_user();          // only where the user said --allow-rf
//! let safe = SafeState::new(Bench { tx, rx, awg }, step_timeout);
//! install_panic_hook(safe.clone());
//! run_guarded(&safe, async {
//!     awg.configure(&awg_settings).await?;           // DCM, 64 GSa/s / 4, levels, read-back
//!     awg.load(&iq_waveform).await?;                 // padded, chunked, marker interleaved
//!     scope.configure(&scope_settings).await?;       // WORD format, 80 GSa/s, record, EX trigger
//!     awg.enable_outputs(&permit).await?;
//!     awg.run().await?;                              // :INIT:IMM last
//!     tx.enable(&permit, &rf).await?; rx.enable(&permit, &rf).await?;
//!     scope.capture_iq(wait_s).await                 // I = C1, Q = C2, N segments, .trc kept
//! }, tokio::signal::ctrl_c()).await;                 // then Tx off, Rx off, outputs off, :ABOR
//! ```
//!
//! # Adding an instrument model
//!
//! A model of a known kind (another AWG speaking the M8195A's SCPI, another MAUI scope, a module
//! with the same register protocol) needs only a catalog file: instruments/README.md, "Adding a
//! scope model with data only", walks through one (`tests/io/driver_second_scope.rs` does it). A new
//! command set needs a driver module here (and its family: a variant and its row in `family.rs`,
//! one `match` arm in `open.rs`): a `commands.rs` with every spelling, pure checks against the
//! catalog before any I/O (`limits`; a scope driver's are `scope_core`'s, and it implements only
//! `ScopeFamily`), the session through [`Scpi`], an implementation of the capability trait, tests
//! with `Scripted` (feature `testing`) that pin each operation's command sequence, and tests against its mock_lab
//! emulator (`keysight_uxr` is the worked example).

#![warn(clippy::missing_errors_doc, clippy::missing_panics_doc)]

pub(crate) mod ask;
pub(crate) mod capability;
pub(crate) mod error;
pub(crate) mod family;
#[cfg(any(test, feature = "testing"))]
pub(crate) mod fault;
pub(crate) mod gotmic;
pub(crate) mod identity;
pub(crate) mod instrument_limits;
pub(crate) mod io;
pub(crate) mod keysight_uxr;
pub(crate) mod lecroy;
pub(crate) mod limits;
pub(crate) mod m8195a;
pub(crate) mod open;
pub(crate) mod permit;
pub(crate) mod rf_state;
mod safe_report;
pub(crate) mod safe_state;
pub(crate) mod scope_core;
pub(crate) mod scpi;
#[cfg(any(test, feature = "testing"))]
pub(crate) mod scripted;
pub(crate) mod trace;

pub use gotmic::Framing;
pub use io::{max_message_bytes, open_session, session_options, set_read_timeout};
pub use lecroy::{
    offset, sample_rate, segments, volts_per_div, wavedesc, waveform, COMMAND_ERRORS,
    SEGMENTS_QUERY, STATUS, STOP,
};
pub use rf_state::snapshot;
pub use safe_report::{SafeStateReport, SafeStep};
pub use safe_state::{share, Bench, Shared};
#[cfg(any(test, feature = "testing"))]
pub use scripted::{Failure, DEVICE_CLEAR, ERROR_CHECK};

/// What drivers report and take from the layers below, so callers need not reach past `driver`.
pub use crate::session::Identity;
pub use crate::transport::{ErrorKind, Journal};
pub use crate::trc::TrcError;
pub use capability::{
    Awg, AwgApplied, AwgSettings, Digitizer, DigitizerApplied, DigitizerSettings, IqWaveform,
    LoadedSegment, ReadyToEnable, ReferenceClock, RfFrontEnd, RfSettings, RfStatus, SegmentEntry,
    Slope,
};
pub use error::DriverError;
#[cfg(any(test, feature = "testing"))]
pub use fault::{FaultCounts, FaultPlan, FaultSwitch, FaultyIo};
pub use gotmic::Gotmic;
pub use io::{BoxFuture, InstrumentIo};
pub use keysight_uxr::KeysightUxr;
pub use lecroy::Lecroy;
pub use m8195a::M8195a;
pub use permit::RfPermit;
pub(crate) use safe_state::{clear_panic_safe_state, set_panic_safe_state};
pub use safe_state::{install_panic_hook, run_guarded, Outcome, SafeState, SafeStateGuard};
pub use scpi::Scpi;
#[cfg(any(test, feature = "testing"))]
pub use scripted::{ScriptLog, Scripted};
pub use trace::{ChannelTrace, IqCapture, NativeFile, SegmentTiming};
