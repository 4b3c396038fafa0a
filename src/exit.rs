//! Exit codes and how errors map to them.
//!
//! | code | meaning |
//! |---|---|
//! | 0 | success |
//! | 1 | internal error (a bug: please report it) |
//! | 2 | bad input: command line, TOML, parameters (the message names the field and what is allowed) |
//! | 3 | instrument or link failure (the instrument refused, or the connection failed) |
//! | 4 | processing failure (the data could not be processed into a result) |
//! | 129, 130, 143 | stopped by SIGHUP, SIGINT (Ctrl-C) or SIGTERM, after the bench was put in its safe state |
//!
//! A leaf module: it imports nothing of radbench, so every layer can classify its errors. Turning
//! an error chain into an exit code (downcasting to each layer's type) is the CLI's job
//! (`cli::classify`).

use std::fmt;

/// The class of a failure, which decides the process exit code.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ExitClass {
    Internal,
    BadInput,
    Instrument,
    Processing,
    /// Stopped by SIGINT (Ctrl-C).
    Interrupted,
    /// Stopped by SIGTERM.
    Terminated,
    /// Stopped by SIGHUP (the terminal went away).
    HungUp,
}

impl ExitClass {
    pub fn code(self) -> i32 {
        match self {
            ExitClass::Internal => 1,
            ExitClass::BadInput => 2,
            ExitClass::Instrument => 3,
            ExitClass::Processing => 4,
            ExitClass::Interrupted => 130,
            ExitClass::Terminated => 143,
            ExitClass::HungUp => 129,
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
    render_chain(err.as_ref())
}

/// `render` of any error and its sources (the one renderer of error chains: the CLI's
/// messages and the campaign's records say the same).
pub(crate) fn render_chain(err: &(dyn std::error::Error + 'static)) -> String {
    let mut out = String::new();
    let mut cause = Some(err);
    while let Some(c) = cause {
        let text = c.to_string();
        if !text.is_empty() && !out.contains(&text) {
            if !out.is_empty() {
                out.push_str(": ");
            }
            out.push_str(&text);
        }
        cause = c.source();
    }
    out
}
