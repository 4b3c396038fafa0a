//! The transport layer's errors: "the link failed", never "the instrument refused a command".

use std::time::Duration;

/// What the caller should do about an error.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ErrorKind {
    /// Transient: clear the device or reconnect, then try again.
    Retry,
    /// Not worth retrying as is: the peer broke the protocol or refused the operation.
    Abort,
    /// The request itself is wrong (too large, unsupported on this transport, bad address).
    FixInput,
}

/// A wire format that could not be decoded. Decoders check every length field against their limit
/// before allocating, so arbitrary bytes give one of these, never a panic or a huge allocation.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum CodecError {
    #[error("{format} message of {announced} bytes exceeds the limit of {limit} bytes; raise max_message_bytes if the instrument really sends this much")]
    TooLarge {
        format: &'static str,
        announced: u64,
        limit: u64,
    },
    #[error("{format}: bad header: {detail}")]
    BadHeader {
        format: &'static str,
        detail: &'static str,
    },
    #[error("XDR field `{field}` is truncated or malformed")]
    Xdr { field: &'static str },
}

/// A failure of the link to the instrument.
#[derive(Debug, thiserror::Error)]
pub enum LinkError {
    #[error("cannot connect to {target}: {source}; check the address, that the instrument is on, and that its {protocol} server is enabled")]
    Connect {
        target: String,
        protocol: &'static str,
        source: std::io::Error,
    },
    #[error("cannot resolve host `{host}`: check the resource string")]
    Resolve { host: String },
    #[error("{op} timed out after {after:?}; the device is cleared before the link is used again, so a late reply is never taken for the next answer. Raise the timeout if the instrument is just slow")]
    Timeout { op: &'static str, after: Duration },
    #[error(
        "the instrument closed the connection during {op}; reconnect (the session can reopen it)"
    )]
    Closed { op: &'static str },
    #[error("I/O error during {op}: {source}")]
    Io {
        op: &'static str,
        source: std::io::Error,
    },
    #[error("{protocol}: the instrument broke the protocol: {detail}")]
    Protocol {
        protocol: &'static str,
        detail: String,
    },
    #[error("{protocol}: {source}")]
    Codec {
        protocol: &'static str,
        #[source]
        source: CodecError,
    },
    #[error("{protocol} server refused {op} with error {code} ({meaning})")]
    Refused {
        protocol: &'static str,
        op: &'static str,
        code: u32,
        meaning: &'static str,
    },
    #[error("{op} is not supported on a {protocol} link")]
    Unsupported {
        protocol: &'static str,
        op: &'static str,
    },
    #[error(
        "the outgoing message is {size} bytes, over the limit of {limit} bytes (max_message_bytes)"
    )]
    MessageTooLarge { size: u64, limit: u64 },
    #[error("an indefinite (#0) block containing a newline cannot be sent over a {protocol} link, whose messages end at a newline; send a definite block instead")]
    IndefiniteBlockWithNewline { protocol: &'static str },
    #[error("serial device `{device}`: {detail}")]
    Serial { device: String, detail: String },
    #[error("the link is closed; reconnect before using it")]
    NotOpen,
}

impl LinkError {
    pub fn kind(&self) -> ErrorKind {
        match self {
            LinkError::Connect { .. }
            | LinkError::Timeout { .. }
            | LinkError::Closed { .. }
            | LinkError::Io { .. }
            | LinkError::Serial { .. }
            | LinkError::NotOpen => ErrorKind::Retry,
            LinkError::Protocol { .. } | LinkError::Codec { .. } | LinkError::Refused { .. } => {
                ErrorKind::Abort
            }
            LinkError::Resolve { .. }
            | LinkError::Unsupported { .. }
            | LinkError::MessageTooLarge { .. }
            | LinkError::IndefiniteBlockWithNewline { .. } => ErrorKind::FixInput,
        }
    }

    /// Whether the stream may hold a partial frame or a pending reply after this error, so the
    /// link must be cleared (or reopened) before it is used again.
    pub fn leaves_link_dirty(&self) -> bool {
        !matches!(
            self,
            LinkError::Unsupported { .. }
                | LinkError::MessageTooLarge { .. }
                | LinkError::IndefiniteBlockWithNewline { .. }
                | LinkError::Refused { .. }
        )
    }

    pub(crate) fn codec(protocol: &'static str) -> impl Fn(CodecError) -> LinkError {
        move |source| LinkError::Codec { protocol, source }
    }
}

impl crate::exit::Classify for LinkError {
    fn exit_class(&self) -> crate::exit::ExitClass {
        match self {
            LinkError::Resolve { .. } => crate::exit::ExitClass::BadInput,
            _ => crate::exit::ExitClass::Instrument,
        }
    }
}
