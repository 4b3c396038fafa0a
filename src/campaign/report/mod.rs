//! The run's report, written from `manifest.toml`, `results.json` and each step's
//! `profile.csv` and `link.svg` (so `radbench campaign report RUN_DIR` writes it again, byte for byte, at any
//! time): `report.md` (tables, mean +- std
//! over the repetitions) and `report.html` (the same tables and every plot inline as SVG; no
//! script, no external file, opens from disk).
//!
//! | module | what it holds |
//! |---|---|
//! | [`mod@figures`] | which plots a run gets, from its numbers (and the thesis' values beside) |
//! | [`plots`] | a chart as SVG text (plotters, the embedded font) |
//! | [`profiles`] | every step's range profile, one waterfall row per step |
//! | `summary` | the answer first: pass/fail, worst error, false targets, who, when, on what |
//! | `sweep` | a sweep over any settings: each metric against the inner axis, a line per outer value |
//! | `link` | every step's link figure (constellation, channel estimate or phase trajectory) with its EVM and MER, small multiples |
//! | `markdown` | `report.md` |
//! | `run_figures` | a run's figures in the report's order: the kinds' own around the common ones |
//! | `html` | `report.html` |

pub(crate) mod figures;
pub(crate) mod html;
pub(crate) mod link;
pub(crate) mod markdown;
pub(crate) mod plots;
pub(crate) mod profiles;
mod run_figures;
pub(crate) mod summary;
pub(crate) mod sweep;

pub use figures::{theory, wilson95};
pub use plots::{svg, Chart, HLine, Point, Series, Style};
pub use profiles::step_profiles;

use super::error::{io, CampaignError};
use super::manifest::Manifest;
use super::results::Results;
use crate::storage::write_atomic;
use std::path::{Path, PathBuf};

pub use figures::Figure;
pub use run_figures::figures;

/// The Markdown report's file name in a run folder.
pub(crate) const REPORT_FILE: &str = "report.md";
/// The HTML report's file name in a run folder.
pub const HTML_FILE: &str = "report.html";
/// The folder of the report's figures as PNG (`report.md` links them by this relative path).
pub(crate) const FIGURES_DIR: &str = "figures";

/// Writes `dir/report.md` and `dir/report.html` (each atomically); returns the Markdown's path.
pub fn write(dir: &Path, manifest: &Manifest, results: &Results) -> Result<PathBuf, CampaignError> {
    let mut figures = figures(manifest, results);
    figures.extend(sweep::sweep_figures(&results.steps));
    figures.extend(profiles::step_profiles(dir, results));
    let summary = summary::summary(dir, manifest, results);
    let pngs = render_pngs(&figures);
    let images: Vec<Option<String>> = figures
        .iter()
        .zip(&pngs)
        .map(|(f, png)| png.as_ref().map(|_| format!("{FIGURES_DIR}/{}.png", f.id)))
        .collect();
    let md = dir.join(REPORT_FILE);
    write_atomic(
        &md,
        markdown::markdown(manifest, results, &summary, &figures, &images).as_bytes(),
    )?;
    let page = html::html(
        manifest,
        results,
        &summary,
        &figures,
        &pngs,
        &link::section(dir, results),
    );
    write_atomic(&dir.join(HTML_FILE), page.as_bytes())?;
    // The PNGs last: the reports say first what the run found, should the disk fill up.
    if images.iter().any(Option::is_some) {
        let folder = dir.join(FIGURES_DIR);
        std::fs::create_dir_all(&folder).map_err(io(&folder))?;
        for (image, png) in images.iter().zip(&pngs) {
            if let (Some(image), Some(png)) = (image, png) {
                write_atomic(&dir.join(image), png)?;
            }
        }
    }
    Ok(md)
}

/// Each figure as a PNG (`None` for a plot that cannot be drawn: the report says so and goes
/// on).
fn render_pngs(figures: &[Figure]) -> Vec<Option<Vec<u8>>> {
    figures
        .iter()
        .map(|f| {
            plots::png(&f.chart)
                .map_err(|e| tracing::warn!("report figure {}: {e}", f.id))
                .ok()
        })
        .collect()
}

/// Reads a run folder's manifest and results and writes its report and `results.csv` again;
/// returns the Markdown's path, and a note when `force` rendered a `results.json` that no longer
/// matches the manifest's hash (the manifest then records the new hashes of it, of
/// `results.csv` and of both reports). A `results.csv` the manifest does not list yet (a run
/// folder from before it) is recorded too.
/// Without `force` such a `results.json` is refused: the report would not show what the run
/// recorded, and the manifest's hashes would be false from then on.
pub fn rewrite(dir: &Path, force: bool) -> Result<(PathBuf, Option<String>), CampaignError> {
    use super::manifest::FileRecord;
    use super::run::RESULTS_FILE;
    let mut manifest = Manifest::load(dir)?;
    let changed = manifest
        .files
        .iter()
        .find(|f| f.path == Path::new(RESULTS_FILE))
        .and_then(|f| f.check(dir));
    if let (Some(why), false) = (&changed, force) {
        return Err(CampaignError::Manifest {
            path: dir.join(RESULTS_FILE),
            message: format!(
                "{why}: a report from it would not show what the run recorded; pass --force to \
                 render it anyway and record its new hash (and the reports') in the manifest"
            ),
        });
    }
    let results = load_results(dir)?;
    let md = write(dir, &manifest, &results)?;
    // results.csv is results.json flat: written again with the report. A run folder from
    // before results.csv gets one, and the manifest records it.
    let csv = super::results::CSV_FILE;
    write_atomic(&dir.join(csv), super::results::to_csv(&results).as_bytes())?;
    let csv_record = FileRecord::of(dir, Path::new(csv))?;
    let csv_new = !manifest.files.contains(&csv_record);
    let Some(why) = changed else {
        if csv_new {
            manifest.set_file(csv_record);
            manifest.store(dir)?;
        }
        return Ok((md, None));
    };
    for file in [RESULTS_FILE, csv, REPORT_FILE, HTML_FILE] {
        manifest.set_file(FileRecord::of(dir, Path::new(file))?);
    }
    manifest.store(dir)?;
    Ok((
        md,
        Some(format!(
            "{why}; rendered with --force, and the manifest now records the new SHA-256 of \
             results.json, results.csv, report.md and report.html"
        )),
    ))
}

/// A run folder's `results.json`. Missing, not text or not a campaign's: bad input (the
/// message says which).
pub fn load_results(dir: &Path) -> Result<Results, CampaignError> {
    let path = dir.join(super::run::RESULTS_FILE);
    let bad = |message: String| CampaignError::Manifest {
        path: path.clone(),
        message,
    };
    let bytes = match std::fs::read(&path) {
        Ok(b) => b,
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => {
            return Err(bad(
                "missing: a run folder holds results.json once its first step is done (is \
                 this a campaign's run folder?)"
                    .into(),
            ))
        }
        Err(e) => return Err(io(&path)(e)),
    };
    let text = String::from_utf8(bytes)
        .map_err(|e| bad(format!("not a campaign results.json: not UTF-8 text ({e})")))?;
    serde_json::from_str(&text).map_err(|e| bad(format!("not a campaign results.json: {e}")))
}

#[cfg(test)]
mod tests {
    #[test]
    fn a_small_deviation_keeps_two_significant_digits() {
        assert_eq!(
            super::markdown::pm(13.2641, Some(0.00112), 2),
            "13.2641 ± 0.0011"
        );
        assert_eq!(super::markdown::pm(13.2641, Some(0.5), 2), "13.26 ± 0.50");
        assert_eq!(super::markdown::pm(13.2641, Some(0.0), 2), "13.26 ± 0.00");
        assert_eq!(super::markdown::pm(13.2641, None, 1), "13.3");
    }
}
