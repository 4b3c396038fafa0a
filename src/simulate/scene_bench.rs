//! `radbench simulate run --scene FILE`: the capture `radbench capture --allow-rf --scene FILE`
//! takes on the built-in mock lab, made in-process without instruments or sockets
//! ([`crate::measure::bench::scene_capture`]: the same transmission, instrument settings, synthesis,
//! scope ADC and pipeline), reported as a simulation: the capture's detections (`targets`, with
//! their levels) and, per scene target, the nearest detection.
//!
//! For the same scene file, waveform, `--seed` and processing options the detections are the
//! capture's; trial `k` is the lab's `k`-th capture (its noise generator carries on).

use super::run::SimOutcome;
use super::scene::Target;
use super::spec::{RunSpec, ScenarioResult};
use super::SimError;
use crate::dsp::C0;
use crate::measure::bench::scene_capture::SceneCapture;
use crate::measure::processing::family;
use crate::measure::CaptureRequest;
use crate::measure::ProcessOptions;
use crate::measure::Processed;
use crate::waveform::WaveformSpec;
use mock_lab::scene::Scene;

/// The capture's acquisition wait (`radbench capture --wait`, default 10 s): only checked.
const WAIT_S: f64 = 10.0;

/// What a scene simulation takes: what `capture --scene` takes, less the transports.
#[derive(Debug, Clone)]
pub struct SceneSpec {
    pub scene: Scene,
    /// The waveform as the capture sends it (OFDM keeps its preamble).
    pub waveform: WaveformSpec,
    /// Text to send (PRBS bits from `seed` when `None`).
    pub payload: Option<Vec<u8>>,
    /// Seed of the PRBS bits (`--seed`); the noise comes from the scene's own `seed`.
    pub seed: u64,
    /// The processing options with the capture's range window; the system delay is the lab's.
    pub options: ProcessOptions,
    /// Acquisitions, each processed alone.
    pub trials: usize,
}

/// A scene simulation: its figures and first-trial profiles, and the run they refer to.
pub struct SceneOutcome {
    pub outcome: SimOutcome,
    /// The `RunSpec` the figures refer to (the scene's targets; for plots and tables).
    pub spec: RunSpec,
}

/// Runs `spec`: prepares the lab's capture, then acquires and processes every trial.
pub fn simulate_scene(spec: &SceneSpec) -> Result<SceneOutcome, SimError> {
    if spec.trials == 0 || spec.trials > super::spec::MAX_TRIALS {
        return Err(SimError::Param {
            field: "--trials",
            reason: format!(
                "{}: allowed 1 ..= {} acquisitions",
                spec.trials,
                super::spec::MAX_TRIALS
            ),
        });
    }
    let request = CaptureRequest {
        waveform: spec.waveform,
        payload: spec.payload.clone(),
        seed: spec.seed,
        options: spec.options.clone(),
        tx_off: false,
        wait_s: WAIT_S,
        background: None,
    };
    let mut lab = SceneCapture::prepare(&spec.scene, &request)?;
    let run_spec = run_spec(spec, lab.options());
    let truth: Vec<f64> = run_spec.targets.iter().map(|t| t.range_m).collect();
    let cell_m = C0 / (2.0 * lab.transmission().bandwidth_hz());
    let mut first: Option<(Processed, Vec<Option<f64>>)> = None;
    let mut trial_peaks = Vec::with_capacity(spec.trials);
    let mut resolved_count = 0usize;
    for _ in 0..spec.trials {
        let processed = lab.acquire(&spec.scene)?;
        let found: Vec<f64> = processed.targets.iter().map(|t| t.range_m).collect();
        let matched = match_targets(&truth, &found, cell_m);
        resolved_count += usize::from(matched.iter().all(Option::is_some));
        trial_peaks.push(found);
        if first.is_none() {
            first = Some((processed, matched));
        }
    }
    let Some((processed, matched)) = first else {
        return Err(SimError::Param {
            field: "--trials",
            reason: "must be at least 1".into(),
        });
    };
    let many = spec.trials > 1;
    let mut extra = family::of(&spec.waveform).own_settings(&run_spec.processing);
    extra.insert("targets".into(), serde_json::json!(processed.targets));
    extra.insert("snr_profile_db".into(), serde_json::json!(processed.snr_db));
    extra.insert("warnings".into(), serde_json::json!(processed.warnings));
    extra.insert(
        "clipped_samples".into(),
        serde_json::json!(processed.clipping),
    );
    extra.insert(
        "system_delay_s".into(),
        serde_json::json!(spec.scene.system_delay_s),
    );
    extra.insert(
        "samples_per_repetition".into(),
        serde_json::json!(lab.period()),
    );
    extra.insert(
        "scene".into(),
        serde_json::to_value(&spec.scene).unwrap_or(serde_json::Value::Null),
    );
    let result = ScenarioResult {
        id: run_spec.id.clone(),
        waveform: spec.waveform.name(),
        algorithm: run_spec.processing.algorithm.name(),
        carrier_phase: run_spec.carrier,
        snr_db: Some(spec.scene.snr_db),
        capture_rate_hz: lab.capture_rate_hz(),
        seed: spec.seed,
        targets_m: truth.clone(),
        peaks_m: trial_peaks[0].clone(),
        errors_cm: matched
            .iter()
            .zip(&truth)
            .map(|(m, t)| m.map(|r| (r - t) * 100.0))
            .collect(),
        // The capture's figures of its strongest detection (summary.json's keys).
        width_3db_cm: processed.width_3db_cm,
        sidelobe_db: processed.sidelobe_db,
        resolved: matched.iter().all(Option::is_some),
        range_bin_m: processed.profiles.first().map(|p| p.axis.step),
        trials: spec.trials,
        detector: run_spec.processing.detector.name(),
        detected_m: trial_peaks[0].clone(),
        resolved_rate: many.then(|| resolved_count as f64 / spec.trials as f64),
        trial_peaks_m: many.then_some(trial_peaks),
        extra,
    };
    Ok(SceneOutcome {
        outcome: SimOutcome {
            result,
            profiles: processed.profiles,
        },
        spec: run_spec,
    })
}

/// Per true range, the detection nearest to it within half the distance to the nearest other
/// true range and within one resolution cell (`None`: missed).
fn match_targets(truth: &[f64], found: &[f64], cell_m: f64) -> Vec<Option<f64>> {
    truth
        .iter()
        .enumerate()
        .map(|(i, &r)| {
            let gap = truth
                .iter()
                .enumerate()
                .filter(|&(j, _)| j != i)
                .map(|(_, &o)| (o - r).abs() / 2.0)
                .fold(cell_m, f64::min);
            found
                .iter()
                .copied()
                .filter(|f| (f - r).abs() < gap)
                .min_by(|a, b| (a - r).abs().total_cmp(&(b - r).abs()))
        })
        .collect()
}

/// The figures' view of the scene: its targets as simulation targets, the capture's options.
fn run_spec(spec: &SceneSpec, options: &ProcessOptions) -> RunSpec {
    let targets = spec
        .scene
        .targets
        .iter()
        .map(|t| Target {
            range_m: t.range_m,
            amplitude: t.amplitude,
            velocity_mps: t.velocity_mps,
        })
        .collect();
    let mut run = RunSpec::new("run", spec.waveform, targets);
    // As sent (RunSpec::new drops OFDM's preamble for its own idealised frames).
    run.waveform = spec.waveform;
    run.processing = options.clone();
    run.snr_db = Some(spec.scene.snr_db);
    run.seed = spec.seed;
    run.trials = spec.trials;
    run
}
