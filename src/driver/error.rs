//! The driver layer's error: values refused before anything was sent (catalog limits), instrument
//! refusals and link failures (from the session), and replies the driver could not make sense of.

use crate::exit::{Classify, ExitClass};
use crate::session::SessionError;
use crate::transport::ErrorKind;

#[derive(Debug, thiserror::Error)]
pub enum DriverError {
    /// A value outside the instrument's catalog limits; nothing was sent.
    #[error("{instrument}: {parameter} = {value} is not allowed: {allowed} (nothing was sent)")]
    Limit {
        instrument: &'static str,
        parameter: &'static str,
        value: String,
        allowed: String,
    },
    /// The catalog entry lacks what this driver needs.
    #[error("{instrument}: the catalog entry `{key}` has no {what}; use the built-in instruments/ file or add it")]
    Catalog {
        instrument: &'static str,
        key: String,
        what: &'static str,
    },
    /// `*IDN?` named a different instrument.
    #[error("{instrument}: *IDN? answered {idn:?}, which is not a {expected}; check the resource string")]
    WrongInstrument {
        instrument: &'static str,
        expected: String,
        idn: String,
    },
    /// The session failed: the instrument refused (device errors with code and text) or the link failed.
    #[error(transparent)]
    Session(#[from] SessionError),
    /// A module of the line protocol answered `ERR <code> <text>`.
    #[error("{instrument}: `{request}` was refused: ERR {code} {text}")]
    Refused {
        instrument: &'static str,
        request: String,
        code: u8,
        text: String,
    },
    /// A reply that does not follow the protocol.
    #[error("{instrument}: the reply to `{request}` is not {expected}: {reply:?}")]
    BadReply {
        instrument: &'static str,
        request: String,
        expected: &'static str,
        reply: String,
    },
    /// A read-back differs from what was written.
    #[error("{instrument}: {what} reads back {got}, expected {expected}")]
    Readback {
        instrument: &'static str,
        what: String,
        expected: String,
        got: String,
    },
    /// No trigger edge arrived while the acquisition was armed.
    #[error("{instrument}: no trigger within {waited:?}; check that the AWG runs with its marker output on and wired to the scope's EXT input, and the trigger level")]
    NoTrigger {
        instrument: &'static str,
        waited: std::time::Duration,
    },
    /// The instrument does not answer over this protocol (remote-interface setting).
    #[error("{instrument} at {resource}: {detail}")]
    RemoteInterface {
        instrument: &'static str,
        resource: String,
        detail: String,
    },
}

impl DriverError {
    /// Retry, abort or fix the input.
    pub fn kind(&self) -> ErrorKind {
        match self {
            DriverError::Limit { .. } | DriverError::Catalog { .. } => ErrorKind::FixInput,
            DriverError::Session(e) => e.kind(),
            DriverError::WrongInstrument { .. }
            | DriverError::Refused { .. }
            | DriverError::BadReply { .. }
            | DriverError::Readback { .. }
            | DriverError::RemoteInterface { .. } => ErrorKind::Abort,
            DriverError::NoTrigger { .. } => ErrorKind::Retry,
        }
    }
}

impl Classify for DriverError {
    fn exit_class(&self) -> ExitClass {
        match self {
            DriverError::Limit { .. } | DriverError::Catalog { .. } => ExitClass::BadInput,
            DriverError::Session(e) => e.exit_class(),
            _ => ExitClass::Instrument,
        }
    }
}
