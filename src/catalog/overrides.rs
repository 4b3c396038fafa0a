//! A bench-local overrides file: one TOML file of just the values a bench's units answer
//! differently from the catalog (`radbench doctor --verify-catalog --write-overrides FILE` writes
//! it; the bench file's `catalog_overrides = "FILE"` applies it). Its tables are the models' keys
//! and under them the instrument file's own tables:
//!
//! ```toml
//! [keysight-m8195a.awg]
//! options = ["001", "002"]
//! dac_rate_max = 6.45e10
//! ```
//!
//! Each value replaces the model's, and the model is validated again as a whole, so an override
//! is held to the rules of an instrument file.

use super::{parse_model, Catalog, CatalogError, Origin, Problem, EMBEDDED_FILES};
use std::path::Path;

/// The text of the instrument file a model was loaded from.
pub(crate) fn source_text(origin: &Origin) -> Result<String, CatalogError> {
    match origin {
        Origin::Embedded(name) => Ok(EMBEDDED_FILES
            .iter()
            .find(|(n, _)| n == name)
            .map(|(_, t)| (*t).to_string())
            .unwrap_or_default()),
        Origin::File(path) => std::fs::read_to_string(path).map_err(|source| CatalogError::Read {
            file: path.clone(),
            source,
        }),
    }
}

fn invalid(path: &Path, field: &str, reason: String) -> CatalogError {
    CatalogError::Invalid {
        file: path.display().to_string(),
        problems: vec![Problem {
            field: field.to_string(),
            line: None,
            reason,
        }],
    }
}

/// `over` laid onto `base`: tables merged key by key, any other value replaced.
fn merge(base: &mut toml::Table, over: &toml::Table) {
    for (key, value) in over {
        match (base.get_mut(key), value) {
            (Some(toml::Value::Table(b)), toml::Value::Table(o)) => merge(b, o),
            _ => {
                base.insert(key.clone(), value.clone());
            }
        }
    }
}

impl Catalog {
    /// Applies the overrides file at `path` on top of this catalog.
    ///
    /// # Errors
    /// [`CatalogError::Read`] when the file cannot be read; [`CatalogError::Invalid`] when it is
    /// not TOML, names a model the catalog does not hold, or makes a model invalid.
    pub(crate) fn apply_overrides(&mut self, path: &Path) -> Result<(), CatalogError> {
        let text = std::fs::read_to_string(path).map_err(|source| CatalogError::Read {
            file: path.to_path_buf(),
            source,
        })?;
        let table: toml::Table = text
            .parse()
            .map_err(|e: toml::de::Error| invalid(path, "", e.message().trim().to_string()))?;
        for (key, over) in &table {
            let Some(over) = over.as_table() else {
                return Err(invalid(
                    path,
                    key,
                    "expected a table named by a model key, e.g. [keysight-m8195a.awg]".into(),
                ));
            };
            let Some(i) = self
                .entries
                .iter()
                .position(|(m, _)| m.instrument.key == *key)
            else {
                let known: Vec<&str> = self
                    .entries
                    .iter()
                    .map(|(m, _)| m.instrument.key.as_str())
                    .collect();
                return Err(invalid(
                    path,
                    key,
                    format!("not a model of the catalog; known: {}", known.join(", ")),
                ));
            };
            let origin = self.entries[i].1.clone();
            let mut base: toml::Table = source_text(&origin)?
                .parse()
                .map_err(|e: toml::de::Error| invalid(path, key, e.message().to_string()))?;
            merge(&mut base, over);
            let merged = toml::to_string(&base).map_err(|e| invalid(path, key, e.to_string()))?;
            let model = parse_model(&format!("{origin} with {}", path.display()), &merged)?;
            self.entries[i].0 = model;
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn an_override_replaces_only_its_values() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("overrides.toml");
        std::fs::write(
            &path,
            "[keysight-m8195a.awg]\noptions = [\"001\"]\ndac_rate_max = 6.45e10\n",
        )
        .unwrap();
        let mut catalog = Catalog::embedded().unwrap();
        catalog.apply_overrides(&path).unwrap();
        let awg = catalog.get("keysight-m8195a").unwrap().awg.clone().unwrap();
        assert_eq!(awg.options, vec!["001".to_string()]);
        assert_eq!(awg.dac_rate_max, 6.45e10);
        assert_eq!(awg.dac_rate_min, 53.76e9);
    }

    #[test]
    fn an_unknown_model_or_a_bad_value_is_named() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("overrides.toml");
        std::fs::write(&path, "[keysight-m8195b.awg]\noptions = []\n").unwrap();
        let e = Catalog::embedded()
            .unwrap()
            .apply_overrides(&path)
            .unwrap_err()
            .to_string();
        assert!(e.contains("keysight-m8195b") && e.contains("known:"), "{e}");
        std::fs::write(&path, "[keysight-m8195a.awg]\ndac_rate_max = \"fast\"\n").unwrap();
        let e = Catalog::embedded()
            .unwrap()
            .apply_overrides(&path)
            .unwrap_err()
            .to_string();
        assert!(e.contains("dac_rate_max"), "{e}");
    }
}
