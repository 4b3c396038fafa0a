//! The detection stage of the pipeline: which echoes of a record are targets.
//!
//! Correlation and Fourier profiles go through [`crate::dsp::detect`] with the waveform's exact
//! point spread (CLEAN by default: every target is fitted and subtracted, so side-lobes never
//! become targets and a weak target under them is found; docs/detection.md). The subspace
//! algorithms give their own estimates (MUSIC's refined peaks, root-MUSIC's and ESPRIT's ranges),
//! kept inside the range window.

use super::options::ProcessOptions;
use super::range_result::RangeResult;
use crate::dsp::Profile;
use crate::dsp::{DetectOptions, DetectedTarget, Detector, PointSpread, Sidelobes};
use crate::measure::error::MeasureError;
use num_complex::Complex64;
use serde::Serialize;

/// A phase range as a campaign's next step takes it, m: the range and its uncertainty, and the
/// envelope's range (against the calibration's reference) and uncertainty that unwrapping saw.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct PhaseRanged {
    pub(crate) range_m: f64,
    pub(crate) std_m: f64,
    pub(crate) envelope_m: f64,
    pub(crate) envelope_std_m: f64,
}

/// One detected target.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Detection {
    /// Range from the antennas, m (sub-sample interpolated unless `--no-interpolation`).
    pub range_m: f64,
    /// Its standard uncertainty, m: the SNR's, the trigger jitter left, the calibration's
    /// (`measure::ranging`, docs/metrology.md); absent where the SNR is unknown.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub range_std_m: Option<f64>,
    /// Echo amplitude relative to a unit-gain path from AWG output to scope input, dB.
    pub level_db: f64,
    /// Height above the detection threshold, dB (absent for the subspace estimators).
    pub above_threshold_db: Option<f64>,
    /// The profile cell nearest to the target, m (no sub-sample interpolation; absent for the
    /// grid-free estimators).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub on_grid_m: Option<f64>,
    /// Echo power over the noise power per profile cell, dB: the noise measured beside the
    /// waveform's band, where none of the signal is (`Pipeline::process`); absent when the
    /// record leaves no room beside the band or the algorithm gives no complex profile.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub snr_db: Option<f64>,
    /// Echo power over the detector's residual floor per cell (what CLEAN leaves away from the
    /// targets: noise, and where the point spread is not the bench's, the model's misfit), dB.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub peak_to_floor_db: Option<f64>,
    /// -3 dB width of the target's own response (the profile minus every other target), cm.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub width_3db_cm: Option<f64>,
    /// Peak side-lobe level of the target's own response, dB (absent when not meaningful: see
    /// `sidelobe_note`).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub sidelobe_db: Option<f64>,
    /// Why the side-lobe level is not given (another target shares the side-lobe region, the
    /// side-lobes are under the noise, ...).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub sidelobe_note: Option<String>,
    /// Radial velocity (range rate, positive = receding), m/s: OFDM frames of several symbols.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub velocity_mps: Option<f64>,
    /// How a `--ranging phase` range was unwrapped: `phase` (by its envelope), `phase-previous`
    /// (by a campaign's previous step); absent for an envelope range (every range in envelope
    /// mode, and a target that kept its envelope range, with a warning saying why).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub ranging: Option<&'static str>,
    /// The phase range as a campaign's next step unwraps against it.
    #[serde(skip)]
    pub(crate) phase_ranged: Option<PhaseRanged>,
    /// Fractional profile cell of the target (for the payload receiver and plots).
    #[serde(skip)]
    pub cell: Option<f64>,
    /// The fit: sub-cell range (m, whatever `--no-interpolation` reports) and complex amplitude
    /// on the profile's scale (absent for the subspace estimators). A clipped capture's
    /// distortion is modelled from it.
    #[serde(skip)]
    pub(crate) fitted: Option<(f64, Complex64)>,
}

/// What detection decided for one record.
#[derive(Debug, Clone, Default)]
pub struct DetectionReport {
    /// Targets inside the range window, ascending range.
    pub targets: Vec<Detection>,
    /// Index in `targets` of the strongest.
    pub strongest: Option<usize>,
    /// Reflectors fitted outside the range window (the Tx -> Rx leakage near 0 m, ...).
    pub outside: Vec<Detection>,
    /// The detection threshold per cell of the primary profile, as an amplitude on the profile's
    /// scale (empty for the subspace estimators).
    pub threshold: Vec<f64>,
    /// What is left of the primary profile once every fitted target (leakage included) is
    /// subtracted, as an amplitude (empty for the subspace estimators): the threshold applies to
    /// it.
    pub residual: Vec<f64>,
    /// The same residual as complex values and the profile's axis: phase ranging seeks the
    /// leakage in it (CLEAN keeps a weak one as part of a strong target's response).
    pub(crate) residual_complex: Vec<Complex64>,
    pub(crate) axis: Option<crate::dsp::Axis>,
    /// Noise power per profile cell, dB (on the profile's scale).
    pub noise_db: Option<f64>,
    /// The detector stopped at its most targets: there may be more.
    pub capped: bool,
    /// The velocity resolution of the targets' `velocity_mps` (OFDM frames), m/s.
    pub velocity_resolution_mps: Option<f64>,
    /// Detections that sit where a known chain echo of a stronger target falls: not targets.
    pub chain_echoes: Vec<ChainEcho>,
    /// The detector's point spread, to rebuild the fitted echoes' model ([`Self::profile_near`]).
    pub(crate) spread: Option<FittedSpread>,
}

/// The point spread CLEAN fitted with and its first null, cells (`Debug` without its table).
#[derive(Clone)]
pub(crate) struct FittedSpread(pub(crate) std::sync::Arc<dyn PointSpread>, pub(crate) f64);

impl std::fmt::Debug for FittedSpread {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str("FittedSpread")
    }
}

impl DetectionReport {
    /// The profile over `within` (m) less the echoes fitted farther than `apart_m` from it: the
    /// residual with every echo CLEAN fitted near `within` added back, however it split them.
    /// Two echoes closer than a resolution cell (the leakage and a mount beside the horns) are
    /// fitted as one in one record and as two in the next; the profile they make is the same in
    /// both. Returns the first cell and the values; `None` without a complex profile.
    pub(crate) fn profile_near(
        &self,
        within: std::ops::RangeInclusive<f64>,
        apart_m: f64,
    ) -> Option<(usize, Vec<Complex64>)> {
        let (axis, spread) = (self.axis?, self.spread.as_ref()?);
        let r = &self.residual_complex;
        let cell = |m: f64| (m - axis.start) / axis.step;
        // A cell beyond each end, for a peak's neighbours at the ends.
        let lo = (cell(*within.start()).ceil() - 1.0).max(0.0);
        let hi = (cell(*within.end()).floor() + 1.0).min(r.len() as f64 - 1.0);
        if lo > hi {
            return None;
        }
        let (lo, hi) = (lo as usize, hi as usize);
        let mut view = r[lo..=hi].to_vec();
        let near = *within.start() - apart_m..=*within.end() + apart_m;
        let fitted = self
            .targets
            .iter()
            .chain(&self.outside)
            .chain(self.chain_echoes.iter().map(|e| &e.detection));
        for d in fitted {
            let (Some(x), Some((range_m, a))) = (d.cell, d.fitted) else {
                continue;
            };
            if near.contains(&range_m) {
                for (k, v) in view.iter_mut().enumerate() {
                    *v += a * spread.0.value((lo + k) as f64 - x);
                }
            }
        }
        Some((lo, view))
    }

    /// The one echo that best explains the profile near `within` (m), peaking there: its range
    /// (m) and complex amplitude, by the point spread's least-squares fit over its main lobe to
    /// [`Self::profile_near`] (the echoes fitted farther than `apart_m` left out). Fitting the
    /// profile rather than CLEAN's split of it gives the same echo in every record; fitting
    /// over the main lobe rather than reading the peak averages what lies under it.
    pub(crate) fn echo_near(
        &self,
        within: std::ops::RangeInclusive<f64>,
        apart_m: f64,
    ) -> Option<(f64, Complex64)> {
        let (axis, spread) = (self.axis?, self.spread.as_ref()?);
        let half = spread.1.ceil().max(1.0) as usize;
        let pad = half as f64 * axis.step;
        let (first, view) =
            self.profile_near(*within.start() - pad..=*within.end() + pad, apart_m)?;
        let peak = (0..view.len())
            .filter(|&k| within.contains(&axis.at((first + k) as f64)))
            .max_by(|&a, &b| view[a].norm_sqr().total_cmp(&view[b].norm_sqr()))?;
        let mut g = Vec::new();
        let fit = |x: f64, g: &mut Vec<Complex64>| {
            let lo = (x.round() as usize).saturating_sub(half).max(first);
            let hi = (x.round() as usize + half).min(first + view.len() - 1);
            g.resize(hi + 1 - lo, Complex64::default());
            spread.0.response(x, lo as isize, g);
            let (mut c, mut e) = (Complex64::default(), 0.0);
            for (k, gk) in g.iter().enumerate() {
                c += view[lo - first + k] * gk.conj();
                e += gk.norm_sqr();
            }
            (e > 0.0).then(|| (c.norm_sqr() / e, c / e))
        };
        // The best place on a tenth of a cell within a cell of the peak, then a parabola.
        let at = |i: i32| (first + peak) as f64 + 0.1 * f64::from(i);
        let scores: Vec<f64> = (-10..=10)
            .map(|i| fit(at(i), &mut g).map_or(f64::NEG_INFINITY, |f| f.0))
            .collect();
        let best = (1..scores.len() - 1).max_by(|&a, &b| scores[a].total_cmp(&scores[b]))?;
        let (l, c, h) = (scores[best - 1], scores[best], scores[best + 1]);
        let curvature = l - 2.0 * c + h;
        let offset = if curvature < 0.0 {
            (0.5 * (l - h) / curvature).clamp(-0.5, 0.5)
        } else {
            0.0
        };
        let x = at(best as i32 - 10) + 0.1 * offset;
        let (_, amplitude) = fit(x, &mut g)?;
        Some((axis.at(x), amplitude))
    }
}

/// A detection taken for a stronger target's chain echo (`"chain_echo": true`).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ChainEcho {
    #[serde(flatten)]
    pub detection: Detection,
    pub chain_echo: bool,
    /// The stronger target it follows, m, and the calibration's echo it matches: its delay (ns)
    /// and level (dB) behind every path.
    pub of_range_m: f64,
    pub echo_delay_ns: f64,
    pub echo_level_db: f64,
}

/// A detection this much stronger than a known chain echo of a stronger target would make it is
/// a target of its own, dB.
const CHAIN_ECHO_MARGIN_DB: f64 = 6.0;
/// ... and it must lie this close to where that echo falls, m (a third of a 1 GHz range cell).
const CHAIN_ECHO_SLACK_M: f64 = 0.05;

/// Moves the targets that sit at a known chain echo's offset behind a stronger target, no
/// stronger than that echo (plus [`CHAIN_ECHO_MARGIN_DB`]), from `targets` to `chain_echoes`.
/// `echoes` are (delay s, level dB) behind every path.
pub(crate) fn flag_chain_echoes(report: &mut DetectionReport, echoes: &[(f64, f64)]) {
    if echoes.is_empty() || report.targets.len() < 2 {
        return;
    }
    let targets = std::mem::take(&mut report.targets);
    let mut kept = Vec::with_capacity(targets.len());
    for t in &targets {
        let matched = targets.iter().find_map(|s| {
            echoes.iter().find_map(|&(delay_s, level_db)| {
                let behind_m = delay_s * crate::physics::C0 / 2.0;
                let at = (t.range_m - s.range_m - behind_m).abs() <= CHAIN_ECHO_SLACK_M;
                let weak = t.level_db <= s.level_db + level_db + CHAIN_ECHO_MARGIN_DB;
                (at && weak && s.level_db > t.level_db).then_some((s.range_m, delay_s, level_db))
            })
        });
        match matched {
            Some((of, delay_s, level_db)) => report.chain_echoes.push(ChainEcho {
                detection: t.clone(),
                chain_echo: true,
                of_range_m: of,
                echo_delay_ns: delay_s * 1e9,
                echo_level_db: level_db,
            }),
            None => kept.push(t.clone()),
        }
    }
    report.targets = kept;
    report.strongest = strongest(&report.targets);
}

/// The detector options of the processing options.
pub(crate) fn detect_options(options: &ProcessOptions) -> DetectOptions {
    DetectOptions {
        method: options.detector.to_dsp(),
        pfa: options.pfa,
        min_separation_m: options.min_separation_m,
        chain_floor_db: options.chain_floor_db,
        ..DetectOptions::default()
    }
}

fn detection(t: &DetectedTarget, axis_step: f64, interpolate: bool, start: f64) -> Detection {
    let on_grid = start + t.cell.round() * axis_step;
    Detection {
        range_m: if interpolate { t.range_m } else { on_grid },
        range_std_m: None,
        ranging: None,
        phase_ranged: None,
        level_db: t.level_db,
        above_threshold_db: Some(t.above_threshold_db),
        on_grid_m: Some(on_grid),
        snr_db: None,
        peak_to_floor_db: t.snr_db,
        width_3db_cm: t.width_3db_m.map(|w| w * 100.0),
        sidelobe_db: t.sidelobes.psl_db(),
        sidelobe_note: match t.sidelobes {
            Sidelobes::Measured { .. } => None,
            other => Some(other.reason()),
        },
        velocity_mps: None,
        cell: Some(t.cell),
        fitted: Some((t.range_m, t.amplitude)),
    }
}

/// Detects the targets of one record's range processing; `detector` serves the profile
/// algorithms (those with a complex profile).
pub(crate) fn detect(
    range: &RangeResult,
    options: &ProcessOptions,
    detector: Option<&mut Detector>,
) -> Result<DetectionReport, MeasureError> {
    let window = options.min_range_m..=options.max_range_m;
    let mut report = match (&range.estimates_m, &range.complex, detector) {
        (Some(ranges), _, _) => {
            let levels = range.profiles.last().expect("at least one profile");
            let targets: Vec<Detection> = ranges
                .iter()
                .filter(|r| window.contains(*r))
                .map(|&range_m| Detection {
                    range_m,
                    range_std_m: None,
                    ranging: None,
                    phase_ranged: None,
                    level_db: level_at(levels, range_m),
                    above_threshold_db: None,
                    on_grid_m: None,
                    snr_db: None,
                    peak_to_floor_db: None,
                    width_3db_cm: None,
                    sidelobe_db: None,
                    sidelobe_note: None,
                    velocity_mps: None,
                    cell: None,
                    fitted: None,
                })
                .collect();
            DetectionReport {
                targets,
                ..DetectionReport::default()
            }
        }
        (None, Some(z), Some(detector)) => {
            let axis = range.primary().axis;
            let spread = FittedSpread(detector.shared_psf(), detector.shape().first_null);
            let found = detector.detect(z, axis, window)?;
            let convert =
                |t: &DetectedTarget| detection(t, axis.step, options.interpolate, axis.start);
            DetectionReport {
                targets: found.targets.iter().map(convert).collect(),
                outside: found.outside.iter().map(convert).collect(),
                threshold: found.threshold,
                residual: found.residual.iter().map(|v| v.norm()).collect(),
                residual_complex: found.residual,
                axis: Some(axis),
                noise_db: found.noise_power.map(|p| 10.0 * p.max(1e-300).log10()),
                capped: found.capped,
                strongest: None,
                velocity_resolution_mps: None,
                chain_echoes: Vec::new(),
                spread: Some(spread),
            }
        }
        _ => {
            return Err(MeasureError::Worker(
                "the pipeline has no detector for this profile".into(),
            ))
        }
    };
    report
        .targets
        .sort_by(|a, b| a.range_m.total_cmp(&b.range_m));
    report.strongest = strongest(&report.targets);
    Ok(report)
}

/// The index of the strongest target.
pub(crate) fn strongest(targets: &[Detection]) -> Option<usize> {
    targets
        .iter()
        .enumerate()
        .max_by(|a, b| a.1.level_db.total_cmp(&b.1.level_db))
        .map(|(i, _)| i)
}

fn level_at(p: &Profile, range_m: f64) -> f64 {
    let idx = ((range_m - p.axis.start) / p.axis.step).round();
    let i = (idx.max(0.0) as usize).min(p.amplitude.len().saturating_sub(1));
    20.0 * p
        .amplitude
        .get(i)
        .copied()
        .unwrap_or(0.0)
        .max(1e-300)
        .log10()
}

/// Why a capture may show no target, from what it holds.
pub(crate) fn no_target_hint(rx: &[Complex64], profile: &Profile) -> String {
    let rms = (rx.iter().map(|v| v.norm_sqr()).sum::<f64>() / rx.len().max(1) as f64).sqrt();
    let max = profile.amplitude.iter().copied().fold(0.0, f64::max);
    let mut sorted = profile.amplitude.clone();
    sorted.sort_by(f64::total_cmp);
    let median = sorted
        .get(sorted.len() / 2)
        .copied()
        .unwrap_or(0.0)
        .max(1e-300);
    let contrast_db = 20.0 * (max / median).log10();
    if max == 0.0 {
        "no target found: the capture is all zeros after background subtraction; the background \
         holds the same samples (a simulated bench replays its noise when restarted with the same \
         seed), or the scope saw nothing"
            .to_string()
    } else if contrast_db < 15.0 {
        format!(
            "no target found: the range profile is flat (peak {contrast_db:.1} dB over its median, \
             capture RMS {:.2} mV), so the capture looks like noise only. Check that the \
             transmitter and receiver were on (a capture made with --allow-rf, without --tx-off, \
             which measures the noise floor), that the AWG outputs I/Q, and that the antennas \
             face the target",
            rms * 1e3
        )
    } else {
        format!(
            "no target found in the range window: the strongest echo is outside it or below the \
             detection threshold (peak {contrast_db:.1} dB over the median). Check \
             --min-range/--max-range and the calibration"
        )
    }
}
