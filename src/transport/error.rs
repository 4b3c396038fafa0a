//! The transport layer's errors: "the link failed", never "the instrument refused a command".

use crate::exit::ExitClass;
use std::time::Duration;

/// A duration as people read it: `300 ms`, `2 s`, `2.5 s`, `107 s`; never `1.999385989s`.
/// Below a second, whole milliseconds; up to ten seconds, tenths (a trailing `.0` dropped);
/// beyond, whole seconds.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) struct Rounded(pub Duration);

impl std::fmt::Display for Rounded {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let ms = self.0.as_secs_f64() * 1e3;
        if ms < 999.5 {
            return write!(f, "{} ms", ms.round() as u64);
        }
        let tenths = (ms / 100.0).round() as u64;
        if tenths < 100 && tenths % 10 != 0 {
            write!(f, "{}.{} s", tenths / 10, tenths % 10)
        } else {
            write!(f, "{} s", (ms / 1e3).round() as u64)
        }
    }
}

/// A decoding error with one protocol prefix: the codec's own when it names its format (`VICP:
/// bad header ...`), else the link's.
fn codec_text(protocol: &str, source: &CodecError) -> String {
    match source {
        CodecError::TooLarge { .. } | CodecError::BadHeader { .. } => source.to_string(),
        CodecError::Xdr { .. } => format!("{protocol}: {source}"),
    }
}

/// The possible causes of a failed connect, as far as the error tells them apart: a refusal means
/// something answered and nothing listens on that port; silence may be anything on the way.
fn connect_causes(source: &std::io::Error, protocol: &str) -> String {
    match source.kind() {
        std::io::ErrorKind::ConnectionRefused => format!(
            "the connection was refused: the host answered, but nothing accepts {protocol} \
             connections on that port. Possible causes: the instrument is off or still starting \
             up (a PC-based instrument answers before its software does); its {protocol} server \
             is disabled, or its remote interface is set to another protocol; the address or \
             port is wrong"
        ),
        std::io::ErrorKind::TimedOut => format!(
            "nothing answered. Possible causes: the instrument is off or not on this network; a \
             firewall drops the connection; the address is wrong; its {protocol} server is \
             disabled"
        ),
        _ => format!(
            "check the address, that the instrument is on, and that its {protocol} server is \
             enabled"
        ),
    }
}

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
    #[error("{format}: bad header ({detail}): what answered does not speak {format}; check that the resource names the instrument's {format} port")]
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
    #[error("cannot connect to {target}: {source}; {}", connect_causes(.source, .protocol))]
    Connect {
        target: String,
        protocol: &'static str,
        source: std::io::Error,
    },
    #[error("cannot resolve host `{host}`: check the resource string")]
    Resolve { host: String },
    #[error("{op} timed out after {}; the device is cleared before the link is used again, so a late reply is never taken for the next answer. If the instrument is just slow, raise the timeout (--timeout SECONDS)", Rounded(*.after))]
    Timeout { op: &'static str, after: Duration },
    #[error(
        "the instrument closed the connection during {op}; it is reopened before the next operation"
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
    #[error("{}", codec_text(.protocol, .source))]
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
    /// Retry, abort, or fix the input.
    pub fn kind(&self) -> ErrorKind {
        self.classes().0
    }

    /// What to do about it and the exit code it gives: one table for both.
    fn classes(&self) -> (ErrorKind, ExitClass) {
        match self {
            LinkError::Connect { .. }
            | LinkError::Timeout { .. }
            | LinkError::Closed { .. }
            | LinkError::Io { .. }
            | LinkError::Serial { .. }
            | LinkError::NotOpen => (ErrorKind::Retry, ExitClass::Instrument),
            LinkError::Protocol { .. } | LinkError::Codec { .. } | LinkError::Refused { .. } => {
                (ErrorKind::Abort, ExitClass::Instrument)
            }
            LinkError::Resolve { .. } => (ErrorKind::FixInput, ExitClass::BadInput),
            LinkError::Unsupported { .. }
            | LinkError::MessageTooLarge { .. }
            | LinkError::IndefiniteBlockWithNewline { .. } => {
                (ErrorKind::FixInput, ExitClass::Instrument)
            }
        }
    }

    /// Whether nobody answered: the connection was refused or dropped, the server refused the
    /// link, or no reply came in time. At connection time this usually means the instrument does
    /// not serve this protocol at this address (or is off), rather than a fault on a working link.
    pub(crate) fn is_no_answer(&self) -> bool {
        matches!(
            self,
            LinkError::Timeout { .. }
                | LinkError::Closed { .. }
                | LinkError::Connect { .. }
                | LinkError::Refused { .. }
        )
    }

    /// Whether the stream may hold a partial frame or a pending reply after this error, so the
    /// link must be cleared (or reopened) before it is used again.
    pub(crate) fn leaves_link_dirty(&self) -> bool {
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
    fn exit_class(&self) -> ExitClass {
        self.classes().1
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn durations_are_printed_rounded() {
        let text = |d: Duration| Rounded(d).to_string();
        assert_eq!(text(Duration::from_nanos(1_999_385_989)), "2 s");
        assert_eq!(text(Duration::from_millis(300)), "300 ms");
        assert_eq!(text(Duration::from_micros(999_400)), "999 ms");
        assert_eq!(text(Duration::from_micros(999_600)), "1 s");
        assert_eq!(text(Duration::from_millis(2_460)), "2.5 s");
        assert_eq!(text(Duration::from_millis(9_960)), "10 s");
        assert_eq!(text(Duration::from_millis(107_374)), "107 s");
        assert_eq!(text(Duration::ZERO), "0 ms");
        let e = LinkError::Timeout {
            op: "HiSLIP read",
            after: Duration::from_nanos(1_999_385_989),
        };
        assert!(
            e.to_string()
                .starts_with("HiSLIP read timed out after 2 s;"),
            "{e}"
        );
        assert!(
            e.to_string()
                .ends_with("raise the timeout (--timeout SECONDS)"),
            "{e}"
        );
    }

    #[test]
    fn a_bad_header_has_one_prefix_and_says_what_answered_is_not() {
        let e = LinkError::codec("VICP")(CodecError::BadHeader {
            format: "VICP",
            detail: "header version is not 1",
        });
        let text = e.to_string();
        assert!(
            text.starts_with("VICP: bad header (header version is not 1)"),
            "{text}"
        );
        assert_eq!(text.matches("VICP:").count(), 1, "{text}");
        assert!(text.contains("what answered does not speak VICP"), "{text}");
    }

    #[test]
    fn a_refused_connect_says_refused_and_lists_the_causes() {
        let e = LinkError::Connect {
            target: "127.0.0.1:1861".into(),
            protocol: "VICP",
            source: std::io::Error::from(std::io::ErrorKind::ConnectionRefused),
        };
        let text = e.to_string();
        assert!(text.contains("the connection was refused"), "{text}");
        assert!(
            text.contains("Possible causes: the instrument is off"),
            "{text}"
        );
        assert!(text.contains("its VICP server is disabled"), "{text}");
        assert!(!text.contains("probably"), "{text}");
    }
}
