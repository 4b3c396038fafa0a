//! The run's report, written from `manifest.toml` and `results.json` alone (so `radbench campaign
//! report RUN_DIR` writes it again, byte for byte, at any time): `report.md` (tables, mean +- std
//! over the repetitions) and `report.html` (the same tables and every plot inline as SVG; no
//! script, no external file, opens from disk).
//!
//! | module | what it holds |
//! |---|---|
//! | [`mod@figures`] | which plots a run gets, from its numbers (and the thesis' values beside) |
//! | [`plots`] | a chart as SVG text (plotters, the embedded font) |
//! | `markdown` | `report.md` |
//! | `html` | `report.html` |

pub mod figures;
pub(crate) mod html;
pub(crate) mod markdown;
pub mod plots;

use super::manifest::Manifest;
use super::results::Results;
use super::{io, CampaignError};
use crate::storage::atomic::write_atomic;
use std::path::{Path, PathBuf};

pub use figures::{figures, Figure};

/// The Markdown report's file name in a run folder.
pub(crate) const FILE: &str = "report.md";
/// The HTML report's file name in a run folder.
pub(crate) const HTML_FILE: &str = "report.html";

/// Writes `dir/report.md` and `dir/report.html` (each atomically); returns the Markdown's path.
pub fn write(dir: &Path, manifest: &Manifest, results: &Results) -> Result<PathBuf, CampaignError> {
    let figures = figures(manifest, results);
    let md = dir.join(FILE);
    write_atomic(
        &md,
        markdown::markdown(manifest, results, &figures).as_bytes(),
    )?;
    let page = html::html(manifest, results, &figures);
    write_atomic(&dir.join(HTML_FILE), page.as_bytes())?;
    Ok(md)
}

/// Reads a run folder's manifest and results and writes its report again.
pub(crate) fn rewrite(dir: &Path) -> Result<PathBuf, CampaignError> {
    let manifest = Manifest::load(dir)?;
    let results = load_results(dir)?;
    write(dir, &manifest, &results)
}

/// A run folder's `results.json`.
pub fn load_results(dir: &Path) -> Result<Results, CampaignError> {
    let path = dir.join(super::run::RESULTS_FILE);
    let text = std::fs::read_to_string(&path).map_err(io(&path))?;
    serde_json::from_str(&text).map_err(|e| CampaignError::Manifest {
        path: path.clone(),
        message: format!("not a campaign results.json: {e}"),
    })
}

/// `x ± s` with `digits` decimals at least, more (up to 6) so the deviation shows two significant
/// digits; or the value alone.
pub(crate) fn pm(mean: f64, std: Option<f64>, digits: usize) -> String {
    match std {
        Some(s) => {
            let d = if s > 0.0 && s.is_finite() {
                ((1.0 - s.log10().floor()).max(0.0) as usize).clamp(digits, 6)
            } else {
                digits
            };
            format!("{mean:.d$} ± {s:.d$}")
        }
        None => format!("{mean:.digits$}"),
    }
}

#[cfg(test)]
mod tests {
    #[test]
    fn a_small_deviation_keeps_two_significant_digits() {
        assert_eq!(super::pm(13.2641, Some(0.00112), 2), "13.2641 ± 0.0011");
        assert_eq!(super::pm(13.2641, Some(0.5), 2), "13.26 ± 0.50");
        assert_eq!(super::pm(13.2641, Some(0.0), 2), "13.26 ± 0.00");
        assert_eq!(super::pm(13.2641, None, 1), "13.3");
    }
}
