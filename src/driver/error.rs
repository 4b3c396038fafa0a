//! The driver layer's error: what went wrong with an instrument, kept apart by cause so the caller
//! knows whether to fix the settings (exit 2), look at the bench (exit 3), or retry.

use crate::exit::{Classify, ExitClass};
use crate::session::{DeviceError, ErrorList, SessionError};
use crate::transport::ErrorKind;

use super::safe_report::SafeStateReport;

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
    /// The scope does not answer on this protocol: off, unreachable, or set to the other one (the
    /// error cannot tell which, so it lists them).
    #[error("{resource}: no answer over {protocol}: {source}. If the scope is on and reachable, check its remote setting: Utilities > Utilities Setup > Remote must be {protocol} (if it is {other}, use the {other} resource string instead)")]
    RemoteInterface {
        resource: String,
        protocol: &'static str,
        other: &'static str,
        #[source]
        source: Box<SessionError>,
    },
    /// The single acquisition did not complete.
    #[error("no marker edge: check the AWG runs and its marker output is on ({instrument} waited {waited_s} s for a trigger on {source_name}){}", safe_state_text(.safe_state.as_ref()))]
    NoTrigger {
        instrument: String,
        source_name: String,
        waited_s: f64,
        /// What the capture's safe state did after RF was on (filled in by the capture, which
        /// runs it; `None` from the driver itself).
        safe_state: Option<SafeStateReport>,
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
    /// An RF module read back after a capture is not as it was switched on for it: back at its
    /// power-on state, RF off, other settings, or no answer. It was reset or lost power during
    /// the capture (`certain`), or may have been (`!certain`: it did not answer), so the capture
    /// may hold no signal and is not used. A glitch of the bench: the retry policy measures the
    /// step again.
    #[error("{instrument}: {found} after the capture: it {} reset or lost power during the capture, which is not used", if *.certain { "was" } else { "may have been" })]
    StateLost {
        instrument: String,
        found: String,
        certain: bool,
    },
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

/// The end of a message about a stop while RF was on: what the safe state switched off, or that
/// it did not complete.
fn safe_state_text(report: Option<&SafeStateReport>) -> String {
    match report {
        None => String::new(),
        Some(r) if r.steps.is_empty() => String::new(),
        Some(r) if r.is_safe() => {
            format!("; RF was on and is off again, the bench is in its safe state ({r})")
        }
        Some(r) => format!(
            "; RF was on and the safe state did NOT complete ({r}): switch the bench off by hand"
        ),
    }
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
            DriverError::NoTrigger { .. } | DriverError::StateLost { .. } => {
                (ErrorKind::Retry, ExitClass::Instrument)
            }
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
            safe_state: None,
        };
        assert!(trigger
            .to_string()
            .starts_with("no marker edge: check the AWG runs and its marker output is on"));
        assert!(trigger.to_string().ends_with("trigger on EX)"));
        assert_eq!(trigger.exit_class(), ExitClass::Instrument);
    }

    #[test]
    fn a_missing_edge_after_rf_confirms_what_was_switched_off() {
        use super::super::safe_report::SafeStep;
        let step = |step, error: Option<&str>| SafeStep {
            step,
            error: error.map(str::to_string),
        };
        let edge = |steps| DriverError::NoTrigger {
            instrument: "scope".into(),
            source_name: "EX".into(),
            waited_s: 10.0,
            safe_state: Some(SafeStateReport { steps }),
        };
        let safe = edge(vec![
            step("Tx RF off", None),
            step("Rx off", None),
            step("AWG outputs off and :ABOR", None),
        ])
        .to_string();
        assert!(
            safe.ends_with(
                "; RF was on and is off again, the bench is in its safe state (Tx RF off: done; \
                 Rx off: done; AWG outputs off and :ABOR: done)"
            ),
            "{safe}"
        );
        let unsafe_ = edge(vec![step("Tx RF off", Some("timed out"))]).to_string();
        assert!(
            unsafe_.contains("the safe state did NOT complete (Tx RF off: FAILED (timed out))"),
            "{unsafe_}"
        );
    }
}
