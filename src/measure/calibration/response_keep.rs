//! What `calibrate response` does with a measured response, shared by the command and the warm
//! session (Python's `Bench.calibrate_response`): where it is stored, naming it in the bench
//! file, and the report as data.

use super::response::Calibration;
use super::response_run::Calibrated;
use crate::measure::bench::bench_file::{store_calibration, BenchCalibration};
use crate::measure::bench::in_use::Bench;
use crate::measure::error::MeasureError;
use serde_json::{json, Value};
use std::path::{Path, PathBuf};

/// `--gate-ns` checked: a half-width in ns, 0.5 to 50.
pub fn check_gate_ns(gate_ns: Option<f64>) -> Result<(), MeasureError> {
    match gate_ns {
        Some(ns) if !(ns.is_finite() && (0.5..=50.0).contains(&ns)) => Err(MeasureError::option(
            "gate-ns",
            ns,
            "a half-width in ns, 0.5 to 50 (about the chain's longest echo, a few ns)",
        )),
        _ => Ok(()),
    }
}

/// `--out` checked: the header's name ends in `.toml` (the table goes beside it as `.npy`).
pub fn check_response_out(out: Option<&Path>) -> Result<(), MeasureError> {
    match out {
        Some(out) if out.extension().and_then(|e| e.to_str()) != Some("toml") => {
            Err(MeasureError::option(
                "out",
                out.display(),
                "a file name ending in .toml (the table is written beside it as .npy)",
            ))
        }
        _ => Ok(()),
    }
}

/// The gate asked for (ns), or the default for the reference's range; seconds.
pub fn gate_or_default_s(gate_ns: Option<f64>, reference_range_m: f64) -> f64 {
    gate_ns.map_or_else(
        || crate::measure::calibration::delay::default_gate_s(reference_range_m),
        |ns| ns * 1e-9,
    )
}

/// Where the response is stored: `out`, else `<bench stem>-response.toml` beside the bench
/// file; the built-in mock lab's (no bench file, no `out`) is not stored.
pub fn response_path(out: Option<&Path>, bench: &Bench) -> Option<PathBuf> {
    out.map(Path::to_path_buf).or_else(|| {
        bench.path.as_deref().map(|b| {
            let stem = b.file_stem().and_then(|s| s.to_str()).unwrap_or("bench");
            b.with_file_name(format!("{stem}-response.toml"))
        })
    })
}

/// Writes the calibration to `path` and names it in the bench file's `[calibration]` section
/// (keeping the delay and every other line), so the bench's later captures use it.
pub fn store_response(
    calibrated: &Calibrated,
    path: &Path,
    bench: &mut Bench,
) -> Result<Calibration, MeasureError> {
    let stored = calibrated.save(path)?;
    if let Some(bench_path) = bench.path.clone() {
        let mut cal = bench.file.calibration.clone().unwrap_or(BenchCalibration {
            system_delay_s: 0.0,
            reference_range_m: None,
            measured_at: None,
            response: None,
        });
        cal.response = Some(relative_to_bench(&bench_path, path));
        store_calibration(&bench_path, &cal)?;
        bench.file.calibration = Some(cal);
    }
    Ok(stored)
}

/// `calibration` as the bench file names it: relative to the bench file when beside it.
fn relative_to_bench(bench_path: &Path, calibration: &Path) -> String {
    let dir = match bench_path.parent() {
        Some(p) if !p.as_os_str().is_empty() => p,
        _ => Path::new("."),
    };
    let abs = std::fs::canonicalize(calibration).unwrap_or_else(|_| calibration.to_path_buf());
    let dir_abs = std::fs::canonicalize(dir).unwrap_or_else(|_| dir.to_path_buf());
    abs.strip_prefix(&dir_abs)
        .map(|p| p.display().to_string())
        .unwrap_or_else(|_| abs.display().to_string())
}

/// The report as `calibrate response --json` prints it.
pub fn response_report(
    calibrated: &Calibrated,
    stored: Option<&Calibration>,
    refused: Option<&str>,
) -> Value {
    let r = &calibrated.response;
    json!({
        "band_hz": r.band_hz,
        "figures": r.figures,
        "reference": calibrated.reference,
        "chain_echoes": r.chain_echoes,
        "scene_echoes": r.scene_echoes,
        "repetitions": calibrated.request.repetitions,
        "stored_in": stored.map(|c| c.path.display().to_string()),
        "sha256": stored.map(|c| c.sha256.clone()),
        "refused": refused,
    })
}
