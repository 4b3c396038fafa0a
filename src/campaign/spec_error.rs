//! Why a spec cannot be used, at its file, line and field: a file of its own so that the kinds'
//! table, which the spec's reading checks names against, can name fields without the spec.

use std::path::{Path, PathBuf};

/// A spec that cannot be used: the file, the line, the field and what is allowed.
#[derive(Debug, thiserror::Error)]
pub enum SpecError {
    #[error("cannot read the campaign spec {path}: {source}")]
    Read {
        path: PathBuf,
        #[source]
        source: std::io::Error,
    },
    #[error("{}: {message}", located(path, *line, field))]
    Field {
        path: PathBuf,
        /// 1-based; `None` when the field is not written in the file (a default, or a command
        /// line override).
        line: Option<usize>,
        /// Dotted path, e.g. `sweep.count` or `steps[2].targets`.
        field: String,
        /// What is wrong and what is allowed.
        message: String,
    },
}

fn located(path: &Path, line: Option<usize>, field: &str) -> String {
    match line {
        Some(l) => format!("{}:{l}: `{field}`", path.display()),
        None => format!("{}: `{field}`", path.display()),
    }
}

impl crate::exit::Classify for SpecError {
    fn exit_class(&self) -> crate::exit::ExitClass {
        crate::exit::ExitClass::BadInput
    }
}

/// What names a field of the spec in an error (its file and line): the spec file implements it.
pub(crate) trait FieldErrors {
    fn field_error(&self, field: &str, message: String) -> SpecError;
}
