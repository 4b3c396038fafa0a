//! The AWG -> Tx -> Rx -> scope chain as a real E-band bench has it: a frequency response (tilt,
//! standing-wave ripple, group-delay ripple, dispersion, the DAC's sinc, an analogue roll-off, or a
//! measured table), I/Q imbalance and skew on both sides, a second path per target, the AWG's and
//! the scope's timebases, the residual phase noise of a shared LO, and Tx compression.
//!
//! A scene's `[chain]` names a preset (`ideal`, the default, or `thesis-lab`); any field written
//! beside it overrides the preset's value. [`Chain::resolve`] gives the numbers the synthesis uses.
//! examples/scene.toml documents every field: unit, the realistic range on the thesis' bench and
//! where that range comes from.

use num_complex::Complex64;
use serde::{Deserialize, Serialize};
use std::f64::consts::PI;

use super::checks::{finite_in, invalid, SceneError, C0};

/// Named chains.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum ChainPreset {
    /// Flat response, no I/Q errors, shared references: the mock lab as it always was.
    #[default]
    Ideal,
    /// Realistic magnitudes for the thesis' bench, chosen so that one pillar gives figures close
    /// to the thesis' lab (Tables 4.5 and 4.7); see examples/scene.toml.
    ThesisLab,
}

/// The `[chain]` section as written: a preset and the fields that override it.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct Chain {
    pub preset: ChainPreset,
    /// Linear amplitude tilt across the band, dB per GHz of baseband frequency.
    pub tilt_db_per_ghz: Option<f64>,
    /// Standing-wave ripple, dB peak-to-peak (one echo `ripple_period_hz^-1` behind every path).
    pub ripple_db: Option<f64>,
    /// Period of that ripple in frequency, Hz (the echo's extra delay is its inverse).
    pub ripple_period_hz: Option<f64>,
    /// Phase of the standing-wave echo at the carrier (baseband 0 Hz), degrees.
    pub ripple_phase_deg: Option<f64>,
    /// Sinusoidal group-delay ripple, picoseconds peak-to-peak.
    pub group_delay_ripple_ps: Option<f64>,
    /// Its period in frequency, Hz.
    pub group_delay_ripple_period_hz: Option<f64>,
    /// Linear group-delay slope (waveguide dispersion), ps per GHz.
    pub dispersion_ps_per_ghz: Option<f64>,
    /// The DAC's zero-order hold at the AWG rate (sinc roll-off; its half-sample delay is part of
    /// the system delay).
    pub dac_sinc: Option<bool>,
    /// -3 dB bandwidth of a 2nd-order Butterworth roll-off on I and Q, Hz (0 = none); its delay at
    /// DC is part of the system delay.
    pub bandwidth_hz: Option<f64>,
    /// A measured response to play back: `[frequency offset Hz, gain dB, phase deg]` points,
    /// ascending in frequency, interpolated linearly, held at the ends; multiplies the rest.
    pub response: Option<Vec<[f64; 3]>>,
    /// Tx I/Q modulator: Q gain relative to I, dB.
    pub tx_iq_gain_db: Option<f64>,
    /// Tx I/Q modulator: Q phase error relative to I, degrees.
    pub tx_iq_phase_deg: Option<f64>,
    /// Tx: Q delayed relative to I, picoseconds.
    pub tx_iq_skew_ps: Option<f64>,
    /// Rx: Q delayed relative to I at the scope, picoseconds.
    pub rx_iq_skew_ps: Option<f64>,
    /// A second path per target (floor or table bounce): its extra length, metres (path, not
    /// range: the delay grows by extra / c0).
    pub multipath_extra_m: Option<f64>,
    /// Its level relative to the direct path, dB (None or -inf = no second path).
    pub multipath_level_db: Option<f64>,
    /// Its phase relative to the direct path's carrier phase at the longer delay, degrees.
    pub multipath_phase_deg: Option<f64>,
    /// A discrete echo behind every path (an IF cable mismatched at both ends, between the Rx
    /// module and the scope): its extra delay, nanoseconds.
    pub cable_echo_ns: Option<f64>,
    /// Its level relative to the path it follows, dB (None or -inf = no echo).
    pub cable_echo_db: Option<f64>,
    /// Its phase relative to that path at the carrier, degrees.
    pub cable_echo_phase_deg: Option<f64>,
    /// AWG and scope locked to one 10 MHz reference (as in the thesis).
    pub shared_reference: Option<bool>,
    /// Without a shared reference: how fast the scope's timebase runs against the AWG's, ppm.
    pub timebase_offset_ppm: Option<f64>,
    /// Tx and Rx driven by one LO (as in the thesis): the LO's phase noise cancels except over the
    /// echo's round trip. `false`: independent LOs, the phase drifts over the whole record.
    pub shared_lo: Option<bool>,
    /// Tx drive (AWG output |I + jQ|, volts) at which the Tx is 1 dB compressed (soft limiter,
    /// Rapp p = 2). None = linear.
    pub tx_p1db_v: Option<f64>,
    /// Slow drift of every path's delay against the lab's simulated clock (the scene's
    /// `clock_s`), ps per minute: cables and modules warming up. An RF delay: it turns the
    /// carrier phase too.
    pub drift_ps_per_min: Option<f64>,
    /// Slow drift of every path's carrier phase against the simulated clock, degrees per minute
    /// (an LO distribution path warming up).
    pub drift_deg_per_min: Option<f64>,
}

/// The chain's numbers after the preset and the overrides.
#[derive(Debug, Clone, PartialEq)]
pub struct ChainParams {
    pub tilt_db_per_ghz: f64,
    pub ripple_db: f64,
    pub ripple_period_hz: f64,
    pub ripple_phase_deg: f64,
    pub group_delay_ripple_ps: f64,
    pub group_delay_ripple_period_hz: f64,
    pub dispersion_ps_per_ghz: f64,
    pub dac_sinc: bool,
    pub bandwidth_hz: f64,
    pub response: Vec<[f64; 3]>,
    pub tx_iq_gain_db: f64,
    pub tx_iq_phase_deg: f64,
    pub tx_iq_skew_ps: f64,
    pub rx_iq_skew_ps: f64,
    pub multipath_extra_m: f64,
    pub multipath_level_db: f64,
    pub multipath_phase_deg: f64,
    pub cable_echo_ns: f64,
    pub cable_echo_db: f64,
    pub cable_echo_phase_deg: f64,
    pub shared_reference: bool,
    pub timebase_offset_ppm: f64,
    pub shared_lo: bool,
    pub tx_p1db_v: f64,
    pub drift_ps_per_min: f64,
    pub drift_deg_per_min: f64,
}

impl ChainParams {
    /// A flat chain.
    pub const IDEAL: ChainParams = ChainParams {
        tilt_db_per_ghz: 0.0,
        ripple_db: 0.0,
        ripple_period_hz: 1e9,
        ripple_phase_deg: 0.0,
        group_delay_ripple_ps: 0.0,
        group_delay_ripple_period_hz: 1e9,
        dispersion_ps_per_ghz: 0.0,
        dac_sinc: false,
        bandwidth_hz: 0.0,
        response: Vec::new(),
        tx_iq_gain_db: 0.0,
        tx_iq_phase_deg: 0.0,
        tx_iq_skew_ps: 0.0,
        rx_iq_skew_ps: 0.0,
        multipath_extra_m: 0.3,
        multipath_level_db: f64::NEG_INFINITY,
        multipath_phase_deg: 180.0,
        cable_echo_ns: 15.0,
        cable_echo_db: f64::NEG_INFINITY,
        cable_echo_phase_deg: 0.0,
        shared_reference: true,
        timebase_offset_ppm: 0.0,
        shared_lo: true,
        tx_p1db_v: f64::INFINITY,
        drift_ps_per_min: 0.0,
        drift_deg_per_min: 0.0,
    };

    /// The thesis' bench, as examples/scene.toml explains field by field.
    pub fn thesis_lab() -> ChainParams {
        ChainParams {
            tilt_db_per_ghz: -0.8,
            // -20 dB, 1.25 ns behind (a horn-to-module standing wave over ~15 cm of WR-12): on
            // the thesis' chirp, swept 0..1 GHz, it raises the side-lobe behind the peak to the
            // lab's -10.5 dB (Table 4.5); on the centred OFDM band it widens the main lobe as the
            // lab's did (Table 4.7). Searched for those figures with a range bias of 1-3 mm.
            ripple_db: 1.8,
            ripple_period_hz: 800e6,
            ripple_phase_deg: 285.0,
            group_delay_ripple_ps: 20.0,
            group_delay_ripple_period_hz: 400e6,
            dispersion_ps_per_ghz: -6.0,
            dac_sinc: true,
            bandwidth_hz: 5e9,
            response: Vec::new(),
            tx_iq_gain_db: 0.4,
            tx_iq_phase_deg: 3.0,
            tx_iq_skew_ps: 2.0,
            rx_iq_skew_ps: 3.0,
            ..ChainParams::IDEAL
        }
    }

    /// True when the chain does nothing: the synthesis skips every chain step.
    pub fn is_ideal(&self) -> bool {
        *self == ChainParams::IDEAL
    }

    /// The drift at `clock_s` on the simulated clock: (extra delay s, extra phase rad).
    pub(crate) fn drift_at(&self, clock_s: f64) -> (f64, f64) {
        let minutes = clock_s / 60.0;
        (
            self.drift_ps_per_min * 1e-12 * minutes,
            self.drift_deg_per_min.to_radians() * minutes,
        )
    }

    /// The scope's timebase error, relative (0 with a shared reference).
    pub(crate) fn timebase_error(&self) -> f64 {
        if self.shared_reference {
            0.0
        } else {
            self.timebase_offset_ppm * 1e-6
        }
    }

    /// Whether the Tx side needs I and Q treated apart (imbalance, skew, the per-channel filters).
    pub(crate) fn tx_widely_linear(&self) -> bool {
        self.tx_iq_gain_db != 0.0 || self.tx_iq_phase_deg != 0.0 || self.tx_iq_skew_ps != 0.0
    }

    /// The second path's voltage ratio to the direct one (0 = none).
    pub(crate) fn multipath_ratio(&self) -> f64 {
        if self.multipath_level_db.is_finite() {
            10f64.powf(self.multipath_level_db / 20.0)
        } else {
            0.0
        }
    }

    /// Extra delay of the second path, seconds.
    pub(crate) fn multipath_delay_s(&self) -> f64 {
        self.multipath_extra_m / C0
    }

    /// The per-channel (real) filter on I and Q at baseband frequency `f`: the DAC's sinc at the
    /// AWG rate `fs` and the analogue roll-off, their delay at DC removed.
    pub(crate) fn channel_filter(&self, f: f64, fs: f64) -> Complex64 {
        let mut h = Complex64::new(1.0, 0.0);
        if self.dac_sinc && f != 0.0 {
            let x = PI * f / fs;
            h *= x.sin() / x;
        }
        if self.bandwidth_hz > 0.0 {
            let w = f / self.bandwidth_hz;
            // 2nd-order Butterworth; its group delay at DC, sqrt(2) / (2 pi B), removed.
            let b = Complex64::new(1.0 - w * w, std::f64::consts::SQRT_2 * w);
            let delay0 = std::f64::consts::SQRT_2 / (2.0 * PI * self.bandwidth_hz);
            h *= Complex64::from_polar(1.0, 2.0 * PI * f * delay0) / b;
        }
        h
    }

    /// The complex-baseband response of the RF chain at baseband frequency `f` (tilt, standing
    /// wave, group-delay ripple, dispersion, the table).
    pub fn response_at(&self, f: f64) -> Complex64 {
        let ghz = f / 1e9;
        let mut h = Complex64::from(10f64.powf(self.tilt_db_per_ghz * ghz / 20.0));
        if self.ripple_db > 0.0 {
            // A standing wave between two mismatches: 1 / (1 - g e^{-j(2 pi f T + psi)}) swings
            // between 1/(1+g) and 1/(1-g), i.e. 20 log((1+g)/(1-g)) dB peak-to-peak.
            let r = 10f64.powf(self.ripple_db / 20.0);
            let g = (r - 1.0) / (r + 1.0);
            let phase = 2.0 * PI * f / self.ripple_period_hz + self.ripple_phase_deg.to_radians();
            h /= Complex64::new(1.0, 0.0) - Complex64::from_polar(g, -phase);
        }
        if self.group_delay_ripple_ps > 0.0 {
            // phi(f) = A sin(2 pi f / P) has group delay -(A / P) cos(...): p-p 2 A / P.
            let a = self.group_delay_ripple_ps * 1e-12 * self.group_delay_ripple_period_hz / 2.0;
            h *= Complex64::from_polar(
                1.0,
                a * (2.0 * PI * f / self.group_delay_ripple_period_hz).sin(),
            );
        }
        if self.dispersion_ps_per_ghz != 0.0 {
            // Group delay D f gives phase -pi D f^2.
            let d = self.dispersion_ps_per_ghz * 1e-12 / 1e9;
            h *= Complex64::from_polar(1.0, -PI * d * f * f);
        }
        if self.cable_echo_db.is_finite() {
            // One echo behind every path (leakage included): the cable's round trip.
            let g = 10f64.powf(self.cable_echo_db / 20.0);
            let phase =
                2.0 * PI * f * self.cable_echo_ns * 1e-9 + self.cable_echo_phase_deg.to_radians();
            h *= Complex64::new(1.0, 0.0) + Complex64::from_polar(g, -phase);
        }
        if !self.response.is_empty() {
            let [gain_db, phase_deg] = interpolate(&self.response, f);
            h *= Complex64::from_polar(10f64.powf(gain_db / 20.0), phase_deg.to_radians());
        }
        h
    }

    /// The Tx's soft limiter on one complex sample (volts in, volts out).
    pub(crate) fn compress(&self, v: Complex64) -> Complex64 {
        if !self.tx_p1db_v.is_finite() {
            return v;
        }
        // Rapp, p = 2: |y| = |x| / (1 + (|x|/A)^4)^(1/4); 1 dB down at |x| = 0.8745 A.
        let saturation = self.tx_p1db_v / 0.874_5;
        let r = v.norm() / saturation;
        v / (1.0 + r.powi(4)).powf(0.25)
    }
}

/// Gain (dB) and phase (degrees) of a response table at `f`: linear between points, held beyond
/// the ends.
fn interpolate(table: &[[f64; 3]], f: f64) -> [f64; 2] {
    let first = table[0];
    let last = table[table.len() - 1];
    if f <= first[0] {
        return [first[1], first[2]];
    }
    if f >= last[0] {
        return [last[1], last[2]];
    }
    let k = table.partition_point(|p| p[0] <= f);
    let (a, b) = (table[k - 1], table[k]);
    let t = (f - a[0]) / (b[0] - a[0]);
    [a[1] + t * (b[1] - a[1]), a[2] + t * (b[2] - a[2])]
}

impl Chain {
    /// The preset with this section's fields written over it.
    pub fn resolve(&self) -> ChainParams {
        let base = match self.preset {
            ChainPreset::Ideal => ChainParams::IDEAL,
            ChainPreset::ThesisLab => ChainParams::thesis_lab(),
        };
        ChainParams {
            tilt_db_per_ghz: self.tilt_db_per_ghz.unwrap_or(base.tilt_db_per_ghz),
            ripple_db: self.ripple_db.unwrap_or(base.ripple_db),
            ripple_period_hz: self.ripple_period_hz.unwrap_or(base.ripple_period_hz),
            ripple_phase_deg: self.ripple_phase_deg.unwrap_or(base.ripple_phase_deg),
            group_delay_ripple_ps: self
                .group_delay_ripple_ps
                .unwrap_or(base.group_delay_ripple_ps),
            group_delay_ripple_period_hz: self
                .group_delay_ripple_period_hz
                .unwrap_or(base.group_delay_ripple_period_hz),
            dispersion_ps_per_ghz: self
                .dispersion_ps_per_ghz
                .unwrap_or(base.dispersion_ps_per_ghz),
            dac_sinc: self.dac_sinc.unwrap_or(base.dac_sinc),
            bandwidth_hz: self.bandwidth_hz.unwrap_or(base.bandwidth_hz),
            response: self.response.clone().unwrap_or(base.response),
            tx_iq_gain_db: self.tx_iq_gain_db.unwrap_or(base.tx_iq_gain_db),
            tx_iq_phase_deg: self.tx_iq_phase_deg.unwrap_or(base.tx_iq_phase_deg),
            tx_iq_skew_ps: self.tx_iq_skew_ps.unwrap_or(base.tx_iq_skew_ps),
            rx_iq_skew_ps: self.rx_iq_skew_ps.unwrap_or(base.rx_iq_skew_ps),
            multipath_extra_m: self.multipath_extra_m.unwrap_or(base.multipath_extra_m),
            multipath_level_db: self.multipath_level_db.unwrap_or(base.multipath_level_db),
            multipath_phase_deg: self.multipath_phase_deg.unwrap_or(base.multipath_phase_deg),
            cable_echo_ns: self.cable_echo_ns.unwrap_or(base.cable_echo_ns),
            cable_echo_db: self.cable_echo_db.unwrap_or(base.cable_echo_db),
            cable_echo_phase_deg: self
                .cable_echo_phase_deg
                .unwrap_or(base.cable_echo_phase_deg),
            shared_reference: self.shared_reference.unwrap_or(base.shared_reference),
            timebase_offset_ppm: self.timebase_offset_ppm.unwrap_or(base.timebase_offset_ppm),
            shared_lo: self.shared_lo.unwrap_or(base.shared_lo),
            tx_p1db_v: self.tx_p1db_v.unwrap_or(base.tx_p1db_v),
            drift_ps_per_min: self.drift_ps_per_min.unwrap_or(base.drift_ps_per_min),
            drift_deg_per_min: self.drift_deg_per_min.unwrap_or(base.drift_deg_per_min),
        }
    }

    /// Checks every written field against what the model represents (the realistic ranges are
    /// narrower; examples/scene.toml gives them).
    pub fn validate(&self) -> Result<(), SceneError> {
        let p = self.resolve();
        finite_in("chain.tilt_db_per_ghz", p.tilt_db_per_ghz, -10.0, 10.0)?;
        finite_in("chain.ripple_db", p.ripple_db, 0.0, 10.0)?;
        finite_in("chain.ripple_period_hz", p.ripple_period_hz, 1e6, 1e12)?;
        finite_in("chain.ripple_phase_deg", p.ripple_phase_deg, -360.0, 360.0)?;
        finite_in(
            "chain.group_delay_ripple_ps",
            p.group_delay_ripple_ps,
            0.0,
            1000.0,
        )?;
        finite_in(
            "chain.group_delay_ripple_period_hz",
            p.group_delay_ripple_period_hz,
            1e6,
            1e12,
        )?;
        finite_in(
            "chain.dispersion_ps_per_ghz",
            p.dispersion_ps_per_ghz,
            -1000.0,
            1000.0,
        )?;
        if p.bandwidth_hz != 0.0 {
            finite_in("chain.bandwidth_hz", p.bandwidth_hz, 1e6, 1e12)?;
        }
        finite_in("chain.tx_iq_gain_db", p.tx_iq_gain_db, -6.0, 6.0)?;
        finite_in("chain.tx_iq_phase_deg", p.tx_iq_phase_deg, -45.0, 45.0)?;
        finite_in("chain.tx_iq_skew_ps", p.tx_iq_skew_ps, -100.0, 100.0)?;
        finite_in("chain.rx_iq_skew_ps", p.rx_iq_skew_ps, -100.0, 100.0)?;
        finite_in("chain.multipath_extra_m", p.multipath_extra_m, 0.0, 100.0)?;
        if p.multipath_level_db != f64::NEG_INFINITY {
            finite_in(
                "chain.multipath_level_db",
                p.multipath_level_db,
                -120.0,
                0.0,
            )?;
        }
        finite_in(
            "chain.multipath_phase_deg",
            p.multipath_phase_deg,
            -360.0,
            360.0,
        )?;
        finite_in("chain.cable_echo_ns", p.cable_echo_ns, 0.1, 200.0)?;
        if p.cable_echo_db != f64::NEG_INFINITY {
            finite_in("chain.cable_echo_db", p.cable_echo_db, -120.0, -3.0)?;
        }
        finite_in(
            "chain.cable_echo_phase_deg",
            p.cable_echo_phase_deg,
            -360.0,
            360.0,
        )?;
        finite_in(
            "chain.timebase_offset_ppm",
            p.timebase_offset_ppm,
            -100.0,
            100.0,
        )?;
        if p.shared_reference && p.timebase_offset_ppm != 0.0 {
            return Err(invalid(
                "chain.timebase_offset_ppm",
                "a timebase offset needs `shared_reference = false` (with a shared 10 MHz \
                 reference the AWG and the scope run at one rate)",
            ));
        }
        if p.tx_p1db_v.is_finite() {
            finite_in("chain.tx_p1db_v", p.tx_p1db_v, 1e-3, 100.0)?;
        }
        if let Some(table) = &self.response {
            check_table(table)?;
        }
        finite_in(
            "chain.drift_ps_per_min",
            p.drift_ps_per_min,
            -1000.0,
            1000.0,
        )?;
        finite_in(
            "chain.drift_deg_per_min",
            p.drift_deg_per_min,
            -3600.0,
            3600.0,
        )?;
        Ok(())
    }
}

fn check_table(table: &[[f64; 3]]) -> Result<(), SceneError> {
    if table.is_empty() || table.len() > 65_536 {
        return Err(invalid(
            "chain.response",
            format!(
                "{} points; allowed: 1 to 65536 [frequency offset Hz, gain dB, phase deg] points",
                table.len()
            ),
        ));
    }
    for (i, [f, g, p]) in table.iter().enumerate() {
        finite_in(&format!("chain.response[{i}][0]"), *f, -1e12, 1e12)?;
        finite_in(&format!("chain.response[{i}][1]"), *g, -100.0, 40.0)?;
        finite_in(&format!("chain.response[{i}][2]"), *p, -1e6, 1e6)?;
        if i > 0 && *f <= table[i - 1][0] {
            return Err(invalid(
                format!("chain.response[{i}][0]"),
                format!(
                    "{f} Hz is not above the previous point's {} Hz: list the points in \
                     ascending frequency",
                    table[i - 1][0]
                ),
            ));
        }
    }
    Ok(())
}

/// The 4-point cubic (Catmull-Rom) value of `y` at fractional index `pos` (held at the ends). The
/// record is oversampled many times over (80 GSa/s for a 1 GHz band), so this is exact to far
/// below the ADC's resolution.
pub(crate) fn cubic_at(y: &[Complex64], pos: f64) -> Complex64 {
    let n = y.len() as isize;
    let i = pos.floor();
    let t = pos - i;
    let i = i as isize;
    let at = |k: isize| y[k.clamp(0, n - 1) as usize];
    let (p0, p1, p2, p3) = (at(i - 1), at(i), at(i + 1), at(i + 2));
    let a = p1 * 2.0;
    let b = p2 - p0;
    let c = p0 * 2.0 - p1 * 5.0 + p2 * 4.0 - p3;
    let d = -p0 + p1 * 3.0 - p2 * 3.0 + p3;
    (a + (b + (c + d * t) * t) * t) * 0.5
}
