//! Schema and loader for the instrument catalog in `instruments/*.toml`.
//!
//! Instrument facts (identity strings, transports and ports, limits, quirks, timeouts, register maps)
//! are data, not code. The files are compiled into the binary ([`Catalog::embedded`]); a folder can
//! override them ([`Catalog::load`]): a file there replaces the built-in model with the same
//! `instrument.key` and adds any new model. Every file is checked on load; a bad file is refused with
//! its name, the field, the line and what is allowed ([`CatalogError::Invalid`]).

mod error;
mod identity;
pub(crate) mod locate;
mod overrides;
mod schema;
mod validate;

use std::path::{Path, PathBuf};

pub use error::{CatalogError, Problem};
pub use identity::Idn;
pub use schema::{
    AwgLimits, BitField, Checksum, DacMode, DigitizerLimits, DividerLimits, EmulatorIdentity,
    Identity, Info, InstrumentKind, InstrumentModel, LineProtocol, NumberFormat, Parity,
    ProtocolError, Quirks, Register, RegisterAccess, RfDirection, RfLimits, SerialSettings,
    TimeoutPolicy, TransportKind, TransportSpec,
};

use locate::FieldIndex;

/// The catalog files built into radbench: `(file name, text)`, every `instruments/*.toml` (the
/// build script lists them: a new file is a new built-in model, after the first four).
pub const EMBEDDED_FILES: &[(&str, &str)] =
    include!(concat!(env!("OUT_DIR"), "/embedded_catalog.rs"));

/// Where a model's file came from.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Origin {
    /// Built into the binary (file name under `instruments/`).
    Embedded(&'static str),
    /// Read from an override folder.
    File(PathBuf),
}

impl std::fmt::Display for Origin {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Origin::Embedded(name) => write!(f, "embedded:instruments/{name}"),
            Origin::File(path) => write!(f, "{}", path.display()),
        }
    }
}

/// A model recognised from an `*IDN?` reply.
#[derive(Debug, Clone, Copy)]
pub struct Identified<'a> {
    pub model: &'a InstrumentModel,
    /// The reply came from a mock_lab emulator of the model, not the vendor's hardware.
    pub emulated: bool,
}

/// All known instrument models.
#[derive(Debug, Clone)]
pub struct Catalog {
    entries: Vec<(InstrumentModel, Origin)>,
}

impl Catalog {
    /// The models built into radbench.
    pub fn embedded() -> Result<Catalog, CatalogError> {
        let mut catalog = Catalog {
            entries: Vec::new(),
        };
        for &(name, text) in EMBEDDED_FILES {
            let origin = Origin::Embedded(name);
            let model = parse_model(&origin.to_string(), text)?;
            catalog.insert(model, origin, false)?;
        }
        Ok(catalog)
    }

    /// The built-in models, overridden and extended by the `*.toml` files of `dir` when given.
    pub fn load(override_dir: Option<&Path>) -> Result<Catalog, CatalogError> {
        let mut catalog = Catalog::embedded()?;
        if let Some(dir) = override_dir {
            for (model, origin) in read_dir(dir)? {
                catalog.insert(model, origin, true)?;
            }
        }
        Ok(catalog)
    }

    fn insert(
        &mut self,
        model: InstrumentModel,
        origin: Origin,
        may_override_embedded: bool,
    ) -> Result<(), CatalogError> {
        let existing = self
            .entries
            .iter()
            .position(|(m, _)| m.instrument.key == model.instrument.key);
        match existing {
            Some(i)
                if may_override_embedded && matches!(self.entries[i].1, Origin::Embedded(_)) =>
            {
                tracing::info!(key = %model.instrument.key, from = %origin, "catalog override");
                self.entries[i] = (model, origin);
                Ok(())
            }
            Some(i) => Err(CatalogError::DuplicateKey {
                key: model.instrument.key,
                first: self.entries[i].1.to_string(),
                second: origin.to_string(),
            }),
            None => {
                self.entries.push((model, origin));
                Ok(())
            }
        }
    }

    /// All models with their origin, in load order.
    pub fn models(&self) -> impl Iterator<Item = (&InstrumentModel, &Origin)> {
        self.entries.iter().map(|(m, o)| (m, o))
    }

    /// The model with this `instrument.key`.
    pub fn get(&self, key: &str) -> Result<&InstrumentModel, CatalogError> {
        self.entries
            .iter()
            .map(|(m, _)| m)
            .find(|m| m.instrument.key == key)
            .ok_or_else(|| CatalogError::UnknownKey {
                key: key.to_string(),
                known: self
                    .entries
                    .iter()
                    .map(|(m, _)| m.instrument.key.as_str())
                    .collect::<Vec<_>>()
                    .join(", "),
            })
    }

    /// The model whose identity patterns (or emulator identity) match an `*IDN?` reply.
    pub fn identify(&self, idn_reply: &str) -> Option<Identified<'_>> {
        let idn = Idn::parse(idn_reply)?;
        self.entries.iter().find_map(|(model, _)| {
            let emulated = model.identity.matches(&idn.manufacturer, &idn.model)?;
            Some(Identified { model, emulated })
        })
    }
}

/// Parses and validates one catalog file. `file` names it in error messages.
pub fn parse_model(file: &str, text: &str) -> Result<InstrumentModel, CatalogError> {
    let index = FieldIndex::new(text);
    let mut model: InstrumentModel = toml::from_str(text).map_err(|e| {
        let offset = e.span().map(|s| s.start);
        CatalogError::Invalid {
            file: file.to_string(),
            problems: vec![Problem {
                field: offset
                    .and_then(|o| index.path_at(o))
                    .unwrap_or_default()
                    .to_string(),
                line: offset.map(|o| index.line_of(o)),
                reason: e.message().trim().to_string(),
            }],
        }
    })?;
    let moved = validate::adopt_old_places(&mut model);
    let problems: Vec<Problem> = validate::validate(&model)
        .into_iter()
        .chain(moved)
        .map(|(field, reason)| Problem {
            line: index.line_of_path(&field),
            field,
            reason,
        })
        .collect();
    if problems.is_empty() {
        Ok(model)
    } else {
        Err(CatalogError::Invalid {
            file: file.to_string(),
            problems,
        })
    }
}

/// Reads every `*.toml` file of a folder, sorted by name.
/// The instrument files of a catalog folder (`*.toml`, sorted): what [`Catalog::load`] reads.
pub(crate) fn folder_files(dir: &Path) -> Result<Vec<PathBuf>, CatalogError> {
    let listing = std::fs::read_dir(dir).map_err(|source| CatalogError::ReadDir {
        dir: dir.to_path_buf(),
        source,
    })?;
    let mut paths = Vec::new();
    for entry in listing {
        let entry = entry.map_err(|source| CatalogError::ReadDir {
            dir: dir.to_path_buf(),
            source,
        })?;
        let path = entry.path();
        if path.extension().is_some_and(|e| e == "toml") && path.is_file() {
            paths.push(path);
        }
    }
    if paths.is_empty() {
        return Err(CatalogError::EmptyDir {
            dir: dir.to_path_buf(),
        });
    }
    paths.sort();
    Ok(paths)
}

fn read_dir(dir: &Path) -> Result<Vec<(InstrumentModel, Origin)>, CatalogError> {
    let paths = folder_files(dir)?;
    let mut models = Vec::with_capacity(paths.len());
    for path in paths {
        let text = std::fs::read_to_string(&path).map_err(|source| CatalogError::Read {
            file: path.clone(),
            source,
        })?;
        let model = parse_model(&path.display().to_string(), &text)?;
        models.push((model, Origin::File(path)));
    }
    Ok(models)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_embedded_file_is_valid() {
        let catalog = Catalog::embedded().unwrap();
        assert_eq!(catalog.models().count(), EMBEDDED_FILES.len());
    }
}
