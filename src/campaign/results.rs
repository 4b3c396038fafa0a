//! `results.json`: what each step measured, per algorithm, and how far it is from where the targets
//! were put (and, on a simulated bench, from where they really were). Only measured numbers: no
//! times, no paths, so a resumed run's file equals an uninterrupted run's byte for byte.
//!
//! ```json
//! {"steps": [{"index": 1, "nominal": {...}, "repetitions": 1,
//!   "algorithms": {"correlation": {"targets": [{"range_m", "range_std_m", "range_uncertainty_m",
//!     "level_db", "on_grid_m"}],
//!     "width_3db_cm", "sidelobe_db", "snr_db", "error_m", "error_on_grid_m", "truth_error_m",
//!     "truth_error_on_grid_m", "missed", "resolved", "payload",
//!     "spread": {"width_3db_cm": {"mean", "std", "n"}, "sidelobe_db", "snr_db"}}},
//!   "truth": {"targets": [{"range_m"}]}}]}
//! ```
//!
//! Errors: each reference target (nominal, or the ground truth) takes the nearest detection within
//! one resolution cell c0/(2B) not taken by another; the step's error is the largest of those in
//! magnitude, sign kept; `missed` counts the nominal targets left without one. Two or more
//! targets are `resolved` when each has its own detection within +-s/2 (s: the smallest
//! separation), the thesis' rule, against the ground truth when it is known, else the nominal.

use super::plan::{Nominal, Range, Step};
use crate::measure::processing::payload::PayloadResult;
use crate::measure::Processed;
use crate::measure::Spread;
use crate::physics::C0;
use serde::{Deserialize, Serialize};
use serde_json::Value;
use std::collections::BTreeMap;

/// The whole file.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct Results {
    pub steps: Vec<StepResult>,
}

/// One step.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct StepResult {
    pub index: usize,
    pub nominal: Nominal,
    pub repetitions: usize,
    /// By algorithm name (`correlation`, `fourier`, `music`, `root-music`, `esprit`).
    pub algorithms: BTreeMap<String, AlgorithmResult>,
    /// The simulated scene of the capture (simulated benches only).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub truth: Option<Truth>,
}

/// The ground truth of a simulated capture.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Truth {
    pub targets: Vec<Range>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub snr_db: Option<f64>,
}

/// What one algorithm made of the step's captures.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct AlgorithmResult {
    /// Ascending range.
    pub targets: Vec<TargetResult>,
    /// Of the strongest target (null when none, or for the subspace algorithms).
    pub width_3db_cm: Option<f64>,
    pub sidelobe_db: Option<f64>,
    pub snr_db: Option<f64>,
    /// Measured minus nominal range, interpolated (the largest over the targets, sign kept).
    pub error_m: Option<f64>,
    /// The same on the profile's grid (no sub-cell interpolation).
    pub error_on_grid_m: Option<f64>,
    /// Measured minus the simulated ground truth.
    pub truth_error_m: Option<f64>,
    pub truth_error_on_grid_m: Option<f64>,
    /// Nominal targets without a detection within one resolution cell.
    pub missed: usize,
    /// Two or more targets: whether each has its own detection within +-s/2.
    pub resolved: Option<bool>,
    pub payload: Option<PayloadFigures>,
    /// Mean and standard deviation of the repetitions processed alone (several repetitions
    /// only; the figures above are the coherent average's).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub spread: Option<SpreadFigures>,
    /// Detections taken for a stronger target's chain echo (where the response calibration
    /// measured an echo behind every path): not among `targets` (absent when none, and in runs
    /// written before them).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub chain_echoes: Vec<ChainEchoResult>,
}

/// A detection taken for the chain's echo of a stronger target (the capture's `chain_echoes`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ChainEchoResult {
    pub range_m: f64,
    pub level_db: f64,
    /// The stronger target it follows, m.
    pub of_range_m: f64,
    /// The calibration's echo it matches: its delay (ns) and level (dB) behind every path.
    pub echo_delay_ns: f64,
    pub echo_level_db: f64,
}

impl ChainEchoResult {
    /// What the user reads of it (the capture's warning, in a line).
    pub fn describe(&self) -> String {
        format!(
            "the echo at {:.4} m ({:.1} dB) is taken for the chain's: it lies {:.1} ns behind the \
             target at {:.4} m, where the calibration measured an echo of every path at {:.1} dB",
            self.range_m, self.level_db, self.echo_delay_ns, self.of_range_m, self.echo_level_db
        )
    }
}

/// Mean, sample standard deviation (n - 1) and count of one figure over the repetitions.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct MeanStd {
    pub mean: f64,
    pub std: f64,
    pub n: usize,
}

/// The strongest target's figures over the repetitions, each processed alone.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SpreadFigures {
    pub width_3db_cm: Option<MeanStd>,
    pub sidelobe_db: Option<MeanStd>,
    pub snr_db: Option<MeanStd>,
}

impl From<crate::measure::Stat> for MeanStd {
    fn from(s: crate::measure::Stat) -> Self {
        Self {
            mean: s.mean,
            std: s.std,
            n: s.n,
        }
    }
}

/// One detected target.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct TargetResult {
    pub range_m: f64,
    /// Standard deviation of the repetitions' own ranges (several repetitions only).
    pub range_std_m: Option<f64>,
    /// The range's standard uncertainty (the detection's `range_std_m`: SNR, trigger jitter,
    /// calibration; docs/metrology.md).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub range_uncertainty_m: Option<f64>,
    pub level_db: f64,
    /// The nearest profile cell (absent for the grid-free estimators).
    pub on_grid_m: Option<f64>,
}

/// The decoded data of the step (every repetition counted).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct PayloadFigures {
    pub bit_errors: usize,
    pub bits: usize,
    pub ber: f64,
    /// Why the data could not be decoded.
    pub error: Option<String>,
    /// RMS error-vector magnitude of the data symbols, percent (the coherent average's).
    #[serde(default)]
    pub evm_rms_pct: Option<f64>,
    /// The 95th percentile of the symbols' EVM, percent.
    #[serde(default)]
    pub evm_p95_pct: Option<f64>,
    /// Modulation error ratio, dB.
    #[serde(default)]
    pub mer_db: Option<f64>,
}

/// What one algorithm gave, as the runner hands it over.
pub(crate) struct AlgorithmOutput<'a> {
    pub name: &'static str,
    pub processed: &'a Processed,
    pub spread: Option<&'a Spread>,
}

/// The ranges of a simulated scene's targets (ascending), from its JSON.
pub(crate) fn truth_of(scene: &Value) -> Truth {
    let mut ranges: Vec<f64> = scene["targets"]
        .as_array()
        .map(|t| t.iter().filter_map(|x| x["range_m"].as_f64()).collect())
        .unwrap_or_default();
    ranges.sort_by(f64::total_cmp);
    Truth {
        targets: ranges
            .into_iter()
            .map(|range_m| Range { range_m })
            .collect(),
        snr_db: scene["snr_db"].as_f64(),
    }
}

/// The result of one step.
pub(crate) fn step_result(
    step: &Step,
    bandwidth_hz: f64,
    repetitions: usize,
    ground_truth: Option<&Value>,
    outputs: &[AlgorithmOutput<'_>],
) -> StepResult {
    let truth = ground_truth.map(truth_of);
    let nominal = step.nominal.ranges();
    let truth_ranges: Option<Vec<f64>> = truth
        .as_ref()
        .map(|t| t.targets.iter().map(|r| r.range_m).collect());
    let cell = C0 / (2.0 * bandwidth_hz);
    let algorithms = outputs
        .iter()
        .map(|o| {
            let targets = target_results(o.processed, o.spread);
            let (error_m, error_on_grid_m, missed) = errors(&nominal, &targets, cell);
            let (truth_error_m, truth_error_on_grid_m) = match &truth_ranges {
                Some(t) => {
                    let (e, g, _) = errors(t, &targets, cell);
                    (e, g)
                }
                None => (None, None),
            };
            let reference = truth_ranges.as_deref().unwrap_or(&nominal);
            let result = AlgorithmResult {
                resolved: resolved(reference, &targets),
                width_3db_cm: o.processed.width_3db_cm,
                sidelobe_db: o.processed.sidelobe_db,
                snr_db: o.processed.snr_db,
                error_m,
                error_on_grid_m,
                truth_error_m,
                truth_error_on_grid_m,
                missed: if nominal.is_empty() { 0 } else { missed },
                payload: payload(o.processed.payload.as_ref(), o.spread),
                spread: o
                    .spread
                    .filter(|s| s.repetitions > 1)
                    .map(|s| SpreadFigures {
                        width_3db_cm: s.width_3db_cm.map(MeanStd::from),
                        sidelobe_db: s.sidelobe_db.map(MeanStd::from),
                        snr_db: s.snr_db.map(MeanStd::from),
                    }),
                chain_echoes: o
                    .processed
                    .detection
                    .chain_echoes
                    .iter()
                    .map(|e| ChainEchoResult {
                        range_m: e.detection.range_m,
                        level_db: e.detection.level_db,
                        of_range_m: e.of_range_m,
                        echo_delay_ns: e.echo_delay_ns,
                        echo_level_db: e.echo_level_db,
                    })
                    .collect(),
                targets,
            };
            (o.name.to_string(), result)
        })
        .collect();
    StepResult {
        index: step.index,
        nominal: step.nominal.clone(),
        repetitions,
        algorithms,
        truth,
    }
}

fn target_results(p: &Processed, spread: Option<&Spread>) -> Vec<TargetResult> {
    p.targets
        .iter()
        .enumerate()
        .map(|(k, t)| TargetResult {
            range_m: t.range_m,
            range_std_m: spread
                .and_then(|s| s.targets.get(k))
                .and_then(|s| s.range)
                .map(|r| r.std),
            range_uncertainty_m: t.range_std_m,
            level_db: t.level_db,
            on_grid_m: t.on_grid_m,
        })
        .collect()
}

/// Each reference, in order, takes the nearest detection within `tolerance` not taken by an
/// earlier one: the index of each reference's detection.
fn matches(reference: &[f64], targets: &[TargetResult], tolerance: f64) -> Vec<Option<usize>> {
    let mut taken = vec![false; targets.len()];
    reference
        .iter()
        .map(|&r| {
            let best = targets
                .iter()
                .enumerate()
                .filter(|(i, t)| !taken[*i] && (t.range_m - r).abs() <= tolerance)
                .min_by(|a, b| (a.1.range_m - r).abs().total_cmp(&(b.1.range_m - r).abs()))
                .map(|(i, _)| i);
            if let Some(i) = best {
                taken[i] = true;
            }
            best
        })
        .collect()
}

/// Each reference takes the nearest free detection within `tolerance` ([`matches`]); the
/// largest error (sign kept), on the grid too, and how many references found none.
fn errors(
    reference: &[f64],
    targets: &[TargetResult],
    tolerance: f64,
) -> (Option<f64>, Option<f64>, usize) {
    let mut worst: Option<f64> = None;
    let mut worst_grid: Option<f64> = None;
    let mut missed = 0;
    let larger = |a: Option<f64>, b: f64| match a {
        Some(x) if x.abs() >= b.abs() => Some(x),
        _ => Some(b),
    };
    for (&r, found) in reference.iter().zip(matches(reference, targets, tolerance)) {
        match found {
            Some(i) => {
                let t = &targets[i];
                worst = larger(worst, t.range_m - r);
                if let Some(g) = t.on_grid_m {
                    worst_grid = larger(worst_grid, g - r);
                }
            }
            None => missed += 1,
        }
    }
    (worst, worst_grid, missed)
}

/// The detections of `a` no nominal target of `step` takes (each takes the nearest within one
/// resolution cell c0/(2B), as `error_m` matches them) and no simulated true target either:
/// false targets, their ranges ascending. None when the step names no targets (nothing to
/// tell a false one by).
pub(crate) fn false_targets(step: &StepResult, a: &AlgorithmResult) -> Vec<f64> {
    let nominal = step.nominal.ranges();
    if nominal.is_empty() {
        return Vec::new();
    }
    let cell = C0 / (2.0 * step.nominal.bandwidth_hz);
    let truth: Vec<f64> = step
        .truth
        .as_ref()
        .map(|t| t.targets.iter().map(|r| r.range_m).collect())
        .unwrap_or_default();
    let by_nominal = matches(&nominal, &a.targets, cell);
    let by_truth = matches(&truth, &a.targets, cell);
    (0..a.targets.len())
        .filter(|i| !by_nominal.contains(&Some(*i)) && !by_truth.contains(&Some(*i)))
        .map(|i| a.targets[i].range_m)
        .collect()
}

/// `results.csv` in a run folder: `results.json` flat, for a spreadsheet or `pandas.read_csv`.
pub(crate) const CSV_FILE: &str = "results.csv";

/// The columns of `results.csv`, in order (docs/campaign.md says what each holds).
pub(crate) const CSV_COLUMNS: [&str; 28] = [
    "step",
    "label",
    "parameter",
    "value",
    "bandwidth_hz",
    "algorithm",
    "repetitions",
    "target",
    "nominal_m",
    "truth_m",
    "range_m",
    "range_std_m",
    "range_uncertainty_m",
    "on_grid_m",
    "level_db",
    "error_m",
    "error_on_grid_m",
    "truth_error_m",
    "truth_error_on_grid_m",
    "missed",
    "resolved",
    "width_3db_cm",
    "sidelobe_db",
    "snr_db",
    "bit_errors",
    "bits",
    "ber",
    "payload_error",
];

/// One row of `results.csv` before it is written: a reference target (nominal, ground truth)
/// and the detection matched to it, or a detection matched to none.
struct CsvTarget {
    nominal: Option<f64>,
    truth: Option<f64>,
    detection: Option<usize>,
}

/// The rows of one step and algorithm: every detection (with the nominal and true target
/// matched to it as `error_m` matches them), then every nominal target left without one
/// (missed), then every true target left without one; in ascending range. A step and
/// algorithm with neither targets nor detections still gets a row.
fn csv_targets(step: &StepResult, a: &AlgorithmResult) -> Vec<CsvTarget> {
    let cell = C0 / (2.0 * step.nominal.bandwidth_hz);
    let nominal = step.nominal.ranges();
    let truth: Vec<f64> = step
        .truth
        .as_ref()
        .map(|t| t.targets.iter().map(|r| r.range_m).collect())
        .unwrap_or_default();
    let by_nominal = matches(&nominal, &a.targets, cell);
    let by_truth = matches(&truth, &a.targets, cell);
    let find = |m: &[Option<usize>], refs: &[f64], i: usize| {
        m.iter().position(|x| *x == Some(i)).map(|k| refs[k])
    };
    let mut rows: Vec<CsvTarget> = (0..a.targets.len())
        .map(|i| CsvTarget {
            nominal: find(&by_nominal, &nominal, i),
            truth: find(&by_truth, &truth, i),
            detection: Some(i),
        })
        .collect();
    let mut truth_used: Vec<bool> = by_truth.iter().map(Option::is_some).collect();
    for (k, r) in nominal.iter().enumerate() {
        if by_nominal[k].is_some() {
            continue;
        }
        // The true target of a missed nominal one: the same place in the list, when both
        // lists are as long and it too found no detection.
        let t = (truth.len() == nominal.len() && !truth_used[k]).then(|| {
            truth_used[k] = true;
            truth[k]
        });
        rows.push(CsvTarget {
            nominal: Some(*r),
            truth: t,
            detection: None,
        });
    }
    for (k, t) in truth.iter().enumerate() {
        if !truth_used[k] {
            rows.push(CsvTarget {
                nominal: None,
                truth: Some(*t),
                detection: None,
            });
        }
    }
    let key = |r: &CsvTarget| {
        r.nominal
            .or(r.truth)
            .or(r.detection.map(|i| a.targets[i].range_m))
            .unwrap_or(0.0)
    };
    rows.sort_by(|x, y| key(x).total_cmp(&key(y)));
    if rows.is_empty() {
        rows.push(CsvTarget {
            nominal: None,
            truth: None,
            detection: None,
        });
    }
    rows
}

/// A CSV field: quoted (quotes doubled) when it holds a comma, a quote or a line break.
fn csv_field(text: &str) -> String {
    if text.contains([',', '"', '\n', '\r']) {
        format!("\"{}\"", text.replace('"', "\"\""))
    } else {
        text.to_string()
    }
}

/// `results.csv`: one row per step, algorithm and target ([`csv_targets`]), the columns of
/// [`CSV_COLUMNS`]; numbers as `results.json` holds them (the shortest text that reads back to
/// the same float64), an empty field where there is no value, `true`/`false` for flags. The
/// step's figures (width, side-lobe, SNR of its strongest target, resolved, data) repeat on
/// each of its rows.
pub(crate) fn to_csv(results: &Results) -> String {
    let num = |v: Option<f64>| v.map(|x| x.to_string()).unwrap_or_default();
    let flag = |v: Option<bool>| v.map(|b| b.to_string()).unwrap_or_default();
    // A column per swept setting (several axes, or a setting that is not a kind), after the
    // fixed ones, in the order the steps name them.
    let mut axes: Vec<&str> = Vec::new();
    for a in results.steps.iter().flat_map(|s| &s.nominal.axes) {
        if !axes.contains(&a.name.as_str()) {
            axes.push(&a.name);
        }
    }
    let mut out = CSV_COLUMNS.join(",");
    for a in &axes {
        out.push_str(&format!(",{}", axis_column(a)));
    }
    out.push('\n');
    for step in &results.steps {
        let n = &step.nominal;
        let axis_fields: Vec<String> = axes
            .iter()
            .map(|name| {
                n.axes
                    .iter()
                    .find(|a| a.name == *name)
                    .map(|a| csv_field(&a.value.to_string()))
                    .unwrap_or_default()
            })
            .collect();
        for (name, a) in &step.algorithms {
            for (k, row) in csv_targets(step, a).iter().enumerate() {
                let t = row.detection.map(|i| &a.targets[i]);
                let range = t.map(|t| t.range_m);
                let grid = t.and_then(|t| t.on_grid_m);
                let minus = |x: Option<f64>, r: Option<f64>| Some(x? - r?);
                let p = a.payload.as_ref();
                let fields = [
                    step.index.to_string(),
                    csv_field(n.label.as_deref().unwrap_or("")),
                    csv_field(n.parameter.map_or("", |p| p.name())),
                    num(n.value),
                    num(Some(n.bandwidth_hz)),
                    csv_field(name),
                    step.repetitions.to_string(),
                    (k + 1).to_string(),
                    num(row.nominal),
                    num(row.truth),
                    num(range),
                    num(t.and_then(|t| t.range_std_m)),
                    num(t.and_then(|t| t.range_uncertainty_m)),
                    num(grid),
                    num(t.map(|t| t.level_db)),
                    num(minus(range, row.nominal)),
                    num(minus(grid, row.nominal)),
                    num(minus(range, row.truth)),
                    num(minus(grid, row.truth)),
                    flag((row.nominal.is_some() || row.truth.is_some()).then_some(t.is_none())),
                    flag(a.resolved),
                    num(a.width_3db_cm),
                    num(a.sidelobe_db),
                    num(a.snr_db),
                    p.map(|p| p.bit_errors.to_string()).unwrap_or_default(),
                    p.map(|p| p.bits.to_string()).unwrap_or_default(),
                    num(p.map(|p| p.ber)),
                    csv_field(p.and_then(|p| p.error.as_deref()).unwrap_or("")),
                ];
                out.push_str(&fields.join(","));
                for f in &axis_fields {
                    out.push(',');
                    out.push_str(f);
                }
                out.push('\n');
            }
        }
    }
    out
}

/// The `results.csv` column of a swept setting: `swept_` and its name in snake case
/// (`swept_awg_amplitude`), apart from the measured columns of the same words.
pub(crate) fn axis_column(name: &str) -> String {
    format!("swept_{}", name.replace('-', "_"))
}

/// The thesis' rule: with two or more targets, each has its own detection within +-s/2.
fn resolved(reference: &[f64], targets: &[TargetResult]) -> Option<bool> {
    if reference.len() < 2 {
        return None;
    }
    let s = reference
        .windows(2)
        .map(|w| (w[1] - w[0]).abs())
        .fold(f64::INFINITY, f64::min);
    let mut taken = vec![false; targets.len()];
    for &r in reference {
        let found = targets
            .iter()
            .enumerate()
            .filter(|(i, t)| !taken[*i] && (t.range_m - r).abs() <= s / 2.0)
            .min_by(|a, b| (a.1.range_m - r).abs().total_cmp(&(b.1.range_m - r).abs()));
        match found {
            Some((i, _)) => taken[i] = true,
            None => return Some(false),
        }
    }
    Some(true)
}

fn payload(p: Option<&PayloadResult>, spread: Option<&Spread>) -> Option<PayloadFigures> {
    let p = p?;
    let (bit_errors, bits) = match spread {
        Some(s) if s.bits > 0 => (s.bit_errors, s.bits),
        _ => (p.bit_errors, p.bits),
    };
    Some(PayloadFigures {
        bit_errors,
        bits,
        ber: if bits > 0 {
            bit_errors as f64 / bits as f64
        } else {
            0.0
        },
        error: p.error.clone(),
        evm_rms_pct: p.evm_rms_pct,
        evm_p95_pct: p.evm_p95_pct,
        mer_db: p.mer_db,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn floats_survive_json_exactly() {
        // A resumed run reads the earlier steps' results back: they must come out bit for bit
        // (serde_json's float_roundtrip feature; without it this value moves by one ulp).
        for x in [
            -13.339831317062941_f64,
            0.9700012394236971,
            1.2394236971191575e-6,
        ] {
            let back: f64 = serde_json::from_str(&serde_json::to_string(&x).unwrap()).unwrap();
            assert_eq!(back.to_bits(), x.to_bits());
        }
    }

    fn t(range_m: f64, on_grid_m: f64) -> TargetResult {
        TargetResult {
            range_m,
            range_std_m: None,
            range_uncertainty_m: None,
            level_db: -6.0,
            on_grid_m: Some(on_grid_m),
        }
    }

    #[test]
    fn the_largest_error_keeps_its_sign_and_misses_are_counted() {
        let found = [t(0.9996, 0.995), t(1.3009, 1.304)];
        let (e, g, missed) = errors(&[1.0, 1.3, 2.0], &found, 0.15);
        assert!((e.unwrap() - 0.0009).abs() < 1e-12);
        assert!((g.unwrap() - (-0.005)).abs() < 1e-12);
        assert_eq!(missed, 1);
    }

    fn step(targets: &[f64], truth: Option<&[f64]>, found: Vec<TargetResult>) -> StepResult {
        let range = |r: &f64| Range { range_m: *r };
        let mut algorithms = BTreeMap::new();
        algorithms.insert(
            "correlation".to_string(),
            AlgorithmResult {
                targets: found,
                width_3db_cm: Some(13.3),
                sidelobe_db: Some(-13.3),
                snr_db: None,
                error_m: None,
                error_on_grid_m: None,
                truth_error_m: None,
                truth_error_on_grid_m: None,
                missed: 0,
                resolved: Some(false),
                payload: Some(PayloadFigures {
                    bit_errors: 3,
                    bits: 128,
                    ber: 3.0 / 128.0,
                    error: Some("no sync word, \"SFD\"".into()),
                    evm_rms_pct: None,
                    evm_p95_pct: None,
                    mer_db: None,
                }),
                spread: None,
                chain_echoes: Vec::new(),
            },
        );
        StepResult {
            index: 2,
            nominal: Nominal {
                label: Some("two pillars, 30 cm".into()),
                parameter: None,
                value: None,
                targets: targets.iter().map(range).collect(),
                bandwidth_hz: 1e9,
                tx_attenuation_db: None,
                snr_db: None,
                velocity_mps: None,
                ..Nominal::default()
            },
            repetitions: 1,
            algorithms,
            truth: truth.map(|t| Truth {
                targets: t.iter().map(range).collect(),
                snr_db: None,
            }),
        }
    }

    /// The rows of `to_csv` as column -> text (fields split as RFC 4180 reads them).
    fn rows(csv: &str) -> Vec<BTreeMap<String, String>> {
        fn fields(line: &str) -> Vec<String> {
            let (mut out, mut cur, mut quoted, mut chars) =
                (Vec::new(), String::new(), false, line.chars().peekable());
            while let Some(c) = chars.next() {
                match (c, quoted) {
                    ('"', true) if chars.peek() == Some(&'"') => {
                        cur.push('"');
                        chars.next();
                    }
                    ('"', _) => quoted = !quoted,
                    (',', false) => out.push(std::mem::take(&mut cur)),
                    (c, _) => cur.push(c),
                }
            }
            out.push(cur);
            out
        }
        let mut lines = csv.lines();
        let header = fields(lines.next().unwrap());
        assert_eq!(header, CSV_COLUMNS);
        lines
            .map(|l| header.iter().cloned().zip(fields(l)).collect())
            .collect()
    }

    #[test]
    fn results_csv_has_a_row_per_target_missed_and_extra_ones_too() {
        // Nominal 1.0 and 1.3 m; found near 1.0 m and a ghost at 2.0 m; 1.3 m missed.
        let s = step(
            &[1.0, 1.3],
            Some(&[1.001, 1.302]),
            vec![t(1.0004, 1.0), t(2.0, 2.0)],
        );
        let r = rows(&to_csv(&Results { steps: vec![s] }));
        assert_eq!(r.len(), 3);
        let (hit, missed, ghost) = (&r[0], &r[1], &r[2]);
        assert_eq!(hit["nominal_m"], "1");
        assert_eq!(hit["truth_m"], "1.001");
        assert_eq!(hit["range_m"], "1.0004");
        assert_eq!(hit["error_m"], (1.0004_f64 - 1.0).to_string());
        assert_eq!(hit["truth_error_m"], (1.0004_f64 - 1.001).to_string());
        assert_eq!(hit["missed"], "false");
        assert_eq!(missed["nominal_m"], "1.3");
        assert_eq!(missed["truth_m"], "1.302");
        assert_eq!(missed["range_m"], "");
        assert_eq!(missed["missed"], "true");
        assert_eq!(ghost["nominal_m"], "");
        assert_eq!(ghost["range_m"], "2");
        assert_eq!(ghost["missed"], "");
        for (k, row) in r.iter().enumerate() {
            assert_eq!(row["target"], (k + 1).to_string());
            assert_eq!(row["step"], "2");
            assert_eq!(row["label"], "two pillars, 30 cm");
            assert_eq!(row["payload_error"], "no sync word, \"SFD\"");
            assert_eq!(row["resolved"], "false");
            assert_eq!(row["snr_db"], "");
            assert_eq!(row["bits"], "128");
        }
    }

    #[test]
    fn a_step_without_targets_or_detections_still_has_its_row() {
        let r = rows(&to_csv(&Results {
            steps: vec![step(&[], None, Vec::new())],
        }));
        assert_eq!(r.len(), 1);
        assert_eq!(r[0]["range_m"], "");
        assert_eq!(r[0]["missed"], "");
        assert_eq!(r[0]["ber"], (3.0_f64 / 128.0).to_string());
    }

    #[test]
    fn two_targets_are_resolved_only_with_a_detection_near_each() {
        assert_eq!(resolved(&[1.0], &[t(1.0, 1.0)]), None);
        assert_eq!(
            resolved(&[1.0, 1.08], &[t(1.005, 1.0), t(1.07, 1.07)]),
            Some(true)
        );
        assert_eq!(resolved(&[1.0, 1.08], &[t(1.04, 1.04)]), Some(false));
        // One detection cannot serve both.
        assert_eq!(resolved(&[1.0, 1.08], &[t(1.039, 1.04)]), Some(false));
    }
}
