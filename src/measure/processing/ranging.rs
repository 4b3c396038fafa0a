//! Each target's standard uncertainty of range (`range_std_m`), and `--ranging phase`: the
//! envelope's range refined by the echo's carrier phase (docs/metrology.md).
//!
//! The uncertainty, in both modes, is the root sum of squares of
//! * the SNR's: the envelope's Cramer-Rao bound for the profile's band and window
//!   ([`BandShape`]), or in phase mode the carrier phase's;
//! * the trigger's jitter left in the record: the scope's stated jitter for the envelope (a
//!   record's envelope moves with its trigger), what the in-record reference leaves of it in
//!   phase mode (none reaches the carrier phase, but the envelope that unwraps it has it);
//! * the calibration's own: the reference's, measured the same way in the calibration's record
//!   (its jitter included for the envelope);
//! * in phase mode, the coupling of a target and its phase reference: what the correction leaves
//!   of each where the other stands (the calibration's residual profile), which turns with the
//!   target's phase since the calibration;
//! * unwrapping: a cycle is taken only where the envelope tells it within `lambda / 8` (the
//!   target falls back to its envelope range with a warning otherwise), so a wrong cycle is a
//!   2.6 sd event and not carried.

pub(crate) use super::detect::PhaseRanged;
use super::detect::{Detection, DetectionReport};
use super::options::{ProcessOptions, Ranging};
use crate::dsp::carrier_phase::{
    metres_per_radian, phase_std_rad, unwrap_limit_m, unwrap_range, wrap, BandShape,
};
use crate::dsp::ResidualFloor;
use crate::measure::calibration::response::PhaseAnchor;
use crate::physics::C0;
use num_complex::Complex64;

/// The scope's RMS trigger jitter assumed where the bench file states none
/// (`[scope] trigger_jitter_s`), seconds: a real-time scope's edge trigger, 0.1 ps (LabMaster's
/// software-assisted trigger) to 2 ps (a plain hardware trigger) on their data sheets.
pub(crate) const TYPICAL_TRIGGER_JITTER_S: f64 = 1e-12;

/// The leakage is sought within this of where the calibration found it, m: it moves with the
/// trigger's jitter and the chain's drift (1 ps is 0.15 mm).
const LEAKAGE_SEARCH_M: f64 = 0.02;

/// A campaign's previous step, for a target it moved (`--ranging phase`): that step's phase
/// range, and the move commanded since, m. Under lambda / 4 the phase unwraps against it rather
/// than the envelope (docs/metrology.md).
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct Previous {
    pub(crate) then: PhaseRanged,
    pub(crate) moved_m: f64,
}

/// A target is the one a [`Previous`] expects within this of where it expects it, m (the
/// envelope's jitter is a few hundred micrometres; a campaign's targets stand centimetres apart).
const PREVIOUS_MATCH_M: f64 = 0.005;

/// How a phase range was unwrapped ([`Detection::ranging`]).
const BY_ENVELOPE: &str = "phase";
const BY_PREVIOUS: &str = "phase-previous";

/// What a pipeline needs to give its targets an uncertainty and, in phase mode, their phase
/// ranges; made once per pipeline.
#[derive(Debug, Clone)]
pub(crate) struct RangingModel {
    mode: Ranging,
    band: Option<BandShape>,
    carrier_hz: f64,
    /// The stated trigger jitter as range, m.
    jitter_m: f64,
    /// The calibration's anchor, when the correction's calibration measured one.
    anchor: Option<PhaseAnchor>,
    /// The envelope's calibration uncertainty, m (the delay or response calibration's own).
    calibration_std_m: f64,
    /// A campaign's previous step (its moved targets), for the records of the step it is set
    /// for ([`Self::set_previous`], every step).
    previous: Vec<Previous>,
    /// What the correction leaves around every path with this window (the calibration's
    /// residual profile): how much of a target lies where its phase reference stands, and of
    /// the reference where the target stands.
    residual: Option<ResidualFloor>,
}

/// One echo as the ranging takes it: fitted range (m), complex amplitude, SNR per cell.
#[derive(Debug, Clone, Copy)]
struct Echo {
    range_m: f64,
    amplitude: Complex64,
    snr: f64,
}

impl Echo {
    /// The echo at `range_m` of complex `amplitude` over the noise per cell `noise_per_cell`;
    /// `None` without a usable noise or SNR.
    fn over_noise(range_m: f64, amplitude: Complex64, noise_per_cell: Option<f64>) -> Option<Echo> {
        let noise = noise_per_cell.filter(|n| *n > 0.0)?;
        let snr = amplitude.norm_sqr() / noise;
        (snr.is_finite() && snr > 0.0).then_some(Echo {
            range_m,
            amplitude,
            snr,
        })
    }
}

fn echo_of(d: &Detection, noise_per_cell: Option<f64>) -> Option<Echo> {
    let (range_m, amplitude) = d.fitted?;
    let snr_db = match noise_per_cell {
        Some(n) if n > 0.0 => Some(10.0 * (amplitude.norm_sqr() / n).log10()),
        _ => d.snr_db.or(d.peak_to_floor_db),
    }?;
    let snr = 10f64.powf(snr_db / 10.0);
    (snr.is_finite() && snr > 0.0).then_some(Echo {
        range_m,
        amplitude,
        snr,
    })
}

/// A phase reference (the leakage, or the named reflector) this far over the noise per cell at
/// least, dB: its phase then within 0.022 rad (7 um of range) from the noise alone. Weaker, it
/// is a peak of the noise or a correction's residue where no leakage is (a calibration's record
/// without leakage showed one at 24 dB, 0.09 m, and phase ranges against it erred by 100 um).
const MIN_REFERENCE_SNR_DB: f64 = 30.0;

/// The calibration's residual profile cannot see where its own phase reference stood from its
/// pillar (the reference's echo was divided out there): it holds the largest level within 1 ns
/// beside that place, this far each side of it, m. A target near the calibration's pillar finds
/// its reference there.
const UNSEEN_HALF_M: f64 = 0.15;

/// ... and that largest level, of the two or three range cells it is taken from, stands about
/// this many times over their mean power (the expected largest of 2 and 3 exponential draws:
/// 1.5 and 1.8), which the coupling of a target and its reference takes.
const FILLED_OVER_MEAN: f64 = 2.0;

/// A named reflector is sought this close to where the user put it, m (as the calibration
/// seeks it: `calibrate response --reflector`).
const NAMED_NEAR_M: f64 = 0.075;

/// The leakage is sought this close to the horns in a calibration's record, m.
const LEAKAGE_REACH_M: f64 = 0.3;

/// Echoes are added back this far around a phase reference's search
/// ([`DetectionReport::echo_near`]), m: a main lobe and more (13 cm at 3 dB for the thesis'
/// band), so every echo CLEAN split a reference's neighbourhood into is taken, and a target a
/// reference range away (0.8 m at least) is not.
const REFERENCE_NEIGHBOURHOOD_M: f64 = 0.15;

/// The leakage (or a fixed reflector) within `within` (m): the one echo that best fits the
/// profile there, the echoes CLEAN fitted near it added back to the residual. Fitting the
/// profile, not CLEAN's split of it, gives the same reference in the calibration's record and in
/// every capture: the leakage and a mount 12 cm from it were fitted as one echo in one record and
/// as two in another, and phase ranges against them erred by 460 um (a quarter cycle) with 13 um
/// stated. Without the detector's spread: the strongest of the echoes fitted there (CLEAN fits
/// the leakage as a reflector outside the range window) and the residual's peak there (where
/// CLEAN left it as part of a strong target's response).
fn leakage(
    report: &DetectionReport,
    within: std::ops::RangeInclusive<f64>,
    noise_per_cell: Option<f64>,
) -> Option<Echo> {
    if let Some((range_m, amplitude)) = report.echo_near(within.clone(), REFERENCE_NEIGHBOURHOOD_M)
    {
        return Echo::over_noise(range_m, amplitude, noise_per_cell);
    }
    report
        .outside
        .iter()
        .chain(&report.targets)
        .filter_map(|d| echo_of(d, noise_per_cell))
        .filter(|e| within.contains(&e.range_m))
        .chain(residual_peak(report, within.clone(), noise_per_cell))
        .max_by(|a, b| a.amplitude.norm().total_cmp(&b.amplitude.norm()))
}

/// The strongest peak of the detection's residual within `within` (m): the leakage, which CLEAN
/// leaves in it as part of a strong target's response (its chain floor), or which no target took.
/// Its position from a parabola through the peak's power and its neighbours', its complex value
/// interpolated there (cubic; the profile is oversampled several times over a main lobe).
fn residual_peak(
    report: &DetectionReport,
    within: std::ops::RangeInclusive<f64>,
    noise_per_cell: Option<f64>,
) -> Option<Echo> {
    let axis = report.axis?;
    let r = &report.residual_complex;
    let peak = (1..r.len().saturating_sub(1))
        .filter(|&k| within.contains(&axis.at(k as f64)))
        .max_by(|&a, &b| r[a].norm_sqr().total_cmp(&r[b].norm_sqr()))?;
    let (l, c, h) = (
        r[peak - 1].norm_sqr(),
        r[peak].norm_sqr(),
        r[peak + 1].norm_sqr(),
    );
    let curvature = l - 2.0 * c + h;
    let offset = if curvature < 0.0 {
        (0.5 * (l - h) / curvature).clamp(-0.5, 0.5)
    } else {
        0.0
    };
    let at = peak as f64 + offset;
    Echo::over_noise(axis.at(at), cubic_at(r, at), noise_per_cell)
}

/// `y` at fractional index `pos` by cubic (Catmull-Rom) interpolation of its four neighbours.
fn cubic_at(y: &[Complex64], pos: f64) -> Complex64 {
    let i = pos.floor() as isize;
    let t = pos - i as f64;
    let at = |k: isize| y[k.clamp(0, y.len() as isize - 1) as usize];
    let (p0, p1, p2, p3) = (at(i - 1), at(i), at(i + 1), at(i + 2));
    let a = p1 * 2.0;
    let b = p2 - p0;
    let c = p0 * 2.0 - p1 * 5.0 + p2 * 4.0 - p3;
    let d = p3 - p0 + (p1 - p2) * 3.0;
    (a + (b + (c + d * t) * t) * t) * 0.5
}

impl RangingModel {
    /// The model of `options` for a profile of band shape `band` (`None`: no complex profile),
    /// with the correction's calibration anchor `anchor`.
    pub(crate) fn new(
        options: &ProcessOptions,
        band: Option<BandShape>,
        anchor: Option<PhaseAnchor>,
        residual: Option<ResidualFloor>,
    ) -> Self {
        let jitter_s = options.trigger_jitter_s.unwrap_or(TYPICAL_TRIGGER_JITTER_S);
        let jitter_m = C0 * jitter_s / 2.0;
        // A response calibration sets the ranges (its reference lands at its stated range):
        // its reference's envelope uncertainty is the calibration's. Without one, a measured
        // system delay carries its capture's jitter.
        let calibration_std_m = match (&options.correction, anchor) {
            (Some(_), Some(a)) => a.envelope_std_m(jitter_m),
            (Some(_), None) => jitter_m,
            (None, _) if options.system_delay_s != 0.0 => jitter_m,
            (None, _) => 0.0,
        };
        Self {
            mode: options.ranging,
            band,
            carrier_hz: options.carrier_hz,
            jitter_m,
            anchor: options.correction.as_ref().and(anchor),
            calibration_std_m,
            previous: Vec::new(),
            residual,
        }
    }

    /// The calibration's record as the step before a campaign's first (its pillar stood at the
    /// reference range; the stage has moved to `set` since): one [`Previous`] per target set,
    /// in phase mode with a calibration anchor; none otherwise.
    pub(crate) fn calibration_as_previous(&self, set: &[f64]) -> Vec<Previous> {
        let (Ranging::Phase, Some(a)) = (self.mode, self.anchor) else {
            return Vec::new();
        };
        // The calibration's envelope is its reference's, at its stated range by construction.
        let then = PhaseRanged {
            range_m: a.range_m,
            std_m: a.phase_std_rad * metres_per_radian(self.carrier_hz),
            envelope_m: a.range_m,
            envelope_std_m: 0.0,
        };
        set.iter()
            .map(|&at| Previous {
                then,
                moved_m: at - a.range_m,
            })
            .collect()
    }

    /// The next record's previous step ([`Previous`]); a move of lambda / 4 or more is not
    /// taken (its cycle is not known from the step alone).
    pub(crate) fn set_previous(&mut self, previous: Vec<Previous>) {
        let quarter = 2.0 * unwrap_limit_m(self.carrier_hz);
        self.previous = previous
            .into_iter()
            .filter(|p| p.moved_m.abs() < quarter && p.then.std_m.is_finite())
            .collect();
    }

    /// The envelope's standard uncertainty from the SNR alone, m.
    fn snr_std_m(&self, snr: f64) -> Option<f64> {
        self.band.map(|b| b.envelope_std_m(snr))
    }

    /// Sets every target's `range_std_m`; in phase mode refines its range first. Returns the
    /// warnings (a target left at its envelope range, and why).
    pub(crate) fn apply(
        &self,
        report: &mut DetectionReport,
        noise_per_cell: Option<f64>,
    ) -> Vec<String> {
        let previous = &self.previous;
        let mut warnings = Vec::new();
        let reference = match self.mode {
            Ranging::Envelope => None,
            Ranging::Phase => match self.in_record_reference(report, noise_per_cell) {
                Ok(r) => Some(r),
                Err(why) => {
                    warnings.push(format!(
                        "--ranging phase: {why}; every range is the envelope's"
                    ));
                    None
                }
            },
        };
        let mut fixed_echoes: Vec<Echo> = report
            .targets
            .iter()
            .filter_map(|d| echo_of(d, noise_per_cell))
            .collect();
        // The calibration's fixed reflector where CLEAN did not report it (a named one may stand
        // in a strong target's chain floor): the strongest echo or residual peak where it was.
        if let Some(then) = reference.as_ref().and_then(|(a, _)| a.fixed_range_m) {
            let near = then - LEAKAGE_SEARCH_M..=then + LEAKAGE_SEARCH_M;
            fixed_echoes.extend(leakage(report, near, noise_per_cell));
        }
        for t in &mut report.targets {
            let Some(echo) = echo_of(t, noise_per_cell) else {
                continue;
            };
            let Some(snr_std) = self.snr_std_m(echo.snr) else {
                continue;
            };
            let envelope_std =
                (snr_std.powi(2) + self.jitter_m.powi(2) + self.calibration_std_m.powi(2)).sqrt();
            t.range_std_m = Some(envelope_std);
            if let Some((anchor, leak)) = &reference {
                let fixed = self.fixed_echo(anchor, &fixed_echoes, &echo);
                let off = |p: &Previous| (p.then.range_m + p.moved_m - echo.range_m).abs();
                let expected = previous
                    .iter()
                    .filter(|p| off(p) <= PREVIOUS_MATCH_M)
                    .min_by(|a, b| off(a).total_cmp(&off(b)));
                match self.phase_range(anchor, leak, &echo, snr_std, fixed, expected) {
                    Ok((ranged, by, note)) => {
                        t.range_m = ranged.range_m;
                        t.range_std_m = Some(ranged.std_m);
                        t.ranging = Some(by);
                        t.phase_ranged = Some(ranged);
                        warnings.extend(note);
                    }
                    Err(why) => warnings.push(format!(
                        "--ranging phase: the target at {:.6} m keeps its envelope range: {why}",
                        t.range_m
                    )),
                }
            }
        }
        warnings
    }

    /// The calibration record's fixed reflector in this record, for a target `echo` other than
    /// it: (its range now, the variance of its move, its range then).
    fn fixed_echo(
        &self,
        anchor: &PhaseAnchor,
        echoes: &[Echo],
        echo: &Echo,
    ) -> Option<(f64, f64, f64)> {
        let (then_m, then_std) = (anchor.fixed_range_m?, anchor.fixed_snr_std_m?);
        let now = echoes
            .iter()
            .filter(|e| (e.range_m - then_m).abs() <= LEAKAGE_SEARCH_M)
            .filter(|e| (e.range_m - echo.range_m).abs() > LEAKAGE_SEARCH_M)
            .max_by(|a, b| a.amplitude.norm().total_cmp(&b.amplitude.norm()))?;
        let var = self.snr_std_m(now.snr)?.powi(2) + then_std.powi(2);
        Some((now.range_m, var, then_m))
    }

    /// The calibration's anchor and this record's leakage (the time and phase reference).
    fn in_record_reference(
        &self,
        report: &DetectionReport,
        noise_per_cell: Option<f64>,
    ) -> Result<(PhaseAnchor, Echo), String> {
        let anchor = self.anchor.ok_or(
            "no phase reference: capture with --calibration FILE of a response calibration \
             (`radbench calibrate response`) that measured one (one whose record showed no \
             Tx -> Rx leakage 30 dB over the noise has none: name a fixed reflector in the \
             reference's scene with `calibrate response --reflector M`)",
        )?;
        if self.band.is_none() {
            return Err(
                "this algorithm gives no complex profile (use correlation or fourier)".into(),
            );
        }
        let near =
            anchor.leakage_range_m - LEAKAGE_SEARCH_M..=anchor.leakage_range_m + LEAKAGE_SEARCH_M;
        let leak = leakage(report, near, noise_per_cell).ok_or_else(|| {
            format!(
                "{} (the time and phase reference, at {:.4} m in the calibration) is not in \
                 this record",
                anchor.reference_name(),
                anchor.leakage_range_m
            )
        })?;
        Ok((anchor, leak))
    }

    /// The variance of a target's phase against its reference's (rad^2) from what the
    /// correction leaves of each where the other stands (the calibration's residual profile at
    /// their offset, relative to each's amplitude): `|K|^2`, the variance of the error it makes
    /// over the target's phases ([`Self::coupling_left`] takes the calibration's record's share).
    /// A clutter point 0.75 m before the reference, which the calibration took for the chain's,
    /// left -51 dB where the leakage stood, and phase ranges erred by up to 21 um with 1.2 um
    /// stated (docs/metrology.md).
    fn coupling_rad2(&self, anchor: &PhaseAnchor, echo: &Echo, reference: &Echo) -> f64 {
        let Some(floor) = &self.residual else {
            return 0.0;
        };
        let behind_m = echo.range_m - reference.range_m;
        // Where the calibration's own reference stood from its pillar, the profile is the
        // largest level beside it (`calibration::response::fill_blind`).
        let unseen = anchor.envelope_range_m - anchor.leakage_range_m;
        let typical = if (behind_m - unseen).abs() <= UNSEEN_HALF_M {
            FILLED_OVER_MEAN.recip()
        } else {
            1.0
        };
        let ratio = (echo.amplitude.norm() / reference.amplitude.norm()).powi(2);
        typical * (floor.bin_at(-behind_m) * ratio + floor.bin_at(behind_m) / ratio)
    }

    /// The part of [`Self::coupling_rad2`] a target `moved_m` from the calibration's reference
    /// keeps: the calibration's record holds the same residue where the target stood then, so
    /// what is left is `|K|^2 (1 - rho cos phi)` for the target's phase `phi` since then and the
    /// correlation `rho` of the residues at the two offsets (1 at the same place, none a range
    /// cell apart): none at the calibration's place, twice the mean a quarter wavelength away.
    fn coupling_left(&self, moved_m: f64) -> f64 {
        // The range cell of a flat band as wide (RMS) as the profile's.
        let cell_m = self
            .band
            .map_or(0.0, |b| C0 / (2.0 * 12f64.sqrt() * b.rms_hz));
        let rho = if cell_m > 0.0 {
            (1.0 - moved_m.abs() / cell_m).max(0.0)
        } else {
            0.0
        };
        1.0 - rho * (moved_m / metres_per_radian(self.carrier_hz)).cos()
    }

    /// A target's range from its carrier phase against the anchor's, both relative to their
    /// record's leakage, with its standard uncertainty, and how its cycle was chosen (with a
    /// note when the `expected` previous step was not taken); or why not.
    fn phase_range(
        &self,
        anchor: &PhaseAnchor,
        leak: &Echo,
        echo: &Echo,
        snr_std_m: f64,
        fixed: Option<(f64, f64, f64)>,
        expected: Option<&Previous>,
    ) -> Result<(PhaseRanged, &'static str, Option<String>), String> {
        let leak_std = self.snr_std_m(leak.snr).unwrap_or(f64::INFINITY);
        // The envelope that unwraps the phase: the target against the anchor, less the common
        // move of the record (the trigger's jitter, capture's and calibration's) where a fixed
        // reflector of the calibration's record shows it (the leakage's envelope cannot: it is
        // cut by the profile's start), weighted by how well it knows it.
        let jitter_var = 2.0 * self.jitter_m.powi(2);
        // A move the jitter cannot explain (over 3 sd) is the chain's drift since the
        // calibration, which does not move every echo's fitted envelope alike (the receiver's
        // I/Q image and DC do not turn with the chain): it only tells that no cycle is guessed.
        // The fixed reflector's move tells it; without one, the leakage's, whose envelope is too
        // distorted to measure a move (docs/metrology.md, Known limits).
        let leak_move = leak.range_m - anchor.leakage_range_m;
        let leak_var = leak_std.powi(2) + anchor.leakage_snr_std_m.powi(2);
        let mut drifted = (fixed.is_none()
            && leak_move.abs() > 3.0 * (jitter_var + leak_var).sqrt())
        .then(|| (anchor.reference_name(), leak_move));
        let (weight, left_var, common_move) = match fixed {
            Some((now, fixed_var, then_m)) => {
                let moved = now - then_m;
                if moved.abs() > 3.0 * (jitter_var + fixed_var).sqrt() {
                    drifted = Some(("the fixed reflector", moved));
                }
                (
                    jitter_var / (jitter_var + fixed_var),
                    jitter_var * fixed_var / (jitter_var + fixed_var),
                    moved,
                )
            }
            None => (0.0, jitter_var, 0.0),
        };
        let rough =
            anchor.range_m + (echo.range_m - anchor.envelope_range_m) - weight * common_move;
        let rough_std = (snr_std_m.powi(2) + anchor.envelope_snr_std_m.powi(2) + left_var).sqrt();
        let envelope = (rough, rough_std);
        // The previous step's range plus the commanded move tells the cycle better than the
        // envelope, where the envelope moved as much since that step (a stage that moved
        // otherwise than commanded, or a wrong cycle there, shows as a disagreement). The chain's
        // slow drift moves the envelope between two steps by little, and the phase not at all
        // (the leakage goes through the same cables): a drift does not stop it.
        let (rough, rough_std, by, note) = match expected {
            Some(p) if p.then.std_m < rough_std => {
                let apart = (rough - p.then.envelope_m) - p.moved_m;
                let bound = 3.0 * (rough_std.powi(2) + p.then.envelope_std_m.powi(2)).sqrt();
                if apart.abs() <= bound {
                    (p.then.range_m + p.moved_m, p.then.std_m, BY_PREVIOUS, None)
                } else {
                    let note = format!(
                        "--ranging phase: the target at {:.6} m moved {:.3} mm more than \
                         commanded since the step before, by its envelope, more than the \
                         envelope's uncertainty explains: unwrapped by its envelope (did the \
                         stage move as commanded?)",
                        echo.range_m,
                        apart * 1e3
                    );
                    (rough, rough_std, BY_ENVELOPE, Some(note))
                }
            }
            _ => (rough, rough_std, BY_ENVELOPE, None),
        };
        if let (Some((what, moved)), BY_ENVELOPE) = (drifted, by) {
            return Err(format!(
                "{what} moved {:.2} mm since the calibration, more than the trigger's jitter \
                 explains: the chain drifted and the phase's cycle is not known (calibrate \
                 again; a campaign's steps under lambda/4 unwrap by the step before)",
                moved * 1e3
            ));
        }
        let phase = wrap((echo.amplitude / leak.amplitude).arg() - anchor.phase_to_leakage_rad);
        let range_m = unwrap_range(anchor.range_m, phase, rough, rough_std, self.carrier_hz)
            .ok_or_else(|| {
                format!(
                    "the envelope's uncertainty {:.0} um is over lambda/8 = {:.0} um, so the \
                     phase's cycle is not known (a wrong one is a {:.2} mm error)",
                    rough_std * 1e6,
                    unwrap_limit_m(self.carrier_hz) * 1e6,
                    4.0 * unwrap_limit_m(self.carrier_hz) * 1e3
                )
            })?;
        let coupling_var =
            self.coupling_rad2(anchor, echo, leak) * self.coupling_left(range_m - anchor.range_m);
        let phase_var = phase_std_rad(echo.snr).powi(2)
            + phase_std_rad(leak.snr).powi(2)
            + anchor.phase_std_rad.powi(2)
            + coupling_var;
        // The fitted position's error turns the fitted phase by 2 pi f_mean e: a range error of
        // f_mean / f_c times the envelope's.
        let centroid = self.band.map_or(0.0, |b| b.mean_hz) / self.carrier_hz;
        let std = (phase_var * metres_per_radian(self.carrier_hz).powi(2)
            + (centroid * snr_std_m).powi(2)
            + (centroid * leak_std).powi(2))
        .sqrt();
        let um = |rad: f64| rad * metres_per_radian(self.carrier_hz) * 1e6;
        tracing::debug!(
            target: "radbench::ranging",
            "unwrapping {by}: the envelope {:.1} um +- {:.1} um, the leakage moved {:.1} um",
            envelope.0 * 1e6,
            envelope.1 * 1e6,
            leak_move * 1e6
        );
        tracing::debug!(
            target: "radbench::ranging",
            "phase range {range_m:.7} m: sd {:.3} um of the target's phase {:.3}, the leakage's \
             {:.3}, the anchor's {:.3}, their coupling {:.3}, the envelope's centroid {:.3} and \
             the leakage's {:.3} (SNR per cell {:.1} and {:.1} dB)",
            std * 1e6,
            um(phase_std_rad(echo.snr)),
            um(phase_std_rad(leak.snr)),
            um(anchor.phase_std_rad),
            um(coupling_var.sqrt()),
            centroid * snr_std_m * 1e6,
            centroid * leak_std * 1e6,
            10.0 * echo.snr.log10(),
            10.0 * leak.snr.log10(),
        );
        let ranged = PhaseRanged {
            range_m,
            std_m: std,
            envelope_m: envelope.0,
            envelope_std_m: envelope.1,
        };
        Ok((ranged, by, note))
    }

    /// The anchor of a calibration's corrected reference record: the reference (the strongest
    /// target within 0.3 m of `reference_range_m`) against the leakage (the strongest echo
    /// before it, outside the range window) or, where the record shows none, against the
    /// reflector named at `reflector_m` (`calibrate response --reflector`). `None` when the
    /// reference or both are missing.
    pub(crate) fn anchor_of(
        &self,
        report: &DetectionReport,
        noise_per_cell: Option<f64>,
        reference_range_m: f64,
        reflector_m: Option<f64>,
    ) -> Option<PhaseAnchor> {
        let strongest = |it: &mut dyn Iterator<Item = Echo>| {
            it.max_by(|a, b| a.amplitude.norm().total_cmp(&b.amplitude.norm()))
        };
        let reference = strongest(
            &mut report
                .targets
                .iter()
                .filter_map(|d| echo_of(d, noise_per_cell))
                .filter(|e| (e.range_m - reference_range_m).abs() < 0.3),
        )?;
        let horns = f64::NEG_INFINITY..=LEAKAGE_REACH_M.min(reference.range_m - 0.3);
        // A phase reference under this SNR is a peak of the noise (where no leakage is), not one.
        let clear = |e: &Echo| e.snr >= 10f64.powf(MIN_REFERENCE_SNR_DB / 10.0);
        let named = |r: f64| {
            leakage(report, r - NAMED_NEAR_M..=r + NAMED_NEAR_M, noise_per_cell).filter(clear)
        };
        let (leak, by_reflector) = match leakage(report, horns, noise_per_cell).filter(clear) {
            Some(leak) => (leak, false),
            None => (reflector_m.and_then(named)?, true),
        };
        // A fixed reflector: the one named to the calibration (CLEAN may leave it in the
        // reference's chain floor rather than report it), else the strongest other target of
        // the calibration's record (the unwrapping's envelope takes the record's common move
        // from it, and its move tells a drift).
        let fixed = reflector_m.and_then(named).or_else(|| {
            strongest(
                &mut report
                    .targets
                    .iter()
                    .filter_map(|d| echo_of(d, noise_per_cell))
                    .filter(|e| (e.range_m - reference.range_m).abs() >= 0.3),
            )
        });
        Some(PhaseAnchor {
            // Set by the calibration, which knows how many records it averaged.
            repetitions: None,
            fixed_range_m: fixed.map(|f| f.range_m),
            fixed_snr_std_m: fixed.and_then(|f| self.snr_std_m(f.snr)),
            range_m: reference_range_m,
            envelope_range_m: reference.range_m,
            envelope_snr_std_m: self.snr_std_m(reference.snr)?,
            leakage_range_m: leak.range_m,
            leakage_snr_std_m: self.snr_std_m(leak.snr)?,
            phase_to_leakage_rad: (reference.amplitude / leak.amplitude).arg(),
            phase_std_rad: (phase_std_rad(reference.snr).powi(2) + phase_std_rad(leak.snr).powi(2))
                .sqrt(),
            by_reflector,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::waveform::WaveformKind;

    const LAMBDA_M: f64 = C0 / 80e9;

    /// A phase ranging model with a 1 GHz flat band, a residual profile of `-66 dB` in every
    /// bin but `ahead_db_at_1m` at 0.95-1.0 m ahead, and an anchor whose pillar stood 0.5 m
    /// behind its leakage.
    fn model(ahead_db_at_1m: f64) -> (RangingModel, PhaseAnchor) {
        let mut options = ProcessOptions::for_waveform(WaveformKind::MskLfm);
        options.carrier_hz = 80e9;
        let band = BandShape {
            mean_hz: 0.5e9,
            rms_hz: 1e9 / 12f64.sqrt(),
        };
        let mut ahead = vec![-66.0; 40];
        ahead[19] = ahead_db_at_1m;
        let floor = ResidualFloor::from_db(0.05, &[-66.0; 40], &ahead).unwrap();
        let anchor = PhaseAnchor {
            range_m: 0.53,
            envelope_range_m: 0.53,
            envelope_snr_std_m: 1e-5,
            leakage_range_m: 0.03,
            leakage_snr_std_m: 1e-4,
            phase_to_leakage_rad: 0.0,
            phase_std_rad: 1e-3,
            fixed_range_m: None,
            fixed_snr_std_m: None,
            repetitions: Some(16),
            by_reflector: false,
        };
        let m = RangingModel::new(&options, Some(band), Some(anchor), Some(floor));
        (m, anchor)
    }

    fn echo(range_m: f64, amplitude: f64) -> Echo {
        Echo {
            range_m,
            amplitude: Complex64::new(amplitude, 0.0),
            snr: 1e7,
        }
    }

    #[test]
    fn the_coupling_is_the_profile_where_each_echo_finds_the_other() {
        let (m, anchor) = model(-50.0);
        let (target, leakage) = (echo(1.005, 0.5), echo(0.03, 0.03));
        // The target's residue 0.975 m ahead of it, over the leakage's amplitude, and the
        // leakage's 0.975 m behind it, over the target's.
        let ratio = (0.5f64 / 0.03).powi(2);
        let expected = 1e-5 * ratio + 10f64.powf(-6.6) / ratio;
        let k2 = m.coupling_rad2(&anchor, &target, &leakage);
        assert!(
            (k2 - expected).abs() < 1e-9 * expected,
            "{k2} against {expected}"
        );
        // Where the calibration's own reference stood from its pillar (0.5 m), the profile is
        // the largest level beside it: half of it is taken.
        let near = echo(0.53, 0.5);
        let unseen = 10f64.powf(-6.6) * (ratio + 1.0 / ratio) / FILLED_OVER_MEAN;
        let k2 = m.coupling_rad2(&anchor, &near, &leakage);
        assert!((k2 - unseen).abs() < 1e-9 * unseen, "{k2} against {unseen}");
    }

    #[test]
    fn the_calibrations_share_of_the_coupling_is_none_at_its_place_and_twice_a_quarter_wave_off() {
        let (m, _) = model(-66.0);
        assert!(m.coupling_left(0.0).abs() < 1e-12);
        let quarter = m.coupling_left(LAMBDA_M / 4.0);
        assert!((1.98..=2.0).contains(&quarter), "{quarter}");
        // Half a wavelength on, the target's phase has come round: almost none again.
        assert!(m.coupling_left(LAMBDA_M / 2.0) < 0.02);
        // A range cell (15 cm) and more away the residues are other ones: the mean.
        assert_eq!(m.coupling_left(0.2), 1.0);
        assert_eq!(m.coupling_left(-0.2), 1.0);
    }
}
