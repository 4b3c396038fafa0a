//! The bench file and the catalog, before any instrument is touched: each instrument's catalog
//! entry and its resource string parsed. A bench file that fails here is no checklist but an
//! error (exit 2): there is nothing to check yet.

use crate::address::Resource;
use crate::catalog::{Catalog, InstrumentModel};
use crate::measure::bench::bench_file::BenchFile;
use crate::measure::error::MeasureError;

/// One instrument of the bench file.
pub(super) struct Entry {
    /// Its section, as check ids name it (`awg`, `scope`, `tx`, `rx`).
    pub(super) name: &'static str,
    /// Its resource string as the bench file writes it.
    pub(super) written: String,
    pub(super) resource: Resource,
    pub(super) model: InstrumentModel,
}

/// Every instrument the doctor opens: the AWG, the scope, and the front ends radbench drives
/// (`driver = "manual"` ones are not here: the bench file holds them apart).
pub(super) struct Entries {
    pub(super) awg: Entry,
    pub(super) scope: Entry,
    /// Tx then Rx, those the bench file has.
    pub(super) fronts: Vec<Entry>,
}

impl Entries {
    /// The bench file's instruments: models first (AWG, scope), then resources, then the front
    /// ends', each failing with the section it is in.
    pub(super) fn read(file: &BenchFile) -> Result<Entries, MeasureError> {
        let catalog: Catalog = file.catalog()?;
        let awg_model = catalog.get(&file.awg.model)?.clone();
        let scope_model = catalog.get(&file.scope.model)?.clone();
        let awg = entry("awg", &file.awg.resource, awg_model)?;
        let scope = entry("scope", &file.scope.resource, scope_model)?;
        let fronts = [("tx", &file.tx), ("rx", &file.rx)]
            .into_iter()
            .filter_map(|(name, e)| e.as_ref().map(|e| (name, e)))
            .map(|(name, e)| {
                let resource = parse(&e.resource, name)?;
                Ok(Entry {
                    name,
                    written: e.resource.clone(),
                    resource,
                    model: catalog.get(&e.model)?.clone(),
                })
            })
            .collect::<Result<_, MeasureError>>()?;
        Ok(Entries { awg, scope, fronts })
    }
}

fn entry(name: &'static str, written: &str, model: InstrumentModel) -> Result<Entry, MeasureError> {
    Ok(Entry {
        name,
        written: written.to_string(),
        resource: parse(written, name)?,
        model,
    })
}

fn parse(text: &str, section: &'static str) -> Result<Resource, MeasureError> {
    text.parse().map_err(|source| MeasureError::Resource {
        section,
        text: text.to_string(),
        source,
    })
}
