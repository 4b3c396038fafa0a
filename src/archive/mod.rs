//! Archive processing driven by the run catalog: the captures a query selects, each processed
//! into a folder addressed by content (the input's SHA-256, the processing options' hash and
//! radbench's version). A unit whose folder exists is done and skipped; a unit is written under
//! a hidden temporary name and renamed into place when complete, so a killed worker never
//! leaves a duplicate or a half-written result. `radbench process --from-catalog` runs the
//! units on threads, the Python package's Dask path runs the same units on a cluster.

mod settings;
mod unit;

pub use settings::ArchiveSettings;
pub use unit::{process_unit, sweep_partials, units, units_of, Unit, UnitDone, UnitStatus};

/// radbench's version, the third part of every output's address.
pub const VERSION: &str = env!("CARGO_PKG_VERSION");
