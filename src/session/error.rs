//! The session layer's errors: "the instrument refused" ([`SessionError::Device`], entries from
//! `SYST:ERR?` with code and text) is kept apart from "the link failed" ([`SessionError::Link`]);
//! a query with no reply while the queue holds entries is [`SessionError::Unanswered`].

use crate::exit::{Classify, ExitClass};
use crate::transport::{ErrorKind, LinkError};
use std::fmt;

/// One entry of the instrument's error queue, e.g. `-222,"Data out of range"`.
#[derive(Debug, Clone, PartialEq, Eq, serde::Serialize)]
pub struct DeviceError {
    pub code: i32,
    pub message: String,
}

impl fmt::Display for DeviceError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{},\"{}\"", self.code, self.message)
    }
}

impl DeviceError {
    /// SCPI error classes: -1xx command and -2xx execution errors mean the input was wrong;
    /// -3xx device-specific, -4xx query and vendor (positive) errors mean stop and look.
    pub fn kind(&self) -> ErrorKind {
        match self.code {
            -299..=-100 => ErrorKind::FixInput,
            _ => ErrorKind::Abort,
        }
    }
}

/// Error entries as one line, `-222,"Data out of range"; -221,"Settings conflict"`.
#[derive(Debug, Clone, Copy)]
pub(crate) struct ErrorList<'a>(pub &'a [DeviceError]);

impl fmt::Display for ErrorList<'_> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        for (i, e) in self.0.iter().enumerate() {
            if i > 0 {
                f.write_str("; ")?;
            }
            write!(f, "{e}")?;
        }
        Ok(())
    }
}

#[derive(Debug, thiserror::Error)]
pub enum SessionError {
    #[error("{resource}: the instrument refused{}: {}", .after.as_deref().map(|c| format!(" `{c}`")).unwrap_or_default(), ErrorList(.errors))]
    Device {
        resource: String,
        /// The command after which the errors were read, when known.
        after: Option<String>,
        errors: Vec<DeviceError>,
    },
    #[error("{resource}: no reply to `{query}` within {}, and the instrument's error queue holds: {}. A query the instrument refuses gets no reply; if it was only slow, raise the timeout (--timeout SECONDS)", crate::transport::Rounded(*.after), ErrorList(.errors))]
    Unanswered {
        resource: String,
        query: String,
        after: std::time::Duration,
        errors: Vec<DeviceError>,
    },
    #[error("{resource}: {source}")]
    Link {
        resource: String,
        #[source]
        source: LinkError,
    },
    #[error("{resource}: the reply to `{command}` is not {expected}: {reply:?}")]
    Reply {
        resource: String,
        command: String,
        expected: &'static str,
        reply: String,
    },
    #[error("command {command:?} contains a line end (LF, or the serial line's `line_terminator`); send one command per call (or separate them with `;`)")]
    CommandHasNewline { command: String },
    #[error("a definite block holds at most 999999999 bytes, this one has {len}; split it (e.g. several :TRAC:DATA writes at increasing offsets)")]
    BlockTooLarge { len: u64 },
    #[error("{resource}: the error queue still had entries after {limit} reads of `{query}`; the instrument may not implement it")]
    ErrorQueueNotDraining {
        resource: String,
        query: String,
        limit: usize,
    },
}

impl SessionError {
    /// Retry, abort, or fix the input.
    pub fn kind(&self) -> ErrorKind {
        self.classes().0
    }

    /// What to do about it and the exit code it gives: one table for both.
    fn classes(&self) -> (ErrorKind, ExitClass) {
        match self {
            SessionError::Device { errors, .. } | SessionError::Unanswered { errors, .. } => {
                let kind = if errors.iter().all(|e| e.kind() == ErrorKind::FixInput) {
                    ErrorKind::FixInput
                } else {
                    ErrorKind::Abort
                };
                (kind, ExitClass::Instrument)
            }
            SessionError::Link { source, .. } => (source.kind(), source.exit_class()),
            SessionError::Reply { .. } | SessionError::ErrorQueueNotDraining { .. } => {
                (ErrorKind::Abort, ExitClass::Instrument)
            }
            SessionError::CommandHasNewline { .. } | SessionError::BlockTooLarge { .. } => {
                (ErrorKind::FixInput, ExitClass::BadInput)
            }
        }
    }

    /// The device errors, if the instrument refused.
    pub fn device_errors(&self) -> Option<&[DeviceError]> {
        match self {
            SessionError::Device { errors, .. } | SessionError::Unanswered { errors, .. } => {
                Some(errors)
            }
            _ => None,
        }
    }

    /// Whether the link failed because nobody answered (refused or dropped connection, no reply
    /// in time): see [`LinkError::is_no_answer`].
    pub(crate) fn is_no_answer(&self) -> bool {
        self.link_error().is_some_and(LinkError::is_no_answer)
    }

    /// The link error, if the link failed.
    pub fn link_error(&self) -> Option<&LinkError> {
        match self {
            SessionError::Link { source, .. } => Some(source),
            _ => None,
        }
    }
}

impl Classify for SessionError {
    fn exit_class(&self) -> ExitClass {
        self.classes().1
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::exit::{Classify, ExitClass};

    #[test]
    fn refused_and_link_failed_are_told_apart() {
        let refused = SessionError::Device {
            resource: "r".into(),
            after: Some(":VOLT 9".into()),
            errors: vec![DeviceError {
                code: -222,
                message: "Data out of range".into(),
            }],
        };
        assert_eq!(refused.kind(), ErrorKind::FixInput);
        assert_eq!(refused.exit_class(), ExitClass::Instrument);
        assert!(refused.to_string().contains("-222,\"Data out of range\""));
        assert!(refused.device_errors().is_some() && refused.link_error().is_none());
        let failed = SessionError::Link {
            resource: "r".into(),
            source: LinkError::Closed { op: "read" },
        };
        assert_eq!(failed.kind(), ErrorKind::Retry);
        assert_eq!(failed.exit_class(), ExitClass::Instrument);
        assert!(failed.link_error().is_some() && failed.device_errors().is_none());
        let hw = DeviceError {
            code: -310,
            message: "System error".into(),
        };
        assert_eq!(hw.kind(), ErrorKind::Abort);
    }
}
