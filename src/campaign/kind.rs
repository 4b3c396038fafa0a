//! The campaign kinds: the parameter a sweep moves, and everything that depends on it, in one
//! table ([`SweepParameter::kind`]): its name and unit, how a value reads, what it sets in a
//! step, whether only a simulated bench can set it and the `results.json` metrics its figures
//! read. The report's figures of each kind are a table of their own, keyed by the same enum
//! (`report/run_figures.rs`, `own_figures`): the report reads the plan, never the other way.
//!
//! Beside the kinds, [`SETTINGS`] is the table of every setting a step can set (a `[[sweep]]`
//! axis or a `[[steps]]` key): its name, unit, how its value reads and what it sets in the step.
//! A new sweepable setting is one row there (and, when a bench must check it, a line in
//! `plan::check_nominal`). The six settings that are also kinds (`position`, `separation`,
//! `bandwidth`, `tx-attenuation`, `snr`, `velocity`) set the step as their kind does.
//!
//! Adding a kind: a variant here and its arm in [`SweepParameter::kind`], its figure function
//! (`report/figures.rs`) and its arm in `report/run_figures.rs`'s `own_figures` (the compiler
//! asks for it) when it has figures of its own, and its commented spec
//! (`examples/<kind>.toml`, listed in `builtin::TEMPLATES` for `radbench campaign new`).

use super::axis::{AxisValue, SweepParameter};
use super::nominal::{Nominal, Range, MAX_VELOCITY_MPS};
use super::spec_error::{FieldErrors, SpecError};
use crate::measure::capture::MAX_REPETITIONS;
use crate::measure::{Algorithm, WindowName};

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
    /// What a value sets in the step (the targets, the bandwidth, ...).
    pub set: fn(&mut Nominal, f64, &SweepAt<'_>) -> Result<(), SpecError>,
    /// The `results.json` metrics (of each algorithm) its own figures plot: what a reader of the
    /// table learns here, checked against the file's fields by the tests.
    #[cfg_attr(not(test), allow(dead_code))]
    pub metrics: &'static [&'static str],
}

/// Where a setting's value is set: the spec (for errors), its `[[sweep]]` table (an empty one
/// for a `[[steps]]` entry), the setting's row, the field naming the value and the prefix of its
/// sibling fields (`sweep`, `sweep[1]`, `steps[3]`).
pub(crate) struct SweepAt<'a> {
    pub spec: &'a dyn FieldErrors,
    /// The `[[sweep]]` table's `targets` and `target` (none for a `[[steps]]` entry).
    pub targets: Option<&'a [f64]>,
    pub target: Option<usize>,
    pub setting: &'a Setting,
    pub value_field: String,
    pub prefix: String,
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
                set: set_position,
                metrics: &["error_m", "error_on_grid_m", "targets"],
            },
            SweepParameter::Separation => Kind {
                name: "separation",
                unit: "m",
                show: |v| format!("{v:.3} m"),
                simulated_only: false,
                set: set_separation,
                metrics: &[],
            },
            SweepParameter::Bandwidth => Kind {
                name: "bandwidth",
                unit: "Hz",
                show: |v| format!("{} GHz", v / 1e9),
                simulated_only: false,
                set: |n, v, _| {
                    n.bandwidth_hz = v;
                    Ok(())
                },
                metrics: &[],
            },
            SweepParameter::TxAttenuation => Kind {
                name: "tx-attenuation",
                unit: "dB",
                show: |v| format!("{v} dB"),
                simulated_only: false,
                set: |n, v, _| {
                    n.tx_attenuation_db = Some(v);
                    Ok(())
                },
                metrics: LINK_METRICS,
            },
            SweepParameter::Snr => Kind {
                name: "snr",
                unit: "dB",
                show: |v| format!("{v} dB"),
                simulated_only: true,
                set: |n, v, _| {
                    n.snr_db = Some(v);
                    Ok(())
                },
                metrics: LINK_METRICS,
            },
            SweepParameter::Velocity => Kind {
                name: "velocity",
                unit: "m/s",
                show: |v| format!("{v} m/s"),
                simulated_only: true,
                set: set_velocity,
                metrics: &["error_m", "truth_error_m"],
            },
        }
    }

    /// The kind named `name`, if any.
    pub(crate) fn from_name(name: &str) -> Option<SweepParameter> {
        Self::ALL.into_iter().find(|p| p.name() == name)
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

/// `position`: the moved target (`sweep.target`, default the first of `sweep.targets`, or the
/// value alone) stands at the value.
fn set_position(n: &mut Nominal, v: f64, at: &SweepAt<'_>) -> Result<(), SpecError> {
    let mut t = at.targets.map_or_else(|| vec![v], <[f64]>::to_vec);
    let which = at.target.unwrap_or(0);
    if which >= t.len() {
        return Err(at.spec.field_error(
            &format!("{}.target", at.prefix),
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
        match at.targets {
            Some([first]) => *first,
            _ => return Err(at.spec.field_error(
                &format!("{}.targets", at.prefix),
                "a separation sweep needs targets = [R]: the first target's range, metres (the \
                 second stands R + separation)"
                    .into(),
            )),
        };
    if v <= 0.0 {
        return Err(at
            .spec
            .field_error(&at.value_field, format!("{v}: a separation above 0 m")));
    }
    n.targets = sorted_ranges(vec![base, base + v]);
    Ok(())
}

/// `velocity`: every target moves at the value (m/s, positive receding).
fn set_velocity(n: &mut Nominal, v: f64, at: &SweepAt<'_>) -> Result<(), SpecError> {
    if v.abs() > MAX_VELOCITY_MPS {
        return Err(at.spec.field_error(
            &at.value_field,
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

// ---- Every setting a step can set --------------------------------------------------------

/// How a setting's values read.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Reads {
    /// A finite number in the unit.
    Number,
    /// A whole number (`start`/`step` whole too).
    Count,
    /// A name of a list (`values = ["hann", "taylor"]`).
    Name(&'static [&'static str]),
}

/// One row: everything that depends on a setting.
pub(crate) struct Setting {
    /// As `[[sweep]] parameter` and `[[steps]]` spell it.
    pub name: &'static str,
    pub unit: &'static str,
    pub reads: Reads,
    /// The step's field it sets (errors found after planning name it).
    pub field: &'static str,
    /// Sets the value in the step; errors name `at.value_field`.
    pub apply: fn(&mut Nominal, &AxisValue, &SweepAt<'_>) -> Result<(), SpecError>,
}

const WINDOWS: &[&str] = &["rect", "hann", "taylor", "chebyshev"];
const ALGORITHMS: &[&str] = &["correlation", "fourier", "music", "root-music", "esprit"];

/// Every setting a step can set (see the module docs).
pub(crate) const SETTINGS: &[Setting] = &[
    kind_row("position", "targets"),
    kind_row("separation", "targets"),
    kind_row("bandwidth", "bandwidth_hz"),
    kind_row("tx-attenuation", "tx_attenuation_db"),
    kind_row("snr", "snr_db"),
    kind_row("velocity", "velocity_mps"),
    Setting {
        name: "rx-attenuation",
        unit: "dB",
        reads: Reads::Number,
        field: "rx_attenuation_db",
        apply: |n, v, at| {
            n.rx_attenuation_db = Some(number(v, at)?);
            Ok(())
        },
    },
    Setting {
        name: "awg-amplitude",
        unit: "Vpp",
        reads: Reads::Number,
        field: "awg_amplitude_vpp",
        apply: |n, v, at| {
            n.awg_amplitude_vpp = Some(number(v, at)?);
            Ok(())
        },
    },
    Setting {
        name: "volts-per-div",
        unit: "V/div",
        reads: Reads::Number,
        field: "volts_per_div",
        apply: |n, v, at| {
            n.volts_per_div = Some(number(v, at)?);
            Ok(())
        },
    },
    Setting {
        name: "pulse-length",
        unit: "s",
        reads: Reads::Number,
        field: "pulse_s",
        apply: |n, v, at| {
            n.pulse_s = Some(number(v, at)?);
            Ok(())
        },
    },
    Setting {
        name: "bits",
        unit: "bits per pulse",
        reads: Reads::Count,
        field: "bits_per_pulse",
        apply: |n, v, at| {
            n.bits_per_pulse = Some(count(v, at, 1, usize::MAX)?);
            Ok(())
        },
    },
    Setting {
        name: "subcarriers",
        unit: "subcarriers",
        reads: Reads::Count,
        field: "subcarriers",
        apply: |n, v, at| {
            n.subcarriers = Some(count(v, at, 1, usize::MAX)?);
            Ok(())
        },
    },
    Setting {
        name: "repetitions",
        unit: "repetitions",
        reads: Reads::Count,
        field: "repetitions",
        apply: |n, v, at| {
            n.repetitions = Some(count(v, at, 1, MAX_REPETITIONS)?);
            Ok(())
        },
    },
    Setting {
        name: "window",
        unit: "",
        reads: Reads::Name(WINDOWS),
        field: "window",
        apply: |n, v, at| {
            n.window = Some(named::<WindowName>(v, at, WINDOWS)?);
            Ok(())
        },
    },
    Setting {
        name: "algorithm",
        unit: "",
        reads: Reads::Name(ALGORITHMS),
        field: "algorithm",
        apply: |n, v, at| {
            n.algorithm = Some(named::<Algorithm>(v, at, ALGORITHMS)?);
            Ok(())
        },
    },
];

/// A kind's row: its unit and what it sets come from campaign/kind.rs.
const fn kind_row(name: &'static str, field: &'static str) -> Setting {
    Setting {
        name,
        unit: "",
        reads: Reads::Number,
        field,
        apply: apply_kind,
    }
}

fn apply_kind(n: &mut Nominal, v: &AxisValue, at: &SweepAt<'_>) -> Result<(), SpecError> {
    let p = SweepParameter::from_name(at.setting.name).expect("a kind's row names a kind");
    (p.kind().set)(n, number(v, at)?, at)
}

impl Setting {
    /// The row of `name`.
    pub(crate) fn named(name: &str) -> Option<&'static Setting> {
        SETTINGS.iter().find(|s| s.name == name)
    }

    /// The kind of the same name, when it is one.
    pub(crate) fn kind(&self) -> Option<SweepParameter> {
        SweepParameter::from_name(self.name)
    }

    /// The values' unit (a kind's from its table).
    pub(crate) fn unit(&self) -> &'static str {
        match self.kind() {
            Some(p) => p.unit(),
            None => self.unit,
        }
    }

    /// The axis label of a figure: `awg-amplitude (Vpp)`, `window`.
    pub(crate) fn label(&self) -> String {
        match self.unit() {
            "" => self.name.to_string(),
            u => format!("{} ({u})", self.name),
        }
    }
}

/// Every setting's name, for an error's "allowed".
pub(crate) fn allowed_names() -> String {
    SETTINGS
        .iter()
        .map(|s| s.name)
        .collect::<Vec<_>>()
        .join(", ")
}

fn number(v: &AxisValue, at: &SweepAt<'_>) -> Result<f64, SpecError> {
    match v {
        AxisValue::Number(x) if x.is_finite() => Ok(*x),
        other => Err(at.spec.field_error(
            &at.value_field,
            format!(
                "{other:?}: {} takes a finite number in {}",
                at.setting.name,
                at.setting.unit()
            ),
        )),
    }
}

fn count(v: &AxisValue, at: &SweepAt<'_>, min: usize, max: usize) -> Result<usize, SpecError> {
    let x = number(v, at)?;
    if x.fract() == 0.0 && x >= min as f64 && x <= max as f64 {
        return Ok(x as usize);
    }
    let upper = if max == usize::MAX {
        String::new()
    } else {
        max.to_string()
    };
    Err(at.spec.field_error(
        &at.value_field,
        format!(
            "{x}: {} takes a whole number {min}..={upper}",
            at.setting.name
        ),
    ))
}

fn named<T: serde::de::DeserializeOwned>(
    v: &AxisValue,
    at: &SweepAt<'_>,
    allowed: &[&str],
) -> Result<T, SpecError> {
    let bad = || {
        at.spec.field_error(
            &at.value_field,
            format!(
                "{v}: {} takes one of {}",
                at.setting.name,
                allowed
                    .iter()
                    .map(|a| format!("\"{a}\""))
                    .collect::<Vec<_>>()
                    .join(", ")
            ),
        )
    };
    match v {
        AxisValue::Name(n) => {
            serde_json::from_value(serde_json::Value::String(n.clone())).map_err(|_| bad())
        }
        AxisValue::Number(_) => Err(bad()),
    }
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
    #[test]
    fn every_kind_has_its_row_and_names_are_unique() {
        for p in SweepParameter::ALL {
            assert!(Setting::named(p.name()).is_some(), "{p}");
        }
        for (i, s) in SETTINGS.iter().enumerate() {
            assert!(SETTINGS[..i].iter().all(|o| o.name != s.name), "{}", s.name);
        }
    }

    #[test]
    fn the_names_lists_are_the_serde_names() {
        for w in WINDOWS {
            let _: WindowName = serde_json::from_value(serde_json::json!(w)).unwrap();
        }
        for a in ALGORITHMS {
            let _: Algorithm = serde_json::from_value(serde_json::json!(a)).unwrap();
        }
    }
}
