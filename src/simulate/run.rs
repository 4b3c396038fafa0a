//! The simulation engine: transmit, echoes (optionally at the capture rate), noise, decimation,
//! range processing and metrics, over one or more Monte-Carlo trials.

use super::noise::add_noise;
use super::scene::EchoSynth;
use super::spec::{Algorithm, RunSpec, ScenarioResult, WaveformSpec};
use super::SimError;
use crate::dsp::decimate::PeriodicDecimator;
use crate::dsp::metrics::{
    find_peaks, interpolate_peak, resolve_targets, sidelobe_levels, width_3db, Interpolation,
};
use crate::dsp::music::root_music_ranges;
use crate::dsp::music::{ModelOrder, Music, MusicConfig, MusicSpectrum, OrderCriterion};
use crate::dsp::ofdm_radar::{IDiv, OfdmRadar, OfdmRadarConfig, RangeProfile};
use crate::dsp::range_profile::{music_profile, CorrelationProfiler, Profile};
use crate::dsp::C0;
use crate::rng::SplitMix64;
use crate::storage::plot::{Curve, ProfilePlot};
use crate::storage::profile::ProfileTable;
use crate::waveform::bits::BitSource;
use crate::waveform::msk_lfm::{MskLfm, MskLfmParams, PulseLength};
use crate::waveform::ofdm::{Ofdm, OfdmParams, SymbolMatrix};
use num_complex::Complex64;
use std::collections::BTreeMap;

/// Salt that separates the noise stream from the bit stream of one seed.
const NOISE_SALT: u64 = 0x4E4F_4953_4531_3233;

/// Minimum prominence of a peak, dB (the "resolved" rule of thesis-notes.md).
pub const MIN_PROMINENCE_DB: f64 = 3.0;

/// MUSIC pseudo-spectrum grid = this factor x subcarriers (12 800 points, 1.17 mm for the thesis'
/// OFDM): MUSIC peaks are far narrower than Fourier ones, and a 1280-point grid (1.17 cm) leaves
/// sub-sample interpolation errors of several millimetres.
pub const MUSIC_GRID_FACTOR: usize = 100;

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
        ProfilePlot {
            title: format!(
                "{}: {} {} (phase {}{})",
                spec.id,
                spec.waveform.name(),
                spec.algorithm.name(),
                spec.carrier,
                spec.snr_db
                    .map(|s| format!(", {s} dB/sample"))
                    .unwrap_or_default()
            ),
            curves: self
                .profiles
                .iter()
                .map(|p| Curve {
                    label: p.label.clone(),
                    range_m: p.ranges(),
                    db: p.normalised_db(),
                })
                .collect(),
            targets_m: spec.targets.iter().map(|t| t.range_m).collect(),
            window_m: None,
            floor_db: -60.0,
            reference_db: single.then_some(-3.0),
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

/// The transmitted signal and what the receivers need of it.
enum Transmit {
    MskLfm {
        samples: Vec<Complex64>,
    },
    Ofdm {
        samples: Vec<Complex64>,
        ofdm: Box<Ofdm>,
        symbols: SymbolMatrix,
    },
}

impl Transmit {
    fn new(w: &WaveformSpec, seed: u64) -> Result<Self, SimError> {
        let bits = BitSource::Prbs { seed };
        Ok(match *w {
            WaveformSpec::MskLfm {
                sample_rate_hz,
                bandwidth_hz,
                pulse_s,
                bits_per_pulse,
            } => {
                let gen = MskLfm::new(MskLfmParams {
                    sample_rate_hz,
                    bandwidth_hz,
                    pulse: PulseLength::Seconds(pulse_s),
                    bits_per_pulse,
                })?;
                Transmit::MskLfm {
                    samples: gen.generate(&bits, 1)?.samples,
                }
            }
            WaveformSpec::Ofdm {
                bandwidth_hz,
                subcarriers,
                oversampling,
                cp_fraction,
                symbols,
            } => {
                // Radar frames carry data on every symbol: no preamble needed, all are known.
                let ofdm = Ofdm::new(OfdmParams {
                    subcarriers,
                    bandwidth_hz,
                    oversampling,
                    cp_fraction,
                    symbols_per_frame: symbols,
                    preamble_symbols: 0,
                })?;
                let sig = ofdm.generate(&bits, 1)?;
                Transmit::Ofdm {
                    samples: sig.samples,
                    symbols: sig.symbols,
                    ofdm: Box::new(ofdm),
                }
            }
        })
    }

    fn samples(&self) -> &[Complex64] {
        match self {
            Transmit::MskLfm { samples } | Transmit::Ofdm { samples, .. } => samples,
        }
    }
}

/// Synthesis window: an OFDM frame is periodic (circular delay = continuous transmission); a pulse
/// gets room for the longest echo plus 2 m, rounded up to a multiple of 4096 (fast FFT sizes).
fn window_len(spec: &RunSpec, tx_len: usize) -> usize {
    match spec.waveform {
        WaveformSpec::Ofdm { .. } => tx_len,
        WaveformSpec::MskLfm { sample_rate_hz, .. } => {
            let far = spec.targets.iter().map(|t| t.range_m).fold(0.0, f64::max) + 2.0;
            let guard = (2.0 * far / C0 * sample_rate_hz).ceil() as usize;
            (tx_len + guard).div_ceil(4096) * 4096
        }
    }
}

/// What processing gives for one trial.
struct Analysis {
    /// Primary profile first (absent for grid-free estimators), then overlays.
    profiles: Vec<Profile>,
    /// Grid-free range estimates (root-MUSIC / ESPRIT).
    ranges: Option<Vec<f64>>,
    /// Peaks refined off the grid by the estimator itself (MUSIC), ascending.
    refined_peaks_m: Vec<f64>,
}

struct Processor {
    kind: ProcessorKind,
}

// One processor exists per simulation, so the size difference between the variants costs nothing.
#[allow(clippy::large_enum_variant)]
enum ProcessorKind {
    Correlation {
        correlator: Box<CorrelationProfiler>,
    },
    Ofdm {
        radar: Box<OfdmRadar>,
        tx_symbols: Vec<Complex64>,
        idiv: IDiv,
        profile: RangeProfile,
        /// MUSIC / root-MUSIC / ESPRIT estimator (absent for Fourier).
        music: Option<Box<Music>>,
        spectrum: MusicSpectrum,
        df_hz: f64,
    },
}

impl Processor {
    fn new(spec: &RunSpec, tx: &Transmit, window: usize) -> Result<Self, SimError> {
        let fs = spec.waveform.sample_rate_hz();
        let kind = match (spec.algorithm, tx) {
            (Algorithm::Correlation, _) => {
                let lags = match tx {
                    Transmit::MskLfm { samples } => window - samples.len() + 1,
                    Transmit::Ofdm { .. } => window / 2,
                };
                ProcessorKind::Correlation {
                    correlator: Box::new(CorrelationProfiler::new(tx.samples(), window, lags, fs)?),
                }
            }
            (_, Transmit::Ofdm { ofdm, symbols, .. }) => {
                let p = ofdm.params();
                let radar = OfdmRadar::new(OfdmRadarConfig {
                    subcarriers: p.subcarriers,
                    oversampling: p.oversampling,
                    cp_fraction: p.cp_fraction,
                    bandwidth_hz: p.bandwidth_hz,
                    zero_pad: spec.zero_pad,
                    window: spec.window.to_dsp(),
                    fft_precision: spec.fft_precision.to_dsp(),
                    ..OfdmRadarConfig::default()
                })?;
                let music = match spec.algorithm {
                    Algorithm::Music | Algorithm::RootMusic | Algorithm::Esprit => {
                        let m = spec.music_m;
                        let n = p.subcarriers;
                        if m < 2 || m > n {
                            return Err(SimError::Param {
                                field: "--m",
                                reason: format!(
                                    "M = {m}; allowed: 2..={n} (at most the subcarriers)"
                                ),
                            });
                        }
                        if let Some(order) = spec.music_p {
                            if order == 0 || order >= m {
                                return Err(SimError::Param {
                                    field: "--p",
                                    reason: format!("p = {order}; allowed: 1..{m} (below M)"),
                                });
                            }
                        }
                        Some(Box::new(Music::new(MusicConfig {
                            subcarriers: n,
                            subarray: m,
                            order: spec
                                .music_p
                                .map(ModelOrder::Fixed)
                                .unwrap_or(ModelOrder::Estimated(OrderCriterion::Mdl)),
                            forward_backward: spec.forward_backward,
                            grid_points: MUSIC_GRID_FACTOR * n,
                            bandwidth_hz: p.bandwidth_hz,
                        })?))
                    }
                    _ => None,
                };
                ProcessorKind::Ofdm {
                    music,
                    spectrum: MusicSpectrum::default(),
                    df_hz: ofdm.subcarrier_spacing_hz(),
                    radar: Box::new(radar),
                    tx_symbols: symbols.as_slice().to_vec(),
                    idiv: IDiv::new(),
                    profile: RangeProfile::new(),
                }
            }
            (alg, Transmit::MskLfm { .. }) => {
                return Err(SimError::Param {
                    field: "--algorithm",
                    reason: format!("{} needs OFDM; MSK-LFM uses 'correlation'", alg.name()),
                })
            }
        };
        Ok(Self { kind })
    }

    fn analyse(&mut self, rx: &[Complex64], spec: &RunSpec) -> Result<Analysis, SimError> {
        match &mut self.kind {
            ProcessorKind::Correlation { correlator } => Ok(Analysis {
                profiles: vec![correlator.profile(rx)?],
                ranges: None,
                refined_peaks_m: vec![],
            }),
            ProcessorKind::Ofdm {
                radar,
                tx_symbols,
                idiv,
                profile,
                music,
                spectrum,
                df_hz,
            } => {
                radar.process(rx, 0, tx_symbols, idiv, profile)?;
                let fourier = Profile {
                    label: format!("Fourier ({}-point IFFT)", profile.amplitude.len()),
                    axis: profile.axis(),
                    amplitude: profile.amplitude.clone(),
                };
                let Some(music) = music else {
                    return Ok(Analysis {
                        profiles: vec![fourier],
                        ranges: None,
                        refined_peaks_m: vec![],
                    });
                };
                let idiv = idiv.as_slice();
                match spec.algorithm {
                    Algorithm::Esprit => Ok(Analysis {
                        ranges: Some(music.esprit(idiv)?),
                        profiles: vec![fourier],
                        refined_peaks_m: vec![],
                    }),
                    Algorithm::RootMusic => {
                        music.estimate(idiv, spectrum)?;
                        Ok(Analysis {
                            ranges: Some(root_music_ranges(music, spectrum.order, *df_hz)?),
                            profiles: vec![fourier],
                            refined_peaks_m: vec![],
                        })
                    }
                    _ => {
                        music.estimate(idiv, spectrum)?;
                        let mp = music_profile(
                            &spectrum.range_m,
                            &spectrum.pseudo_spectrum,
                            spec.music_m,
                            spectrum.order,
                        );
                        Ok(Analysis {
                            profiles: vec![mp, fourier],
                            ranges: None,
                            refined_peaks_m: spectrum.peaks_m.clone(),
                        })
                    }
                }
            }
        }
    }
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

fn measure(analysis: &Analysis, spec: &RunSpec) -> TrialMetrics {
    let truth: Vec<f64> = spec.targets.iter().map(|t| t.range_m).collect();
    let interp = if spec.interpolate {
        Interpolation::ParabolicDb
    } else {
        Interpolation::None
    };
    if let Some(ranges) = &analysis.ranges {
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
    let is_music = spec.algorithm == Algorithm::Music;
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
        if !spec.interpolate {
            return x;
        }
        analysis
            .refined_peaks_m
            .iter()
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

/// Runs one scenario (all its trials) and returns its figures and first-trial profiles.
pub fn simulate(spec: &RunSpec) -> Result<SimOutcome, SimError> {
    spec.validate()?;
    let tx = Transmit::new(&spec.waveform, spec.seed)?;
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
    let window = window_len(spec, tx.samples().len());
    let up = spec.upsample();
    let synth = EchoSynth::new(tx.samples(), fs, window, up)?;
    let clean = synth.render(
        &spec.targets,
        spec.carrier.carrier_hz(spec.waveform.bandwidth_hz()),
    );
    let mut decimator = match up {
        1 => None,
        _ => Some(PeriodicDecimator::new(
            fs * up as f64,
            up,
            spec.waveform.bandwidth_hz() / 2.0,
        )?),
    };
    let mut processor = Processor::new(spec, &tx, window)?;
    let mut noise_rng = SplitMix64::new(spec.seed ^ NOISE_SALT);

    let mut first: Option<(TrialMetrics, Vec<Profile>)> = None;
    let mut trial_peaks = Vec::with_capacity(spec.trials);
    let mut resolved_count = 0usize;
    for _ in 0..spec.trials {
        let mut rx = clean.clone();
        add_noise(&mut rx, spec.snr_db, &mut noise_rng);
        let rx = match &mut decimator {
            Some(d) => d.decimate(&rx),
            None => rx,
        };
        let analysis = processor.analyse(&rx, spec)?;
        let metrics = measure(&analysis, spec);
        resolved_count += usize::from(metrics.resolved);
        trial_peaks.push(metrics.peaks_m.clone());
        if first.is_none() {
            first = Some((metrics, analysis.profiles));
        }
    }
    let (m, profiles) = first.ok_or_else(|| SimError::Param {
        field: "--trials",
        reason: "must be at least 1".into(),
    })?;
    let many = spec.trials > 1;
    let result = ScenarioResult {
        id: spec.id.clone(),
        waveform: spec.waveform.name(),
        algorithm: spec.algorithm.name(),
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
        trials: spec.trials,
        resolved_rate: many.then(|| resolved_count as f64 / spec.trials as f64),
        trial_peaks_m: many.then_some(trial_peaks),
        extra: match spec.waveform {
            WaveformSpec::Ofdm { .. } => BTreeMap::from([(
                "fft_precision".to_string(),
                serde_json::json!(spec.fft_precision),
            )]),
            WaveformSpec::MskLfm { .. } => BTreeMap::new(),
        },
    };
    Ok(SimOutcome { result, profiles })
}
