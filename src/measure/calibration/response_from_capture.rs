//! A response calibration measured from a saved capture of one reference pillar (`radbench process
//! --calibration CAPTURE --reference-range R`): an archive recorded before calibration existed,
//! or by another tool, corrected the same way as a bench calibration. Without a capture taken
//! with the transmitter off, the DC and the receiver's I/Q imbalance are not measured (left at
//! zero); the response is.

use super::response::{measure, Calibration};
use super::response_run::{try_correction, CalibrateRequest, Calibrated};
use crate::measure::bench::station::Identities;
use crate::measure::error::MeasureError;
use crate::measure::processing::choices::ProcessOverrides;
use crate::measure::processing::pipeline::Aligned;
use crate::measure::records::reprocess::{self, WaveformChoice};
use std::path::Path;

/// Measures the response from the capture at `capture` (a reference pillar at
/// `reference_range_m`) and stores it as `out` (a .toml header, its table beside it).
pub(crate) fn calibrate_from_capture(
    capture: &Path,
    reference_range_m: f64,
    gate_s: f64,
    out: &Path,
) -> Result<Calibration, MeasureError> {
    let bad = |reason: String| MeasureError::CalibrationFile {
        path: capture.display().to_string(),
        reason,
    };
    let source = reprocess::discover(&[capture.to_path_buf()])
        .into_iter()
        .next()
        .ok_or_else(|| bad("no capture there".into()))?
        .map_err(|e| bad(e.to_string()))?;
    let loaded = reprocess::load(&source, None)?;
    let overrides = ProcessOverrides {
        correction: Some(None),
        keep_background: true,
        ..ProcessOverrides::default()
    };
    let resolved = reprocess::resolve(&loaded, &WaveformChoice::default(), &overrides, None)?;
    let rate = loaded
        .repetitions
        .first()
        .map(|r| r.sample_rate_hz)
        .ok_or_else(|| bad("the recording holds no repetition".into()))?;
    let mut pipeline = reprocess::pipeline(&resolved, rate)?;
    let aligned = loaded
        .repetitions
        .iter()
        .map(|r| pipeline.align(r))
        .collect::<Result<Vec<Aligned>, MeasureError>>()?;
    let tx = resolved.tx.clone();
    let system_delay_s = resolved.options.system_delay_s;
    let request = CalibrateRequest {
        waveform: tx.spec,
        reference_range_m,
        repetitions: aligned.len(),
        gate_s,
        reflector_m: None,
    };
    let expected_delay_s = 2.0 * reference_range_m / crate::dsp::C0 + system_delay_s;
    let response = measure(
        &tx.reference,
        tx.sample_rate_hz(),
        &super::response_run::repetitions(&aligned),
        &[],
        expected_delay_s,
        gate_s,
        system_delay_s,
        None,
        &super::response::ResidualWindows {
            windows: &super::response_run::residual_windows(),
            band_hz: tx.band_hz(),
        },
    )?;
    let reference = try_correction(&mut pipeline, &response, &aligned, &request)?;
    let identities = loaded
        .radbench
        .get("instruments")
        .and_then(|v| serde_json::from_value::<Seen>(v.clone()).ok())
        .map(|s| Identities {
            awg: s.awg,
            scope: s.scope,
            tx: s.tx,
            rx: s.rx,
        })
        .unwrap_or_else(|| Identities {
            awg: "unknown (not recorded in the capture)".into(),
            scope: "unknown (not recorded in the capture)".into(),
            tx: None,
            rx: None,
        });
    let calibrated = Calibrated {
        request,
        response,
        reference,
        identities,
        system_delay_s,
    };
    if let Err(why) = calibrated.verdict() {
        return Err(MeasureError::CorrectionRefused(format!(
            "the reference capture {}: {why}; nothing was processed",
            capture.display()
        )));
    }
    calibrated.save(out)
}

/// The instruments a capture recorded (`radbench:instruments`).
#[derive(serde::Deserialize)]
struct Seen {
    awg: String,
    scope: String,
    #[serde(default)]
    tx: Option<String>,
    #[serde(default)]
    rx: Option<String>,
}
