//! The simulation engine: transmit, echoes (optionally at the capture rate), noise, decimation,
//! range processing and metrics, over one or more Monte-Carlo trials.

use super::noise::add_noise;
use super::scene::EchoSynth;
use super::spec::{Algorithm, RunSpec, ScenarioResult};
use super::SimError;
use crate::dsp::Profile;
use crate::dsp::C0;
use crate::dsp::{
    find_peaks, interpolate_peak, resolve_targets, sidelobe_levels, width_3db, Interpolation,
};
use crate::measure::processing::family;
use crate::measure::processing::pipeline::{Pipeline, RawIq, RecordGeometry};
use crate::measure::processing::range_result::RangeResult;
use crate::measure::processing::transmit::{Dac, Transmission};
use crate::measure::ProcessOptions;
use crate::rng::SplitMix64;
use crate::storage::profile::ProfileTable;
use crate::storage::{Curve, Marker, ProfilePlot};
use num_complex::Complex64;
use std::sync::Arc;

/// Salt that separates the noise stream from the bit stream of one seed.
const NOISE_SALT: u64 = 0x4E4F_4953_4531_3233;

/// Minimum prominence of a peak, dB (the "resolved" rule of thesis-notes.md).
pub(crate) const MIN_PROMINENCE_DB: f64 = 3.0;

/// A simulation's result and the profiles of its first trial (for plots and files).
#[derive(Debug, Clone)]
pub struct SimOutcome {
    pub result: ScenarioResult,
    /// Primary profile first, then overlays (Fourier under MUSIC), all on their own axes.
    pub profiles: Vec<Profile>,
}

impl SimOutcome {
    /// The profiles in dB against range, like the thesis' figures.
    pub fn plot(&self, spec: &RunSpec) -> ProfilePlot {
        let single = spec.targets.len() == 1 && !self.profiles.is_empty();
        // Detections sit on the primary profile's normalised curve.
        let markers = self
            .profiles
            .first()
            .map(|p| {
                let db = p.normalised_db();
                self.result
                    .detected_m
                    .iter()
                    .map(|&r| {
                        let i = ((r - p.axis.start) / p.axis.step).round();
                        let i = (i.max(0.0) as usize).min(db.len().saturating_sub(1));
                        Marker {
                            range_m: r,
                            db: db.get(i).copied().unwrap_or(0.0),
                            label: format!("{r:.3} m"),
                        }
                    })
                    .collect()
            })
            .unwrap_or_default();
        ProfilePlot {
            targets_m: spec.targets.iter().map(|t| t.range_m).collect(),
            markers,
            floor_db: Some(-60.0),
            reference_db: single.then_some(-3.0),
            ..ProfilePlot::new(
                format!(
                    "{}: {} {} (phase {}{})",
                    spec.id,
                    spec.waveform.name(),
                    spec.processing.algorithm.name(),
                    spec.carrier,
                    spec.snr_db
                        .map(|s| format!(", {s} dB/sample"))
                        .unwrap_or_default()
                ),
                self.profiles
                    .iter()
                    .map(|p| Curve::solid(p.label.clone(), p.ranges(), p.normalised_db()))
                    .collect(),
            )
        }
    }

    /// The profiles as a table: range then one dB column per profile sharing the first's axis.
    pub fn table(&self) -> ProfileTable {
        let Some(first) = self.profiles.first() else {
            return ProfileTable {
                range_m: vec![],
                columns: vec![],
            };
        };
        let columns = self
            .profiles
            .iter()
            .filter(|p| p.axis == first.axis && p.amplitude.len() == first.amplitude.len())
            .map(|p| (column_name(&p.label), p.normalised_db()))
            .collect();
        ProfileTable {
            range_m: first.ranges(),
            columns,
        }
    }
}

fn column_name(label: &str) -> String {
    let base = label.split(' ').next().unwrap_or("profile").to_lowercase();
    format!("{base}_db")
}

/// Synthesis window: an OFDM frame is periodic (circular delay = continuous transmission); a pulse
/// gets room for the longest echo plus 2 m, rounded up to a multiple of 4096 (fast FFT sizes).
fn window_len(spec: &RunSpec, tx_len: usize) -> usize {
    if family::of(&spec.waveform).is_periodic() {
        return tx_len;
    }
    let far = spec.targets.iter().map(|t| t.range_m).fold(0.0, f64::max) + 2.0;
    let guard = (2.0 * far / C0 * spec.waveform.sample_rate_hz()).ceil() as usize;
    (tx_len + guard).div_ceil(4096) * 4096
}

/// Metrics of one trial.
struct TrialMetrics {
    peaks_m: Vec<f64>,
    errors_cm: Vec<Option<f64>>,
    width_3db_cm: Option<f64>,
    sidelobe_db: Option<f64>,
    resolved: bool,
    range_bin_m: Option<f64>,
}

fn measure(analysis: &RangeResult, spec: &RunSpec) -> TrialMetrics {
    let truth: Vec<f64> = spec.targets.iter().map(|t| t.range_m).collect();
    let interp = if spec.processing.interpolate {
        Interpolation::ParabolicDb
    } else {
        Interpolation::None
    };
    let grid_free = spec.processing.algorithm.is_grid_free();
    if let (true, Some(ranges)) = (grid_free, &analysis.estimates_m) {
        // Grid-free: each target takes the nearest estimate within +-s/2 (s = nearest neighbour).
        let per_target: Vec<Option<f64>> = truth
            .iter()
            .enumerate()
            .map(|(i, &r)| {
                let half = half_window(&truth, i);
                ranges
                    .iter()
                    .copied()
                    .filter(|x| (x - r).abs() < half)
                    .min_by(|a, b| (a - r).abs().total_cmp(&(b - r).abs()))
            })
            .collect();
        return TrialMetrics {
            peaks_m: ranges.clone(),
            errors_cm: errors(&per_target, &truth),
            width_3db_cm: None,
            sidelobe_db: None,
            resolved: per_target.iter().all(Option::is_some),
            range_bin_m: None,
        };
    }
    let primary = &analysis.profiles[0];
    let amp = &primary.amplitude;
    let resolution = resolve_targets(primary.axis, amp, &truth, MIN_PROMINENCE_DB, interp);
    let db = primary.normalised_db();
    let mut peaks = find_peaks(&db, MIN_PROMINENCE_DB);
    peaks.sort_by(|a, b| b.value.total_cmp(&a.value));
    let mut peaks_m: Vec<f64> = peaks
        .iter()
        .take(truth.len())
        .map(|p| primary.axis.at(interpolate_peak(amp, p.index, interp).0))
        .collect();
    peaks_m.sort_by(f64::total_cmp);
    let is_music = spec.processing.algorithm == Algorithm::Music;
    let (width, psl) = match (truth.len(), peaks.first(), is_music) {
        (1, Some(top), false) => {
            let (_, height) = interpolate_peak(amp, top.index, Interpolation::ParabolicDb);
            let width = width_3db(amp, top.index, height).map(|w| w * primary.axis.step * 100.0);
            let psl = sidelobe_levels(amp, top.index, Interpolation::ParabolicDb).map(|s| s.psl_db);
            (width, psl)
        }
        _ => (None, None),
    };
    // Where the estimator refined its peaks off the grid (MUSIC), report those positions.
    let snap = |x: f64| {
        if !spec.processing.interpolate {
            return x;
        }
        analysis
            .estimates_m
            .iter()
            .flatten()
            .copied()
            .filter(|r| (r - x).abs() <= 2.0 * primary.axis.step)
            .min_by(|a, b| (a - x).abs().total_cmp(&(b - x).abs()))
            .unwrap_or(x)
    };
    let peaks_m: Vec<f64> = peaks_m.into_iter().map(snap).collect();
    let per_target: Vec<Option<f64>> = resolution.peaks.iter().map(|p| p.map(snap)).collect();
    TrialMetrics {
        peaks_m,
        errors_cm: errors(&per_target, &truth),
        width_3db_cm: width,
        sidelobe_db: psl,
        resolved: resolution.resolved,
        range_bin_m: Some(primary.axis.step),
    }
}

fn half_window(truth: &[f64], i: usize) -> f64 {
    truth
        .iter()
        .enumerate()
        .filter(|&(j, _)| j != i)
        .map(|(_, &o)| (o - truth[i]).abs())
        .fold(f64::INFINITY, f64::min)
        / 2.0
}

fn errors(found: &[Option<f64>], truth: &[f64]) -> Vec<Option<f64>> {
    found
        .iter()
        .zip(truth)
        .map(|(f, t)| f.map(|x| (x - t) * 100.0))
        .collect()
}

/// The processing options of a run: its choices, no range window but the synthesis window.
pub fn process_options(spec: &RunSpec) -> ProcessOptions {
    ProcessOptions {
        system_delay_s: 0.0,
        min_range_m: 0.0,
        max_range_m: spec.max_range_m().min(1e4),
        carrier_hz: crate::simulate::scene::BENCH_CARRIER_HZ,
        awg_amplitude_vpp: None,
        // A simulation's record has no trigger.
        trigger_jitter_s: Some(0.0),
        ..spec.processing.clone()
    }
}

/// The transmission of a run: the ideal (unquantised) waveform, as the thesis simulates it.
pub fn transmission(spec: &RunSpec) -> Result<Arc<Transmission>, SimError> {
    Ok(Arc::new(Transmission::new(
        &spec.waveform,
        None,
        spec.seed,
        Dac::Ideal,
    )?))
}

/// The pipeline of a run for records of `window` samples at the waveform rate.
pub fn pipeline(
    spec: &RunSpec,
    tx: Arc<Transmission>,
    window: usize,
) -> Result<Pipeline, SimError> {
    let lags = if family::of(&spec.waveform).is_periodic() {
        window / 2
    } else {
        window - tx.len() + 1
    };
    Ok(Pipeline::new(
        tx,
        process_options(spec),
        RecordGeometry {
            period: window,
            correlation_lags: lags,
        },
    )?)
}

/// The noise-free echoes of a run at its capture rate, and the synthesis window (samples at the
/// waveform rate).
pub fn echoes(spec: &RunSpec, tx: &Transmission) -> Result<(Vec<Complex64>, usize), SimError> {
    let fs = spec.waveform.sample_rate_hz();
    let window = window_len(spec, tx.len());
    let synth = EchoSynth::new(&tx.reference, fs, window, spec.upsample())?;
    let clean = synth.render(
        &spec.targets,
        spec.carrier.carrier_hz(spec.waveform.bandwidth_hz()),
    );
    Ok((clean, window))
}

/// The noise generator of a run (one stream for all its trials).
fn noise_source(spec: &RunSpec) -> SplitMix64 {
    SplitMix64::new(spec.seed ^ NOISE_SALT)
}

/// One trial's capture: the echoes plus the next noise of `rng`, at the capture rate, the marker
/// edge at the first sample.
fn noisy(spec: &RunSpec, clean: &[Complex64], rng: &mut SplitMix64) -> RawIq {
    let mut rx = clean.to_vec();
    add_noise(&mut rx, spec.snr_db, rng);
    RawIq {
        samples: rx,
        sample_rate_hz: spec.waveform.sample_rate_hz() * spec.upsample() as f64,
        first_point_s: 0.0,
    }
}

/// The capture of a run's first trial, exactly as [`simulate`] processes it (for checking that a
/// bench capture of the same samples gives the same result).
pub fn first_trial(spec: &RunSpec) -> Result<RawIq, SimError> {
    spec.validate()?;
    let tx = transmission(spec)?;
    let (clean, _) = echoes(spec, &tx)?;
    Ok(noisy(spec, &clean, &mut noise_source(spec)))
}

/// Runs one scenario (all its trials) and returns its figures and first-trial profiles.
pub fn simulate(spec: &RunSpec) -> Result<SimOutcome, SimError> {
    spec.validate()?;
    let tx = transmission(spec)?;
    if let Some(cp_range) = spec.cp_range_m() {
        if let Some(t) = spec.targets.iter().find(|t| t.range_m > cp_range) {
            tracing::warn!(
                "target at {} m: its echo is longer than the cyclic prefix (ranges above {cp_range:.2} m); \
                 inter-symbol interference will raise the floor",
                t.range_m
            );
        }
    }
    let fs = spec.waveform.sample_rate_hz();
    let up = spec.upsample();
    let (clean, window) = echoes(spec, &tx)?;
    let mut pipeline = pipeline(spec, tx, window)?;
    let mut noise_rng = noise_source(spec);

    let mut first: Option<(TrialMetrics, Vec<Profile>, Vec<f64>)> = None;
    let mut trial_peaks = Vec::with_capacity(spec.trials);
    let mut resolved_count = 0usize;
    for _ in 0..spec.trials {
        let raw = noisy(spec, &clean, &mut noise_rng);
        let aligned = pipeline.align(&raw)?;
        let analysis = pipeline.analyse(&aligned)?;
        let metrics = measure(&analysis.range, spec);
        resolved_count += usize::from(metrics.resolved);
        trial_peaks.push(metrics.peaks_m.clone());
        if first.is_none() {
            let detected = analysis
                .detection
                .targets
                .iter()
                .map(|t| t.range_m)
                .collect();
            first = Some((metrics, analysis.range.profiles, detected));
        }
    }
    let (m, profiles, detected_m) = first.ok_or_else(|| SimError::Param {
        field: "--trials",
        reason: "must be at least 1".into(),
    })?;
    let many = spec.trials > 1;
    let extra = family::of(&spec.waveform).own_settings(&spec.processing);
    let result = ScenarioResult {
        id: spec.id.clone(),
        waveform: spec.waveform.name(),
        algorithm: spec.processing.algorithm.name(),
        carrier_phase: spec.carrier,
        snr_db: spec.snr_db,
        capture_rate_hz: fs * up as f64,
        seed: spec.seed,
        targets_m: spec.targets.iter().map(|t| t.range_m).collect(),
        peaks_m: m.peaks_m,
        errors_cm: m.errors_cm,
        width_3db_cm: m.width_3db_cm,
        sidelobe_db: m.sidelobe_db,
        resolved: m.resolved,
        range_bin_m: m.range_bin_m,
        detector: spec.processing.detector.name(),
        detected_m,
        trials: spec.trials,
        resolved_rate: many.then(|| resolved_count as f64 / spec.trials as f64),
        trial_peaks_m: many.then_some(trial_peaks),
        extra,
    };
    Ok(SimOutcome { result, profiles })
}
