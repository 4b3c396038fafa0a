//! Several marker-triggered repetitions of one measurement: their coherent average (processed as
//! the measurement's result) and the spread of what each repetition gives on its own.

use crate::measure::processing::clipping::Clipping;
use crate::measure::processing::detect::Detection;
use crate::measure::processing::payload::PayloadResult;
use crate::measure::processing::pipeline::{Aligned, Processed};
use num_complex::Complex64;
use serde::Serialize;

/// What one repetition gave, processed alone.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct RepetitionResult {
    pub targets: Vec<Detection>,
    pub width_3db_cm: Option<f64>,
    pub sidelobe_db: Option<f64>,
    pub snr_db: Option<f64>,
    pub payload: Option<PayloadResult>,
    /// This repetition's samples at the ADC's rails (captures of the scope's words).
    #[serde(rename = "clipped_samples", skip_serializing_if = "Option::is_none")]
    pub clipping: Option<Clipping>,
}

impl From<&Processed> for RepetitionResult {
    fn from(p: &Processed) -> Self {
        Self {
            targets: p.targets.clone(),
            width_3db_cm: p.width_3db_cm,
            sidelobe_db: p.sidelobe_db,
            snr_db: p.snr_db,
            payload: p.payload.clone(),
            clipping: p.clipping.clone(),
        }
    }
}

/// Mean and standard deviation (sample, n - 1) of the values present.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Stat {
    pub mean: f64,
    pub std: f64,
    /// How many repetitions had a value.
    pub n: usize,
}

impl Stat {
    pub fn of(values: impl IntoIterator<Item = f64>) -> Option<Stat> {
        let v: Vec<f64> = values.into_iter().filter(|x| x.is_finite()).collect();
        if v.is_empty() {
            return None;
        }
        let n = v.len();
        let mean = v.iter().sum::<f64>() / n as f64;
        let std = if n > 1 {
            (v.iter().map(|x| (x - mean) * (x - mean)).sum::<f64>() / (n - 1) as f64).sqrt()
        } else {
            0.0
        };
        Some(Stat { mean, std, n })
    }
}

/// One target of the averaged result, seen across the repetitions.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct TargetSpread {
    /// The averaged result's range.
    pub range_m: f64,
    /// The repetitions' own ranges for this target.
    pub range: Option<Stat>,
    pub level_db: Option<Stat>,
}

/// The spread of the repetitions.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Spread {
    pub repetitions: usize,
    pub targets: Vec<TargetSpread>,
    pub width_3db_cm: Option<Stat>,
    pub sidelobe_db: Option<Stat>,
    pub snr_db: Option<Stat>,
    /// Bit errors over every repetition's decoded data, and the bits.
    pub bit_errors: usize,
    pub bits: usize,
}

/// The coherent average of aligned repetitions (their sub-sample residuals averaged too).
pub(crate) fn average(records: &[Aligned]) -> Option<Aligned> {
    let first = records.first()?;
    let n = records.len() as f64;
    let mut samples = vec![Complex64::new(0.0, 0.0); first.samples.len()];
    for r in records {
        for (a, b) in samples.iter_mut().zip(&r.samples) {
            *a += b;
        }
    }
    for a in &mut samples {
        *a /= n;
    }
    Some(Aligned {
        samples,
        residual_s: records.iter().map(|r| r.residual_s).sum::<f64>() / n,
    })
}

/// Matches each target of the averaged result with the nearest detection of every repetition
/// within `tolerance_m` (half a resolution cell) and summarises.
pub(crate) fn spread(average: &[Detection], each: &[RepetitionResult], tolerance_m: f64) -> Spread {
    let targets = average
        .iter()
        .map(|t| {
            let matched: Vec<&Detection> = each
                .iter()
                .filter_map(|r| {
                    r.targets
                        .iter()
                        .filter(|d| (d.range_m - t.range_m).abs() <= tolerance_m)
                        .min_by(|a, b| {
                            (a.range_m - t.range_m)
                                .abs()
                                .total_cmp(&(b.range_m - t.range_m).abs())
                        })
                })
                .collect();
            TargetSpread {
                range_m: t.range_m,
                range: Stat::of(matched.iter().map(|d| d.range_m)),
                level_db: Stat::of(matched.iter().map(|d| d.level_db)),
            }
        })
        .collect();
    let payloads = each.iter().filter_map(|r| r.payload.as_ref());
    let (bit_errors, bits) = payloads.fold((0, 0), |(e, b), p| (e + p.bit_errors, b + p.bits));
    Spread {
        repetitions: each.len(),
        targets,
        width_3db_cm: Stat::of(each.iter().filter_map(|r| r.width_3db_cm)),
        sidelobe_db: Stat::of(each.iter().filter_map(|r| r.sidelobe_db)),
        snr_db: Stat::of(each.iter().filter_map(|r| r.snr_db)),
        bit_errors,
        bits,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn det(range_m: f64, level_db: f64) -> Detection {
        Detection {
            range_m,
            range_std_m: None,
            ranging: None,
            phase_ranged: None,
            level_db,
            above_threshold_db: Some(10.0),
            on_grid_m: None,
            snr_db: None,
            peak_to_floor_db: None,
            width_3db_cm: None,
            sidelobe_db: None,
            sidelobe_note: None,
            velocity_mps: None,
            cell: None,
            fitted: None,
        }
    }

    #[test]
    fn stat_is_the_sample_mean_and_deviation() {
        let s = Stat::of([1.0, 2.0, 3.0, f64::NAN]).unwrap();
        assert_eq!((s.mean, s.std, s.n), (2.0, 1.0, 3));
        assert_eq!(Stat::of([5.0]).unwrap().std, 0.0);
        assert!(Stat::of([]).is_none());
    }

    #[test]
    fn each_target_takes_the_nearest_detection_within_tolerance() {
        let rep = |ranges: &[f64]| RepetitionResult {
            targets: ranges.iter().map(|&r| det(r, -6.0)).collect(),
            width_3db_cm: Some(13.3),
            sidelobe_db: None,
            snr_db: None,
            payload: None,
            clipping: None,
        };
        let each = [rep(&[1.001, 1.3]), rep(&[0.999, 1.5]), rep(&[1.2])];
        let s = spread(&[det(1.0, -6.0), det(1.3, -10.0)], &each, 0.05);
        let r0 = s.targets[0].range.unwrap();
        assert_eq!(r0.n, 2);
        assert!((r0.mean - 1.0).abs() < 1e-12);
        assert_eq!(s.targets[1].range.unwrap().n, 1);
        assert_eq!(s.width_3db_cm.unwrap().n, 3);
    }

    #[test]
    fn the_average_is_coherent() {
        let a = Aligned {
            samples: vec![Complex64::new(1.0, 0.0); 4],
            residual_s: 1e-12,
        };
        let b = Aligned {
            samples: vec![Complex64::new(0.0, 1.0); 4],
            residual_s: 3e-12,
        };
        let m = average(&[a, b]).unwrap();
        assert_eq!(m.samples[0], Complex64::new(0.5, 0.5));
        assert!((m.residual_s - 2e-12).abs() < 1e-24);
    }
}
