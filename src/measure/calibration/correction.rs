//! The correction a measurement uses: its record (`CorrectionUsed`, what files keep) and the
//! calibration itself, loaded and checked once where a command resolves its options and handed
//! down by reference, so processing (the pipeline, the pre-distorted transmission) never reads
//! the file.

use super::response::{Calibration, CorrectionMode};
use crate::measure::error::MeasureError;
use serde::{Deserialize, Serialize};
use std::path::Path;
use std::sync::Arc;

/// Which correction a measurement used, as recorded in its processing options.
#[derive(Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CorrectionUsed {
    /// `rx`: DC, I/Q imbalance and the chain's response corrected on receive; `tx`, `both`
    /// (files keep the text).
    pub mode: CorrectionMode,
    /// The calibration header's path (absolute when it could be resolved).
    pub calibration: String,
    /// SHA-256 of the header (which holds its table's SHA-256).
    pub sha256: String,
    /// When the calibration was measured.
    pub measured_at: String,
    /// The calibration itself, once loaded; never recorded (a record read back has none until
    /// [`load_recorded`] loads it).
    #[serde(skip)]
    pub(crate) loaded: Loaded,
}

/// A loaded calibration, shared: the options are cloned per algorithm and per worker. It takes
/// no part in comparisons: two corrections are the same when their records are.
#[derive(Clone, Default)]
pub(crate) struct Loaded(Option<Arc<Calibration>>);

impl PartialEq for Loaded {
    fn eq(&self, _: &Self) -> bool {
        true
    }
}

/// The record alone, as the derive printed it: an archive's address hashes the options' `Debug`
/// text (`archive/settings.rs`), so it must not change.
impl std::fmt::Debug for CorrectionUsed {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("CorrectionUsed")
            .field("mode", &self.mode)
            .field("calibration", &self.calibration)
            .field("sha256", &self.sha256)
            .field("measured_at", &self.measured_at)
            .finish()
    }
}

impl Calibration {
    /// What a measurement records when it uses this calibration, with it loaded.
    pub fn used(self: &Arc<Self>) -> CorrectionUsed {
        CorrectionUsed {
            mode: CorrectionMode::Rx,
            calibration: self.path.display().to_string(),
            sha256: self.sha256.clone(),
            measured_at: self.header.measured_at.clone(),
            loaded: Loaded(Some(self.clone())),
        }
    }

    /// What a measurement records when it uses this calibration with `mode` (rx, tx or both).
    pub fn used_as(self: &Arc<Self>, mode: CorrectionMode) -> CorrectionUsed {
        CorrectionUsed {
            mode,
            ..self.used()
        }
    }
}

impl CorrectionUsed {
    /// The loaded calibration. Processing asks here and never reads the file: a correction
    /// without one was not resolved by its command, a bug.
    pub(crate) fn loaded(&self) -> Result<&Calibration, MeasureError> {
        self.loaded
            .0
            .as_deref()
            .ok_or_else(|| MeasureError::CalibrationFile {
                path: self.calibration.clone(),
                reason: "not loaded where the options were resolved (processing reads no file)"
                    .into(),
            })
    }

    /// Hands `cal` to this record, checked to be the calibration it names (its SHA-256).
    pub(crate) fn load_from(&mut self, cal: &Arc<Calibration>) -> Result<(), MeasureError> {
        if cal.sha256 != self.sha256 {
            return Err(MeasureError::CalibrationFile {
                path: self.calibration.clone(),
                reason: format!(
                    "it has changed since it was used (SHA-256 {}, recorded {}): pass \
                     --calibration to use it as it is now",
                    cal.sha256, self.sha256
                ),
            });
        }
        self.loaded = Loaded(Some(cal.clone()));
        Ok(())
    }
}

/// Recorded corrections (a saved capture's, a run's plan) given their calibrations: each file
/// read once and checked against every record naming it; those already loaded are kept, and
/// `none` is left for the pipeline to refuse as it always did.
pub(crate) fn load_recorded<'a>(
    all: impl IntoIterator<Item = &'a mut CorrectionUsed>,
) -> Result<(), MeasureError> {
    let mut read: Vec<Arc<Calibration>> = Vec::new();
    for used in all {
        if used.loaded.0.is_some() || used.mode == CorrectionMode::None {
            continue;
        }
        // `Calibration::path` is canonical; the record keeps the path as it was given.
        let i = match read.iter().position(|c| c.sha256 == used.sha256) {
            Some(i) => i,
            None => {
                read.push(Arc::new(Calibration::load(Path::new(&used.calibration))?));
                read.len() - 1
            }
        };
        used.load_from(&read[i])?;
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    const RECORD: &str = "mode = \"tx\"\ncalibration = \"/cal/response.toml\"\nsha256 = \"ab\"\n\
                          measured_at = \"2026-12-07T06:35:43.455Z\"\n";

    #[test]
    fn a_record_reads_back_writes_and_prints_as_before_and_is_not_loaded() {
        let used: CorrectionUsed = toml::from_str(RECORD).unwrap();
        assert_eq!(toml::to_string(&used).unwrap(), RECORD);
        assert_eq!(
            format!("{used:?}"),
            "CorrectionUsed { mode: Tx, calibration: \"/cal/response.toml\", sha256: \"ab\", \
             measured_at: \"2026-12-07T06:35:43.455Z\" }"
        );
        let err = used.loaded().unwrap_err().to_string();
        assert!(err.contains("not loaded"), "{err}");
    }

    #[test]
    fn a_recorded_calibration_is_read_where_it_is_loaded_and_none_is_left_alone() {
        let gone = RECORD.replace("/cal/", "/no-such-radbench-folder/");
        let mut used: CorrectionUsed = toml::from_str(&gone).unwrap();
        let err = load_recorded([&mut used]).unwrap_err().to_string();
        assert!(err.contains("cannot read it"), "{err}");
        used.mode = CorrectionMode::None;
        load_recorded([&mut used]).unwrap();
    }
}
