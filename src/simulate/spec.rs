//! What one simulation asks for ([`RunSpec`]) and what it reports ([`ScenarioResult`], the JSON
//! schema documented in docs/simulate-json.md).

use super::scene::{CarrierPhase, Target};
use super::SimError;
/// The processing choices a run spec names (defined in `crate::measure::processing::options`).
pub use crate::measure::{Algorithm, FftPrecisionName, ProcessOptions, WindowName};
/// The waveform a run transmits (defined in `crate::waveform::spec`).
pub use crate::waveform::WaveformSpec;
use serde::Serialize;
use std::collections::BTreeMap;

/// Most Monte-Carlo trials of one run.
pub(crate) const MAX_TRIALS: usize = 100_000;
/// Largest capture-to-waveform rate ratio simulated.
pub(crate) const MAX_UPSAMPLE: usize = 16;

/// One simulation: waveform, scene, processing, randomness.
#[derive(Debug, Clone, PartialEq)]
pub struct RunSpec {
    pub id: String,
    pub waveform: WaveformSpec,
    pub targets: Vec<Target>,
    /// Per-sample SNR at the capture rate for a unit-amplitude target; `None` = noise-free.
    pub snr_db: Option<f64>,
    /// How the echoes are processed: the same options a capture takes (`radbench process`). The
    /// range window, the bench delay and the carrier are the simulation's own
    /// ([`process_options`](super::run::process_options)).
    pub processing: ProcessOptions,
    pub carrier: CarrierPhase,
    /// Capture rate; `None` = process at the waveform rate. A multiple of the waveform rate runs the
    /// lab chain: echoes at the capture rate, noise there, then decimation to the waveform rate.
    pub capture_rate_hz: Option<f64>,
    pub seed: u64,
    pub trials: usize,
}

impl RunSpec {
    /// Defaults of `radbench simulate run`: physical phase, seed 1, one trial, noise-free. The
    /// waveform is simulated as a radar frame: every symbol carries data known to the radar (an
    /// OFDM frame without its preamble; the communication receiver is not simulated here).
    pub fn new(id: impl Into<String>, waveform: WaveformSpec, targets: Vec<Target>) -> Self {
        let waveform = crate::measure::processing::family::of(&waveform).as_simulated();
        Self {
            id: id.into(),
            processing: ProcessOptions::for_waveform(waveform.kind()),
            waveform,
            targets,
            snr_db: None,
            carrier: CarrierPhase::Physical,
            capture_rate_hz: None,
            seed: 1,
            trials: 1,
        }
    }

    /// Checks the combination of settings; the waveform and dsp layers check their own numbers.
    pub(crate) fn validate(&self) -> Result<(), SimError> {
        let bad = |field: &'static str, reason: String| Err(SimError::Param { field, reason });
        if self.targets.is_empty() {
            return bad(
                "--targets",
                "give at least one target, e.g. --targets 3".into(),
            );
        }
        if self.trials == 0 || self.trials > MAX_TRIALS {
            return bad(
                "--trials",
                format!("{}: allowed 1 ..= {MAX_TRIALS}", self.trials),
            );
        }
        if let Some(snr) = self.snr_db {
            if !snr.is_finite() {
                return bad("--snr-db", format!("{snr} is not a finite number of dB"));
            }
        }
        let max_range = self.max_range_m();
        for t in &self.targets {
            // An unusable waveform parameter (zero bandwidth, negative pulse) is reported by the
            // waveform layer with its own field name.
            if max_range.is_finite() && max_range > 0.0 && t.range_m >= max_range {
                return bad(
                    "--targets",
                    format!(
                        "range {} m is beyond what this {} waveform can simulate (below {max_range:.2} m: {})",
                        t.range_m,
                        self.waveform.name(),
                        self.waveform.max_range_reason()
                    ),
                );
            }
        }
        if let Some(rate) = self.capture_rate_hz {
            let fs = self.waveform.sample_rate_hz();
            let ratio = rate / fs;
            if ratio.is_finite() && ratio > MAX_UPSAMPLE as f64 {
                return bad(
                    "--capture-rate",
                    format!(
                        "{rate} Sa/s is {ratio:.0} times the waveform rate {fs} Sa/s; allowed at \
                         most {MAX_UPSAMPLE} times (80e9 for 16 GSa/s is the bench's 5)"
                    ),
                );
            }
            if !(rate.is_finite() && ratio >= 1.0 && (ratio - ratio.round()).abs() < 1e-9) {
                return bad(
                    "--capture-rate",
                    format!(
                        "{rate} Sa/s must be a whole multiple of the waveform rate {fs} Sa/s (e.g. 80e9 for 16 GSa/s)"
                    ),
                );
            }
        }
        Ok(())
    }

    /// Ranges this waveform can simulate: MSK-LFM, an echo delay below one pulse length; OFDM, the
    /// unambiguous range `c0 / (2 df)` (19.2 m by default).
    pub(crate) fn max_range_m(&self) -> f64 {
        self.waveform.max_range_m()
    }

    /// OFDM: ranges beyond which the echo delay exceeds the cyclic prefix (inter-symbol
    /// interference); `None` for MSK-LFM.
    pub(crate) fn cp_range_m(&self) -> Option<f64> {
        self.waveform.cp_range_m()
    }

    /// Capture-to-waveform rate ratio (1 when processing at the waveform rate).
    pub fn upsample(&self) -> usize {
        match self.capture_rate_hz {
            Some(rate) => (rate / self.waveform.sample_rate_hz()).round() as usize,
            None => 1,
        }
    }
}

/// One scenario's figures: the JSON schema of `radbench simulate --json` (docs/simulate-json.md).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ScenarioResult {
    pub id: String,
    pub waveform: &'static str,
    pub algorithm: &'static str,
    pub carrier_phase: CarrierPhase,
    pub snr_db: Option<f64>,
    pub capture_rate_hz: f64,
    pub seed: u64,
    pub targets_m: Vec<f64>,
    /// The strongest detected peaks (one per target at most), sorted by range (first trial).
    pub peaks_m: Vec<f64>,
    /// Per target: nearest detected peak minus true range, cm (`null` when nothing is near).
    pub errors_cm: Vec<Option<f64>>,
    /// Interpolated -3 dB width of the strongest peak (single target, profile algorithms).
    pub width_3db_cm: Option<f64>,
    /// Peak side-lobe level relative to the peak (single target, profile algorithms).
    pub sidelobe_db: Option<f64>,
    /// Every target found (resolved rule of thesis-notes.md) in the first trial.
    pub resolved: bool,
    /// Range-profile bin spacing in metres (`null` for grid-free estimators).
    pub range_bin_m: Option<f64>,
    pub trials: usize,
    /// The detector behind `detected_m` (`--detector`).
    pub detector: &'static str,
    /// What the pipeline's detector reported in the first trial, ascending range (m): the same
    /// detections `capture` would report on these samples.
    pub detected_m: Vec<f64>,
    /// Fraction of trials that resolved every target (only with trials > 1).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub resolved_rate: Option<f64>,
    /// Peaks of every trial (only with trials > 1).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub trial_peaks_m: Option<Vec<Vec<f64>>>,
    /// Scenario-specific figures (thesis rows, BER, ...).
    #[serde(flatten)]
    pub extra: BTreeMap<String, serde_json::Value>,
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn msk_lfm_refuses_ofdm_algorithms_naming_the_field() {
        let mut spec = RunSpec::new("x", WaveformSpec::msk_lfm_default(), vec![Target::at(3.0)]);
        spec.processing.algorithm = Algorithm::Music;
        let err = crate::simulate::simulate(&spec).err().unwrap().to_string();
        assert!(err.starts_with("--algorithm"), "{err}");
    }

    #[test]
    fn ranges_are_limited_by_the_waveform() {
        let spec = RunSpec::new("x", WaveformSpec::ofdm_default(), vec![Target::at(20.0)]);
        let err = spec.validate().unwrap_err().to_string();
        assert!(
            err.starts_with("--targets") && err.contains("19.19"),
            "{err}"
        );
        assert!((spec.cp_range_m().unwrap() - 4.797).abs() < 1e-3);
        let spec = RunSpec::new(
            "x",
            WaveformSpec::msk_lfm_default(),
            vec![Target::at(1600.0)],
        );
        assert!(spec.validate().is_err());
    }

    #[test]
    fn capture_rate_must_be_a_multiple() {
        let mut spec = RunSpec::new("x", WaveformSpec::msk_lfm_default(), vec![Target::at(3.0)]);
        spec.capture_rate_hz = Some(80e9);
        spec.validate().unwrap();
        assert_eq!(spec.upsample(), 5);
        spec.capture_rate_hz = Some(50e9);
        assert!(spec
            .validate()
            .unwrap_err()
            .to_string()
            .starts_with("--capture-rate"));
    }
}
