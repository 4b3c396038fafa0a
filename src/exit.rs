//! Exit codes and how errors map to them.
//!
//! | code | meaning |
//! |---|---|
//! | 0 | success |
//! | 1 | internal error (a bug: please report it) |
//! | 2 | bad input: command line, TOML, parameters (the message names the field and what is allowed) |
//! | 3 | instrument or link failure (the instrument refused, or the connection failed) |
//! | 4 | processing failure (the data could not be processed into a result) |
//! | 130 | interrupted by Ctrl-C (after the bench was put in its safe state) |

use std::fmt;

/// The class of a failure, which decides the process exit code.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ExitClass {
    Internal,
    BadInput,
    Instrument,
    Processing,
    Interrupted,
}

impl ExitClass {
    pub fn code(self) -> i32 {
        match self {
            ExitClass::Internal => 1,
            ExitClass::BadInput => 2,
            ExitClass::Instrument => 3,
            ExitClass::Processing => 4,
            ExitClass::Interrupted => 130,
        }
    }
}

/// Errors of every layer implement this so `main` can pick the exit code.
pub trait Classify {
    fn exit_class(&self) -> ExitClass;
}

/// An error that carries its class explicitly; the CLI wraps layer errors in it.
#[derive(Debug)]
pub struct Classified {
    pub class: ExitClass,
    pub message: String,
}

impl fmt::Display for Classified {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(&self.message)
    }
}

impl std::error::Error for Classified {}

/// Bad user input: the message must name the field and what is allowed.
pub fn bad_input(message: impl Into<String>) -> anyhow::Error {
    anyhow::Error::new(Classified {
        class: ExitClass::BadInput,
        message: message.into(),
    })
}

/// The message for the user: every error of the chain, joined with ": ", except a cause whose
/// text the message before it already quotes (layer errors name their source in their own
/// text, so `{:#}` would print it two or three times).
pub fn render(err: &anyhow::Error) -> String {
    let mut out = String::new();
    for cause in err.chain() {
        let text = cause.to_string();
        if text.is_empty() || out.contains(&text) {
            continue;
        }
        if !out.is_empty() {
            out.push_str(": ");
        }
        out.push_str(&text);
    }
    out
}

/// Walks an error chain and returns the class of the first error that knows its class.
pub fn classify(err: &anyhow::Error) -> ExitClass {
    for cause in err.chain() {
        if let Some(c) = cause.downcast_ref::<Classified>() {
            return c.class;
        }
        if let Some(class) = registered_class(cause) {
            return class;
        }
        if cause.downcast_ref::<clap::Error>().is_some() {
            return ExitClass::BadInput;
        }
    }
    ExitClass::Internal
}

/// Layer error types register here (one line each) so their class is found in an `anyhow` chain.
fn registered_class(cause: &(dyn std::error::Error + 'static)) -> Option<ExitClass> {
    macro_rules! try_types {
        ($($t:ty),* $(,)?) => {
            $(if let Some(e) = cause.downcast_ref::<$t>() { return Some(e.exit_class()); })*
        };
    }
    try_types!(
        crate::waveform::ParamError,
        crate::waveform::DecodeError,
        crate::dsp::DspError,
        crate::address::AddressError,
        crate::transport::LinkError,
        crate::transport::journal::JournalError,
        crate::session::SessionError,
        crate::catalog::CatalogError,
        crate::driver::DriverError,
        crate::driver::TrcError,
        crate::storage::StorageError,
        crate::storage::recording::RecordingError,
        crate::simulate::SimError,
        crate::measure::MeasureError,
        crate::measure::bench_file::BenchFileError,
    );
    None
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::session::SessionError;
    use crate::transport::LinkError;

    #[test]
    fn render_names_each_cause_once() {
        let refused = std::io::Error::from(std::io::ErrorKind::ConnectionRefused);
        let refused_text = refused.to_string();
        let err = anyhow::Error::new(SessionError::Link {
            resource: "TCPIP::127.0.0.1::5025::SOCKET".into(),
            source: LinkError::Connect {
                target: "127.0.0.1:5025".into(),
                protocol: "SOCKET",
                source: refused,
            },
        });
        let text = render(&err);
        assert_eq!(text.matches(&refused_text).count(), 1, "{text}");
        assert!(
            text.starts_with("TCPIP::127.0.0.1::5025::SOCKET: cannot connect to 127.0.0.1:5025")
        );
        assert_eq!(classify(&err), ExitClass::Instrument);
    }

    #[test]
    fn render_keeps_context_and_new_causes() {
        let err = anyhow::Error::new(std::io::Error::other("disk full"))
            .context("cannot write run/capture.bin");
        assert_eq!(render(&err), "cannot write run/capture.bin: disk full");
    }
}
