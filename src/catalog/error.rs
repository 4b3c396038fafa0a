//! Errors of the catalog layer. Every problem names the file, the field, the line when known and
//! what is allowed, so the fix is obvious from the message alone.

use std::fmt;
use std::path::PathBuf;

use crate::exit::{Classify, ExitClass};

/// One thing wrong with one field of a catalog file.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Problem {
    /// Dotted path of the field, e.g. `awg.divider[1].granularity` (empty for whole-file syntax errors).
    pub field: String,
    /// 1-based line in the file, when it can be located.
    pub line: Option<usize>,
    /// What is wrong and what is allowed.
    pub reason: String,
}

impl fmt::Display for Problem {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        if let Some(line) = self.line {
            write!(f, "line {line}: ")?;
        }
        if !self.field.is_empty() {
            write!(f, "field `{}`: ", self.field)?;
        }
        f.write_str(&self.reason)
    }
}

/// Why the instrument catalog could not be loaded or used.
#[derive(Debug, thiserror::Error)]
pub enum CatalogError {
    #[error("instrument catalog file {file}: cannot read it ({source}); check the path and its permissions")]
    Read {
        file: PathBuf,
        #[source]
        source: std::io::Error,
    },
    #[error("instrument catalog folder {dir}: cannot list it ({source}); pass a folder that holds *.toml files")]
    ReadDir {
        dir: PathBuf,
        #[source]
        source: std::io::Error,
    },
    #[error("instrument catalog folder {dir} holds no *.toml files; pass the folder with the instrument files")]
    EmptyDir { dir: PathBuf },
    #[error("{}", invalid_message(file, problems))]
    Invalid {
        /// The file as the user named it (a path, or `embedded:<name>` for built-in files).
        file: String,
        problems: Vec<Problem>,
    },
    #[error("instrument key `{key}` is defined twice, in {first} and in {second}; give each file its own `instrument.key`")]
    DuplicateKey {
        key: String,
        first: String,
        second: String,
    },
    #[error("no instrument `{key}` in the catalog; known instruments: {known}")]
    UnknownKey { key: String, known: String },
}

impl CatalogError {
    /// The problems of an invalid file (empty for other errors).
    pub fn problems(&self) -> &[Problem] {
        match self {
            CatalogError::Invalid { problems, .. } => problems,
            _ => &[],
        }
    }
}

fn invalid_message(file: &str, problems: &[Problem]) -> String {
    let mut out = format!("instrument catalog file {file} is invalid:");
    for problem in problems {
        out.push_str("\n  ");
        out.push_str(&problem.to_string());
    }
    out
}

impl Classify for CatalogError {
    fn exit_class(&self) -> ExitClass {
        ExitClass::BadInput
    }
}
