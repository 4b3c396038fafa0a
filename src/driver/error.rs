//! The driver layer's error: what went wrong with an instrument, kept apart by cause so the caller
//! knows whether to fix the settings (exit 2), look at the bench (exit 3), or retry.

use crate::exit::{Classify, ExitClass};
use crate::session::{DeviceError, ErrorList, SessionError};
use crate::transport::ErrorKind;

use crate::trc::TrcError;

/// Everything a driver operation can fail with.
#[derive(Debug, thiserror::Error)]
pub enum DriverError {
    /// A setting outside the catalog's limits; nothing was sent to the instrument.
    #[error("{instrument}: `{field}` = {value} is outside the limits of the catalog ({allowed}); nothing was sent to the instrument")]
    OutOfLimits {
        instrument: String,
        field: &'static str,
        value: String,
        allowed: String,
    },
    /// Settings or data that make no sense whatever the instrument (empty waveform, I/Q lengths
    /// that differ, ...); nothing was sent.
    #[error("{instrument}: `{field}`: {reason}")]
    BadSettings {
        instrument: String,
        field: &'static str,
        reason: String,
    },
    /// The catalog model lacks what this driver needs (a section, a DAC mode, a register).
    #[error("instrument catalog model `{key}`: {reason}; fix the instrument file (see instruments/README.md)")]
    Catalog { key: String, reason: String },
    /// The instrument's error queue held entries after a batch of commands (code and text as the
    /// instrument gave them).
    #[error("{instrument} refused {batch}: {}", ErrorList(.errors))]
    Refused {
        instrument: String,
        batch: String,
        errors: Vec<DeviceError>,
    },
    /// A line-protocol module answered `ERR <code> <text>`.
    #[error("{instrument} refused `{request}`: ERR {code} {text}")]
    LineRefused {
        instrument: String,
        request: String,
        code: i32,
        text: String,
    },
    /// The session failed: the link broke, timed out, or a reply could not be parsed.
    #[error("{instrument}: {source}")]
    Session {
        instrument: String,
        #[source]
        source: Box<SessionError>,
    },
    /// The instrument answered something this driver cannot interpret.
    #[error("{instrument}: the reply to `{command}` is not {expected}: {reply:?}")]
    Reply {
        instrument: String,
        command: String,
        expected: &'static str,
        reply: String,
    },
    /// The instrument accepted a setting but applied something else.
    #[error("{instrument}: asked for {setting} = {wanted}, the instrument applied {applied}")]
    NotApplied {
        instrument: String,
        setting: &'static str,
        wanted: String,
        applied: String,
    },
    /// The `*IDN?` reply is not the model the bench file names.
    #[error("{resource} answers `*IDN?` with `{idn}`, which is not a {expected}; check the resource string in the bench file")]
    WrongInstrument {
        resource: String,
        expected: String,
        idn: String,
    },
    /// The scope does not answer on this protocol; it is most likely set to the other one.
    #[error("{resource}: no answer over {protocol} ({source}); the scope's remote interface is probably set to {other}: change Utilities > Utilities Setup > Remote to {protocol}, or use the {other} resource string")]
    RemoteInterface {
        resource: String,
        protocol: &'static str,
        other: &'static str,
        #[source]
        source: Box<SessionError>,
    },
    /// The single acquisition did not complete.
    #[error("no marker edge: check the AWG runs and its marker output is on ({instrument} waited {waited_s} s for a trigger on {source_name})")]
    NoTrigger {
        instrument: String,
        source_name: String,
        waited_s: f64,
    },
    /// A waveform block that cannot be decoded.
    #[error("{instrument}: channel C{channel}: {source}")]
    Waveform {
        instrument: String,
        channel: u8,
        #[source]
        source: TrcError,
    },
    /// An RF module is not in a state that allows what was asked (interlock open, faults latched,
    /// LO not locked, over temperature).
    #[error("{instrument}: {reason}")]
    RfNotReady { instrument: String, reason: String },
    /// A register write did not stick.
    #[error("{instrument}: wrote {register} = 0x{wrote:04X}, read back 0x{read:04X}; the module did not apply it")]
    VerifyFailed {
        instrument: String,
        register: String,
        wrote: u16,
        read: u16,
    },
    /// Operations called in an order the driver cannot serve (a program error, not a user one).
    #[error("{instrument}: {what}")]
    Sequence { instrument: String, what: String },
}

/// Wraps a session error with the instrument's name: `.map_err(session(name))`.
pub(crate) fn session(instrument: &str) -> impl Fn(SessionError) -> DriverError + '_ {
    move |source| DriverError::Session {
        instrument: instrument.to_string(),
        source: Box::new(source),
    }
}

impl DriverError {
    /// Retry, abort, or fix the input.
    pub fn kind(&self) -> ErrorKind {
        self.classes().0
    }

    /// What to do about it and the exit code it gives: one table for both.
    fn classes(&self) -> (ErrorKind, ExitClass) {
        match self {
            DriverError::OutOfLimits { .. }
            | DriverError::BadSettings { .. }
            | DriverError::Catalog { .. } => (ErrorKind::FixInput, ExitClass::BadInput),
            DriverError::WrongInstrument { .. } => (ErrorKind::FixInput, ExitClass::Instrument),
            DriverError::Sequence { .. } => (ErrorKind::FixInput, ExitClass::Internal),
            DriverError::Refused { errors, .. } => {
                let kind = if errors.iter().all(|e| e.kind() == ErrorKind::FixInput) {
                    ErrorKind::FixInput
                } else {
                    ErrorKind::Abort
                };
                (kind, ExitClass::Instrument)
            }
            DriverError::Session { source, .. } => (source.kind(), source.exit_class()),
            DriverError::NoTrigger { .. } => (ErrorKind::Retry, ExitClass::Instrument),
            DriverError::LineRefused { .. }
            | DriverError::Reply { .. }
            | DriverError::NotApplied { .. }
            | DriverError::RemoteInterface { .. }
            | DriverError::Waveform { .. }
            | DriverError::RfNotReady { .. }
            | DriverError::VerifyFailed { .. } => (ErrorKind::Abort, ExitClass::Instrument),
        }
    }

    /// The instrument's own error entries (code and text), when it refused something.
    pub fn device_errors(&self) -> Option<&[DeviceError]> {
        match self {
            DriverError::Refused { errors, .. } => Some(errors),
            DriverError::Session { source, .. } => source.device_errors(),
            _ => None,
        }
    }
}

impl Classify for DriverError {
    fn exit_class(&self) -> ExitClass {
        self.classes().1
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn settings_errors_are_bad_input_and_refusals_are_instrument_failures() {
        let limits = DriverError::OutOfLimits {
            instrument: "awg".into(),
            field: "sample_rate_hz",
            value: "2e10".into(),
            allowed: "13.44e9..=16.25e9".into(),
        };
        assert_eq!(limits.exit_class(), ExitClass::BadInput);
        assert_eq!(limits.kind(), ErrorKind::FixInput);
        assert!(limits.to_string().contains("nothing was sent"));
        let refused = DriverError::Refused {
            instrument: "awg".into(),
            batch: "the segment download".into(),
            errors: vec![DeviceError {
                code: -222,
                message: "Data out of range".into(),
            }],
        };
        assert_eq!(refused.exit_class(), ExitClass::Instrument);
        assert_eq!(refused.device_errors().map(<[_]>::len), Some(1));
        assert!(refused.to_string().contains("-222,\"Data out of range\""));
        let trigger = DriverError::NoTrigger {
            instrument: "scope".into(),
            source_name: "EX".into(),
            waited_s: 2.0,
        };
        assert!(trigger
            .to_string()
            .starts_with("no marker edge: check the AWG runs and its marker output is on"));
        assert_eq!(trigger.exit_class(), ExitClass::Instrument);
    }
}
