//! The detection stage of the pipeline: which peaks of a range profile are targets.
//!
//! Profile algorithms: peaks with >= 3 dB prominence that pass a CA-CFAR test, lie in the range
//! window and are not side-lobes of a stronger target. Subspace algorithms: their own estimates
//! (MUSIC's refined peaks, root-MUSIC's and ESPRIT's ranges) inside the range window.

use super::options::ProcessOptions;
use super::pipeline::RangeResult;
use super::MeasureError;
use crate::dsp::metrics::{find_peaks, interpolate_peak, CaCfar, Interpolation};
use crate::dsp::range_profile::Profile;
use crate::dsp::C0;
use num_complex::Complex64;
use serde::Serialize;

/// One detected target.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Detection {
    pub range_m: f64,
    /// Echo amplitude relative to a unit-gain path from AWG output to scope input, dB.
    pub level_db: f64,
    /// Height above the detection threshold, dB (absent for grid-free estimators).
    pub above_threshold_db: Option<f64>,
    /// The range of the profile cell that peaked, without sub-sample interpolation (absent for
    /// grid-free estimators).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub on_grid_m: Option<f64>,
}

/// What detection decided for one record.
#[derive(Debug, Clone, Default)]
pub struct DetectionReport {
    /// Targets, ascending range.
    pub targets: Vec<Detection>,
    /// Profile index of the strongest target (profile algorithms).
    pub strongest_index: Option<usize>,
}

/// Side-lobe mask margin: a peak within this of the mask of a stronger target is a side-lobe.
const SIDELOBE_MARGIN_DB: f64 = 3.0;

/// Detects the targets of one record's range processing.
pub fn detect(
    range: &RangeResult,
    options: &ProcessOptions,
) -> Result<DetectionReport, MeasureError> {
    let window = options.min_range_m..=options.max_range_m;
    let mut report = match &range.estimates_m {
        Some(ranges) => {
            let levels = range.profiles.last().expect("at least one profile");
            DetectionReport {
                targets: ranges
                    .iter()
                    .filter(|r| window.contains(*r))
                    .map(|&range_m| Detection {
                        range_m,
                        level_db: level_at(levels, range_m),
                        above_threshold_db: None,
                        on_grid_m: None,
                    })
                    .collect(),
                strongest_index: None,
            }
        }
        None => detect_profile(range.primary(), options)?,
    };
    report
        .targets
        .sort_by(|a, b| a.range_m.total_cmp(&b.range_m));
    Ok(report)
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

/// Peaks with >= 3 dB prominence that pass the CFAR test, lie in the range window and are not
/// side-lobes of a stronger target.
fn detect_profile(p: &Profile, options: &ProcessOptions) -> Result<DetectionReport, MeasureError> {
    let amp = &p.amplitude;
    let db: Vec<f64> = amp.iter().map(|a| 20.0 * a.max(1e-300).log10()).collect();
    let power: Vec<f64> = amp.iter().map(|a| a * a).collect();
    // Training cells span several resolution cells so a target's own main lobe does not mask it.
    let cells_per_resolution = ((C0 / 2e9) / p.axis.step).max(1.0);
    let guard = (2.0 * cells_per_resolution).ceil() as usize;
    let training = (8.0 * cells_per_resolution).ceil() as usize;
    let mut cfar = CaCfar::new(guard, training, options.pfa)?;
    let mut thresholds = vec![0.0; power.len()];
    cfar.detect(&power, &mut thresholds)?;
    let window = options.min_range_m..=options.max_range_m;
    let mut candidates: Vec<(usize, f64, f64)> = find_peaks(&db, 3.0)
        .into_iter()
        .filter_map(|pk| {
            let range = p.axis.at(pk.index as f64);
            let above = 10.0 * (power[pk.index] / thresholds[pk.index]).log10();
            (window.contains(&range) && above > 0.0).then_some((pk.index, pk.value, above))
        })
        .collect();
    candidates.sort_by(|a, b| b.1.total_cmp(&a.1));
    let mut kept: Vec<(usize, f64, f64)> = Vec::new();
    for c in candidates {
        let masked = kept.iter().any(|k| {
            let cells = (c.0 as f64 - k.0 as f64).abs() / cells_per_resolution;
            let mask = if cells < 1.0 {
                0.0
            } else {
                -20.0 * (std::f64::consts::PI * cells).log10()
            };
            c.1 < k.1 + mask + SIDELOBE_MARGIN_DB
        });
        if !masked {
            kept.push(c);
        }
    }
    let interp = if options.interpolate {
        Interpolation::ParabolicDb
    } else {
        Interpolation::None
    };
    let strongest_index = kept.first().map(|k| k.0);
    let targets = kept
        .iter()
        .map(|&(index, _, above)| {
            let (x, height) = interpolate_peak(amp, index, interp);
            Detection {
                range_m: p.axis.at(x),
                level_db: 20.0 * height.max(1e-300).log10(),
                above_threshold_db: Some(above),
                on_grid_m: Some(p.axis.at(index as f64)),
            }
        })
        .collect();
    Ok(DetectionReport {
        targets,
        strongest_index,
    })
}

/// A peak's height over the profile's median power, dB.
pub fn peak_over_median_db(amplitude: &[f64], height: f64) -> f64 {
    let mut sorted: Vec<f64> = amplitude.iter().map(|a| a * a).collect();
    sorted.sort_by(f64::total_cmp);
    let median = sorted
        .get(sorted.len() / 2)
        .copied()
        .unwrap_or(0.0)
        .max(1e-300);
    10.0 * (height * height / median).log10()
}

/// Why a capture may show no target, from what it holds.
pub fn no_target_hint(rx: &[Complex64], profile: &Profile) -> String {
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
             transmitter and receiver are enabled (pass --allow-rf; a --tx-off capture measures \
             the noise floor), that the AWG outputs I/Q, and that the antennas face the target",
            rms * 1e3
        )
    } else {
        format!(
            "no target found in the range window: the strongest echo is outside it or below the \
             CFAR threshold (peak {contrast_db:.1} dB over the median). Check --min-range/--max-range \
             and the calibration"
        )
    }
}
