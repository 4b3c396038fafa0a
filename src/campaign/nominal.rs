//! A step's set-points, as planned: plain data that the plan makes, the kinds' table sets and
//! every result file carries.

use super::axis::{AxisSetting, SweepParameter};
use crate::measure::{Algorithm, WindowName};
use serde::{Deserialize, Serialize};

/// Fastest radial velocity a step may give its targets, m/s (the simulated scene's own limit).
pub(crate) const MAX_VELOCITY_MPS: f64 = 1000.0;

/// One target's range, metres (`{"range_m": ...}` in every JSON file).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Range {
    pub range_m: f64,
}

/// The set-points of one step, as planned.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct Nominal {
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub label: Option<String>,
    /// The swept parameter (`position`, `separation`, `bandwidth`, `tx-attenuation`, `snr`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub parameter: Option<SweepParameter>,
    /// Its value at this step, in its unit (m, Hz, dB).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub value: Option<f64>,
    /// Where the targets stand, ascending (empty: not placed by the campaign).
    pub targets: Vec<Range>,
    pub bandwidth_hz: f64,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub tx_attenuation_db: Option<f64>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub snr_db: Option<f64>,
    /// The targets' radial velocity, m/s, positive receding (simulated benches: the scene's
    /// targets move at it; absent: they stand still, or keep the scene's own velocity).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub velocity_mps: Option<f64>,
    /// Every swept setting's value at this step, outer axis first (`[[sweep]]` tables, or a
    /// `[sweep]` of a setting that is not a kind): `results.csv` has a column per name.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub axes: Vec<AxisSetting>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub rx_attenuation_db: Option<f64>,
    /// The AWG's I and Q amplitude, volts peak to peak.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub awg_amplitude_vpp: Option<f64>,
    /// The scope's vertical scale of both channels.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub volts_per_div: Option<f64>,
    /// MSK-LFM: the pulse length, seconds.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub pulse_s: Option<f64>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub bits_per_pulse: Option<usize>,
    /// OFDM: the subcarriers.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub subcarriers: Option<usize>,
    /// Marker-triggered repetitions of this step (absent: the spec's `repetitions`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub repetitions: Option<usize>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub window: Option<WindowName>,
    /// The one algorithm this step is processed with (absent: the spec's).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub algorithm: Option<Algorithm>,
}

impl Nominal {
    pub fn ranges(&self) -> Vec<f64> {
        self.targets.iter().map(|t| t.range_m).collect()
    }
}
