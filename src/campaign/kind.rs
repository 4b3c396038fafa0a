//! The campaign kinds: the parameter a sweep moves, and everything that depends on it, in one
//! table ([`SweepParameter::kind`]): its name and unit, how a value reads, what it sets in a
//! step, whether only a simulated bench can set it, the `results.json` metrics its figures read
//! and the report's figures of its steps.
//!
//! Adding a kind: a variant here and its arm in [`SweepParameter::kind`], its figure function
//! (`report/figures.rs`) when it has figures of its own, and its commented spec
//! (`examples/<kind>.toml`, listed in `builtin::TEMPLATES` for `radbench campaign new`).

use super::manifest::Manifest;
use super::plan::{Nominal, Range, MAX_VELOCITY_MPS};
use super::report::figures::{self, Figure};
use super::results::StepResult;
use super::spec::{SpecError, SpecFile, SweepSection};
use serde::{Deserialize, Serialize};

/// `sweep.parameter`: what a sweep moves, one value per step.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Deserialize, Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum SweepParameter {
    /// A target's range, metres.
    Position,
    /// The distance between two targets, metres.
    Separation,
    /// The waveform's bandwidth, Hz.
    Bandwidth,
    /// The Tx front end's attenuation, dB.
    TxAttenuation,
    /// The simulated scene's SNR, dB (simulated benches only).
    Snr,
    /// The targets' radial velocity, m/s (simulated benches only).
    Velocity,
}

/// Everything that depends on a kind (see the module docs).
pub(crate) struct Kind {
    /// As the spec, `results.json` and the manifest spell it.
    pub name: &'static str,
    /// The values' unit.
    pub unit: &'static str,
    /// A value as a step's line shows it (`0.970 m`, `2 GHz`, `10 dB`).
    pub show: fn(f64) -> String,
    /// Only a simulated bench can set it (the built-in mock lab, or a bench file with
    /// `[simulation]`).
    pub simulated_only: bool,
    /// Its values place the targets (the steps' `targets` are the sweep's values).
    pub places_targets: bool,
    /// What a value sets in the step (the targets, the bandwidth, ...).
    pub set: fn(&mut Nominal, f64, &SweepAt<'_>) -> Result<(), SpecError>,
    /// The `results.json` metrics (of each algorithm) its own figures plot: what a reader of the
    /// table learns here, checked against the file's fields by the tests.
    #[cfg_attr(not(test), allow(dead_code))]
    pub metrics: &'static [&'static str],
    /// The report's figures of the steps swept in it; `None`: only the figures every run gets
    /// (resolution for two targets, width and side lobes for one).
    pub figures: Option<KindFigures>,
}

/// A kind's own figures and where the report shows them.
#[derive(Clone, Copy)]
pub(crate) struct KindFigures {
    /// Before the figures every run gets (`true`), or after them.
    pub first: bool,
    pub draw: fn(&Manifest, &[&StepResult]) -> Vec<Figure>,
}

/// Where a sweep's value is set: the spec (for errors), its `[sweep]`, the step (0-based).
pub(crate) struct SweepAt<'a> {
    pub spec: &'a SpecFile,
    pub sweep: &'a SweepSection,
    pub k: usize,
}

impl SweepParameter {
    /// Every kind, in the order the report draws their figures.
    pub(crate) const ALL: [SweepParameter; 6] = [
        SweepParameter::Position,
        SweepParameter::Separation,
        SweepParameter::Bandwidth,
        SweepParameter::TxAttenuation,
        SweepParameter::Snr,
        SweepParameter::Velocity,
    ];

    /// The kind's table entry: the one place that names what depends on it.
    pub(crate) fn kind(self) -> Kind {
        match self {
            SweepParameter::Position => Kind {
                name: "position",
                unit: "m",
                show: |v| format!("{v:.3} m"),
                simulated_only: false,
                places_targets: true,
                set: set_position,
                metrics: &["error_m", "error_on_grid_m", "targets"],
                figures: Some(KindFigures {
                    first: true,
                    draw: |m, s| figures::accuracy(m, s).into_iter().collect(),
                }),
            },
            SweepParameter::Separation => Kind {
                name: "separation",
                unit: "m",
                show: |v| format!("{v:.3} m"),
                simulated_only: false,
                places_targets: true,
                set: set_separation,
                metrics: &[],
                figures: None,
            },
            SweepParameter::Bandwidth => Kind {
                name: "bandwidth",
                unit: "Hz",
                show: |v| format!("{} GHz", v / 1e9),
                simulated_only: false,
                places_targets: false,
                set: |n, v, _| {
                    n.bandwidth_hz = v;
                    Ok(())
                },
                metrics: &[],
                figures: None,
            },
            SweepParameter::TxAttenuation => Kind {
                name: "tx-attenuation",
                unit: "dB",
                show: |v| format!("{v} dB"),
                simulated_only: false,
                places_targets: false,
                set: |n, v, _| {
                    n.tx_attenuation_db = Some(v);
                    Ok(())
                },
                metrics: LINK_METRICS,
                figures: Some(LINK_FIGURES),
            },
            SweepParameter::Snr => Kind {
                name: "snr",
                unit: "dB",
                show: |v| format!("{v} dB"),
                simulated_only: true,
                places_targets: false,
                set: |n, v, _| {
                    n.snr_db = Some(v);
                    Ok(())
                },
                metrics: LINK_METRICS,
                figures: Some(LINK_FIGURES),
            },
            SweepParameter::Velocity => Kind {
                name: "velocity",
                unit: "m/s",
                show: |v| format!("{v} m/s"),
                simulated_only: true,
                places_targets: false,
                set: set_velocity,
                metrics: &["error_m", "truth_error_m"],
                figures: Some(KindFigures {
                    first: false,
                    draw: |m, s| figures::velocity(m, s).into_iter().collect(),
                }),
            },
        }
    }

    /// As the spec spells it.
    pub fn name(self) -> &'static str {
        self.kind().name
    }

    /// The values' unit.
    pub fn unit(self) -> &'static str {
        self.kind().unit
    }
}

impl std::fmt::Display for SweepParameter {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

/// What the link figures (BER, EVM, width, PSL, range error against the swept level) read.
const LINK_METRICS: &[&str] = &[
    "payload",
    "width_3db_cm",
    "sidelobe_db",
    "error_m",
    "snr_db",
];

const LINK_FIGURES: KindFigures = KindFigures {
    first: false,
    draw: figures::link_figures,
};

/// `position`: the moved target (`sweep.target`, default the first of `sweep.targets`, or the
/// value alone) stands at the value.
fn set_position(n: &mut Nominal, v: f64, at: &SweepAt<'_>) -> Result<(), SpecError> {
    let mut t = at.sweep.targets.clone().unwrap_or_else(|| vec![v]);
    let which = at.sweep.target.unwrap_or(0);
    if which >= t.len() {
        return Err(at.spec.error(
            "sweep.target",
            format!(
                "{which}: sweep.targets holds {} targets (0-based index)",
                t.len()
            ),
        ));
    }
    t[which] = v;
    n.targets = sorted_ranges(t);
    Ok(())
}

/// `separation`: the first target at `sweep.targets = [R]`, the second at R + the value.
fn set_separation(n: &mut Nominal, v: f64, at: &SweepAt<'_>) -> Result<(), SpecError> {
    let base =
        match at.sweep.targets.as_deref() {
            Some([first]) => *first,
            _ => return Err(at.spec.error(
                "sweep.targets",
                "a separation sweep needs targets = [R]: the first target's range, metres (the \
                 second stands R + separation)",
            )),
        };
    if v <= 0.0 {
        return Err(at.spec.error(
            &format!("sweep.values[{}]", at.k),
            format!("{v}: a separation above 0 m"),
        ));
    }
    n.targets = sorted_ranges(vec![base, base + v]);
    Ok(())
}

/// `velocity`: every target moves at the value (m/s, positive receding).
fn set_velocity(n: &mut Nominal, v: f64, at: &SweepAt<'_>) -> Result<(), SpecError> {
    if v.abs() > MAX_VELOCITY_MPS {
        return Err(at.spec.error(
            &format!("sweep.values[{}]", at.k),
            format!("{v}: allowed -{MAX_VELOCITY_MPS} ..= {MAX_VELOCITY_MPS} m/s"),
        ));
    }
    n.velocity_mps = Some(v);
    Ok(())
}

/// Ranges in ascending order, as a step's targets.
pub(crate) fn sorted_ranges(mut t: Vec<f64>) -> Vec<Range> {
    t.sort_by(f64::total_cmp);
    t.into_iter().map(|range_m| Range { range_m }).collect()
}

/// The figures of every kind that has its own, for the steps swept in it, `first` or after.
pub(crate) fn kind_figures(manifest: &Manifest, steps: &[StepResult], first: bool) -> Vec<Figure> {
    let mut out = Vec::new();
    for p in SweepParameter::ALL {
        let Some(f) = p.kind().figures.filter(|f| f.first == first) else {
            continue;
        };
        let mine: Vec<&StepResult> = steps
            .iter()
            .filter(|s| s.nominal.parameter == Some(p))
            .collect();
        if !mine.is_empty() {
            out.extend((f.draw)(manifest, &mine));
        }
    }
    out
}

/// Whether a step's kind has figures of its own.
pub(crate) fn has_own_figures(s: &StepResult) -> bool {
    s.nominal
        .parameter
        .is_some_and(|p| p.kind().figures.is_some())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_are_the_serde_names_and_every_kind_is_listed() {
        for p in SweepParameter::ALL {
            let text = serde_json::to_value(p).unwrap();
            assert_eq!(text, p.name(), "{p:?}");
            assert_eq!(p.to_string(), p.name());
        }
    }

    #[test]
    fn the_metrics_a_kind_names_are_results_json_fields() {
        use crate::campaign::AlgorithmResult;
        let one = AlgorithmResult {
            targets: Vec::new(),
            width_3db_cm: None,
            sidelobe_db: None,
            snr_db: None,
            error_m: None,
            error_on_grid_m: None,
            truth_error_m: None,
            truth_error_on_grid_m: None,
            missed: 0,
            resolved: None,
            payload: None,
            spread: None,
            chain_echoes: Vec::new(),
        };
        let fields = serde_json::to_value(&one).unwrap();
        for p in SweepParameter::ALL {
            for m in p.kind().metrics {
                assert!(
                    fields.get(m).is_some(),
                    "{p}: {m} is not a field of results.json's algorithm results"
                );
            }
        }
    }
}
