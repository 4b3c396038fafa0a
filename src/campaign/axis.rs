//! What a sweep moves, as plain data: the kind of a campaign ([`SweepParameter`]) and a swept
//! setting's value ([`AxisValue`], [`AxisSetting`]). The table of what each one means and sets
//! is `kind`.

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

/// One value of a setting: a number in its unit, or a name (`window`, `algorithm`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(untagged)]
pub enum AxisValue {
    Number(f64),
    Name(String),
}

impl std::fmt::Display for AxisValue {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            AxisValue::Number(v) => write!(f, "{v}"),
            AxisValue::Name(n) => f.write_str(n),
        }
    }
}

impl AxisValue {
    /// The number, when it is one.
    pub fn number(&self) -> Option<f64> {
        match self {
            AxisValue::Number(v) => Some(*v),
            AxisValue::Name(_) => None,
        }
    }
}

/// A swept setting's value at one step (`results.csv` has a column per name).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct AxisSetting {
    /// As the table of settings spells it.
    pub name: String,
    pub value: AxisValue,
}
