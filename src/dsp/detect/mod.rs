//! Target detection on a complex range profile with the waveform's known point spread.
//!
//! # What it does
//! A profile is `z[c] = sum_i a_i g(c - x_i) + noise`: point targets of complex amplitude `a_i` at
//! fractional cells `x_i`, seen through the point spread `g` of the waveform and the processing
//! (`psf`). [`Detector::detect`] finds the targets, fits each one's sub-cell position and
//! complex amplitude, and measures each one's own response.
//!
//! **CLEAN** ([`Method::Clean`], the default): take the strongest local maximum of the residual
//! that passes the threshold, fit a target there (least squares with `g`: golden-section search on
//! the position, closed-form amplitude), re-fit every target against the profile minus the others
//! (RELAX) so close targets do not bias each other, subtract, and search again; stop when no
//! residual peak passes the threshold or at [`DetectOptions::max_targets`]. Side-lobes are never
//! targets because they leave with the target that made them; a weak target under them shows in
//! the residual. The whole profile is cleaned (leakage near 0 m included, so its side-lobes go
//! too); only targets inside the range window are reported as such ([`Detections::outside`] holds
//! the others).
//!
//! **CFAR** ([`Method::Cfar`]): local maxima of `|z|^2` over a sliding-window threshold (CA, GO,
//! SO or OS, [`CfarKind`]), computed twice, the second time with training cells near the first
//! pass's detections excluded, so one target does not mask another. A detection is dropped as a
//! side-lobe when it lies under a stronger one's side-lobe envelope (from `g`) plus
//! [`DetectOptions::sidelobe_margin_db`]. No subtraction: a weak target under a strong one's
//! side-lobes is lost (docs/detection.md measures how often). Detections are then fitted like CLEAN's.
//!
//! # Threshold and false-alarm probability
//! Noise in the profile is complex Gaussian: a noise cell's power is exponential with mean
//! `sigma^2`. **Pfa is the probability that noise alone crosses the threshold at one given cell**:
//! the noise part of the threshold is `alpha sigma^2` with `exp(-alpha) = Pfa` for a known
//! `sigma^2`, `alpha` raised for an estimated one. Neighbouring cells are correlated over
//! [`PsfShape::noise_cells`] cells (the oversampled axis), so a profile of `n` cells holds about
//! `n / noise_cells` independent cells, and the expected number of false targets per profile is of
//! the order of `Pfa n / noise_cells` (a few times more: a crossing can start anywhere between two
//! independent cells; docs/detection.md gives the measured rate).
//!
//! * CLEAN, [`NoiseEstimate::Global`]: `sigma^2 = median(|r|^2) / ln 2` over the residual `r`,
//!   cells within a main lobe of a fitted target left out; `alpha` is the CA-CFAR factor for the
//!   median's equivalent number of independent samples (0.48 per independent cell).
//! * [`NoiseEstimate::Local`] and [`Method::Cfar`]: the CFAR's own factor for its training cells,
//!   taken every `noise_cells` cells so they are independent (`threshold`).
//!
//! On top of the noise, each fitted target `i` adds a **model floor** `rho |a_i|^2 E(|c - x_i|)`:
//! `rho` = [`DetectOptions::model_floor_db`] (-30 dB), `E` the spread's own side-lobe envelope (1 in
//! the main lobe, [`PsfShape::envelope`]). It stands for what a real bench leaves after subtracting
//! a target with an imperfect `g` (front-end ripple, phase noise, I/Q imbalance): residue below it is
//! not reported. So a second target must be above `rho` times the first target's side-lobe envelope
//! at its distance: at -30 dB, 30 dB under the first within its main lobe, 43 dB under at a -13 dB
//! side-lobe. The threshold per cell, noise plus floors, is [`Detections::threshold`].
//!
//! **Chain floor.** A real bench's spread is not the model's: standing waves between the modules
//! and the horns put an echo a few ns behind every path (-18.8 dB for 2 dB p-p of ripple), and
//! tilt, dispersion and I/Q errors change the main lobe. Once the search has converged, each
//! target's inner main lobe (half the -3 dB width each side) is checked: it **certifies** the model
//! when the residual there is under -50 dB of the target's energy and the noise would have shown
//! a misfit that size. Around a target that does not certify it, anything within
//! [`DetectOptions::chain_extent_m`] (1.6 m) must exceed [`DetectOptions::chain_floor_db`]
//! (-17 dB) relative to it to be a target of its own (out to twice as far, -34 dB: the echo's
//! second round trip); weaker candidates there are pruned and stay
//! part of its measured response (its side-lobes and width include them). On the ideal mock lab
//! strong targets certify the model and keep the full reach above; a measured spread
//! (calibration) is what lowers the floor on a real bench.
//!
//! **Residual floor.** A correction that knows the chain still leaves a residue on every path:
//! what the calibration's fit did not explain, recorded on its reference per window as a residual
//! profile (`dsp::residual`). With [`DetectOptions::residual_floor`] set, each fitted target adds
//! `|a_i|^2 R(d)` times a 6 dB margin to the threshold at offset `d` behind or ahead of it, beyond
//! its main lobe (the first null): a residue under it is not a target, a real target over it is.
//! CFAR adds the same to its side-lobe mask around each kept peak.
//!
//! # Per-target metrics
//! Width and peak side-lobe level are measured on a target's **own response**: the profile minus
//! every other fitted target, over the region of the spread's highest side-lobes
//! ([`PsfShape::psl_span`]). [`Sidelobes`] says when that is not meaningful: another target's
//! subtraction error could reach within 10 dB of this target's side-lobes, the side-lobes are
//! within 10 dB of the noise, or the region runs off the profile.

// One file per detector (`clean`, `cfar`): a new detector is a `Method` variant, its own file
// with an `impl Detector` block, and one arm in `Detector::detect`.
mod cfar;
mod clean;
mod fit;
mod options;
mod output;
pub(crate) mod psf;
mod report;
#[cfg(test)]
mod residual_tests;

pub use super::metrics::threshold::CfarKind;
pub use options::{DetectOptions, Method, NoiseEstimate, ResidualFloor};
pub use output::{DetectedTarget, Detections, Sidelobes};
pub use psf::{PointSpread, PsfShape, SpectralLines, TabulatedPsf};

use std::ops::RangeInclusive;

use num_complex::Complex64;

use super::metrics::threshold::{global_noise, LocalCfar};
use super::metrics::{sidelobe_levels, width_3db, Axis, Interpolation};
use super::DspError;
use fit::{FitWindow, Model};

/// A detector for profiles with one point spread; holds its scratch (no allocation per call
/// beyond the returned report once warmed up).
pub struct Detector {
    psf: std::sync::Arc<dyn PointSpread>,
    shape: PsfShape,
    options: DetectOptions,
    local: Option<LocalCfar>,
    model: Model,
    residual: Vec<Complex64>,
    power: Vec<f64>,
    exclude: Vec<bool>,
    floor: Vec<f64>,
    noise_thr: Vec<f64>,
    threshold: Vec<f64>,
    scratch: Vec<f64>,
    rejected: Vec<f64>,
    own: Vec<f64>,
    g: Vec<Complex64>,
    /// Targets whose main lobe does not fit the model (position, power): each raises the chain
    /// floor around it. Empty during the CLEAN search; set once it has converged.
    mismatched: Vec<(f64, f64)>,
    /// The chain floor's reach, cells (set per profile from its axis).
    chain_extent: f64,
    /// The residual floor per whole cell of offset behind a target and ahead of it, relative to
    /// the target, margin included, 0 within its main lobe (set per profile from its axis;
    /// empty without [`DetectOptions::residual_floor`]).
    residual_behind: Vec<f64>,
    residual_ahead: Vec<f64>,
}

impl std::fmt::Debug for Detector {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Detector")
            .field("shape", &self.shape)
            .field("options", &self.options)
            .finish_non_exhaustive()
    }
}

/// A main lobe that fits the model to this, relative to its energy, counts as exact, dB.
const MISFIT_EXACT_DB: f64 = -50.0;
/// The noise expected over a main lobe must be this many times under a misfit of
/// [`MISFIT_EXACT_DB`] for the lobe to certify the model.
const MISFIT_NOISE_FACTOR: f64 = 4.0;

/// Longest envelope measured for the floors and masks, cells.
const MAX_ENVELOPE_CELLS: usize = 8192;
/// Sweeps of the joint refinement.
const MAX_SWEEPS: usize = 40;

impl Detector {
    /// A detector for profiles with spread `psf`.
    ///
    /// # Errors
    ///
    /// [`DspError::Param`] when an option is out of range (the message names it) or `psf` has a zero
    /// or non-finite response at the target.
    pub fn new(psf: impl PointSpread + 'static, options: DetectOptions) -> Result<Self, DspError> {
        options.validate()?;
        let shape = PsfShape::measure(&psf, MAX_ENVELOPE_CELLS)?;
        let stride = shape.noise_cells.round().max(1.0) as usize;
        let guard = shape.first_null.ceil() as usize;
        let local = match options.method {
            Method::Clean {
                noise: NoiseEstimate::Local(kind),
            }
            | Method::Cfar { kind } => Some(LocalCfar::new(
                kind,
                guard,
                options.cfar_training,
                stride,
                options.pfa,
            )?),
            _ => None,
        };
        Ok(Self {
            psf: std::sync::Arc::new(psf),
            shape,
            options,
            local,
            model: Model::default(),
            residual: Vec::new(),
            power: Vec::new(),
            exclude: Vec::new(),
            floor: Vec::new(),
            noise_thr: Vec::new(),
            threshold: Vec::new(),
            scratch: Vec::new(),
            rejected: Vec::new(),
            own: Vec::new(),
            g: Vec::new(),
            mismatched: Vec::new(),
            chain_extent: 0.0,
            residual_behind: Vec::new(),
            residual_ahead: Vec::new(),
        })
    }

    /// What the detector measured of its spread.
    pub fn shape(&self) -> &PsfShape {
        &self.shape
    }

    pub fn options(&self) -> &DetectOptions {
        &self.options
    }

    pub fn psf(&self) -> &dyn PointSpread {
        self.psf.as_ref()
    }

    /// The spread, shared: a report keeps it to rebuild the fitted echoes' model where it needs
    /// the profile as it was rather than CLEAN's split of it.
    pub(crate) fn shared_psf(&self) -> std::sync::Arc<dyn PointSpread> {
        self.psf.clone()
    }

    /// Detects the targets of the complex profile `z` on `axis`, reporting those whose range lies
    /// in `window_m` (metres on the same axis).
    ///
    /// # Errors
    ///
    /// [`DspError::Param`] when `z` has fewer than 3 cells, the axis is not finite with a positive
    /// step, or the window is not finite and ascending; [`DspError::Processing`] when a cell of `z`
    /// is NaN or infinite.
    pub fn detect(
        &mut self,
        z: &[Complex64],
        axis: Axis,
        window_m: RangeInclusive<f64>,
    ) -> Result<Detections, DspError> {
        let n = z.len();
        if n < 3 {
            return Err(DspError::Param(format!(
                "detection: the profile has {n} cells; at least 3 are needed"
            )));
        }
        if !(axis.step.is_finite() && axis.step > 0.0 && axis.start.is_finite()) {
            return Err(DspError::Param(format!(
                "detection: axis step {} m, start {} m; allowed: finite, step > 0",
                axis.step, axis.start
            )));
        }
        if let Some(i) = z
            .iter()
            .position(|v| !(v.re.is_finite() && v.im.is_finite()))
        {
            return Err(DspError::Processing(format!(
                "detection: profile cell {i} is not finite ({}); the capture or the processing \
                 produced NaN or infinity",
                z[i]
            )));
        }
        let (lo, hi) = (*window_m.start(), *window_m.end());
        if !(lo.is_finite() && hi.is_finite() && lo <= hi) {
            return Err(DspError::Param(format!(
                "detection: range window {lo}..={hi} m; allowed: finite, min <= max"
            )));
        }
        let fitw = FitWindow {
            half_width: (self.shape.first_null.ceil() as usize).max(1),
            bracket: (0.5 * self.shape.resolution).clamp(0.5, 1.0),
            lowest: -self.shape.first_null,
            highest: (n - 1) as f64 + self.shape.first_null,
        };
        let min_sep = self
            .options
            .min_separation_m
            .map(|m| m / axis.step)
            .unwrap_or(0.75 * self.shape.resolution);
        self.model.clear();
        self.rejected.clear();
        self.mismatched.clear();
        self.chain_extent = self.options.chain_extent_m / axis.step;
        self.residual_cells(axis.step);
        let capped = match self.options.method {
            Method::Clean { .. } => {
                let capped = self.clean(z, &fitw, min_sep);
                self.find_mismatch(z);
                self.prune(z, &fitw);
                capped
            }
            Method::Cfar { .. } => self.cfar(z, &fitw, min_sep),
        };
        Ok(self.report(z, axis, lo..=hi, capped))
    }

    /// The noise power per cell of the current residual (0 when it cannot be estimated).
    fn noise_power(&mut self) -> f64 {
        global_noise(
            &self.power,
            &self.exclude,
            self.shape.noise_cells,
            self.options.pfa,
            &mut self.scratch,
        )
        .map_or(0.0, |(s2, _)| s2)
    }

    /// Drops the weaker of any two targets closer than `min_sep`; true when one was dropped.
    fn merge_close(&mut self, min_sep: f64) -> bool {
        let comps = &mut self.model.comps;
        let mut dropped = false;
        'again: loop {
            for i in 0..comps.len() {
                for j in i + 1..comps.len() {
                    if (comps[i].x - comps[j].x).abs() < min_sep {
                        let weaker = if comps[i].a.norm() < comps[j].a.norm() {
                            i
                        } else {
                            j
                        };
                        comps.remove(weaker);
                        dropped = true;
                        continue 'again;
                    }
                }
            }
            return dropped;
        }
    }

    /// Power of the residual, cells near targets, noise threshold, floors and their sum for the
    /// current model.
    fn thresholds(&mut self, n: usize) {
        self.power.clear();
        self.power
            .extend(self.residual.iter().map(|v| v.norm_sqr()));
        self.exclude.clear();
        self.exclude.resize(n, false);
        for c in &self.model.comps {
            mark(&mut self.exclude, c.x, self.shape.first_null);
        }
        self.noise_thr.resize(n, 0.0);
        match self.local.as_mut() {
            Some(local) => local.thresholds(&self.power, &self.exclude, &mut self.noise_thr),
            None => {
                let level = global_noise(
                    &self.power,
                    &self.exclude,
                    self.shape.noise_cells,
                    self.options.pfa,
                    &mut self.scratch,
                )
                .map(|(s2, alpha)| alpha * s2)
                // Too few free cells for an estimate: only the floors count.
                .unwrap_or(0.0);
                self.noise_thr.fill(level);
            }
        }
        let rho = 10f64.powf(self.options.model_floor_db / 10.0);
        self.floor.clear();
        self.floor.resize(n, 0.0);
        for comp in &self.model.comps {
            let p = rho * comp.a.norm_sqr();
            for (c, f) in self.floor.iter_mut().enumerate() {
                *f += p * self.shape.envelope_at(c as f64 - comp.x);
            }
        }
        if !self.residual_behind.is_empty() {
            for comp in &self.model.comps {
                let p = comp.a.norm_sqr();
                let at = comp.x.round() as isize;
                let sides = [(&self.residual_behind, 1isize), (&self.residual_ahead, -1)];
                for (side, sign) in sides {
                    for (k, r) in side.iter().enumerate().skip(1) {
                        let c = at + sign * k as isize;
                        if (0..n as isize).contains(&c) {
                            self.floor[c as usize] += p * r;
                        }
                    }
                }
            }
        }
        self.threshold.clear();
        self.threshold
            .extend(self.noise_thr.iter().zip(&self.floor).map(|(a, b)| a + b));
        if !self.mismatched.is_empty() {
            for c in 0..n {
                self.threshold[c] += self.chain_floor(c as f64, None);
            }
        }
    }

    /// The residual floor per cell of offset for a profile of cells `step` m apart: the
    /// calibration's residual profile plus the margin, taken at each cell's offset, 0 within the
    /// spread's first null (the target's own main lobe, which its fit accounts for).
    fn residual_cells(&mut self, step: f64) {
        self.residual_behind.clear();
        self.residual_ahead.clear();
        let Some(floor) = &self.options.residual_floor else {
            return;
        };
        let margin = 10f64.powf(options::RESIDUAL_MARGIN_DB / 10.0);
        let cells = (floor.reach_m() / step).ceil() as usize + 1;
        let inner = self.shape.first_null.ceil() as usize;
        for k in 0..cells {
            let (behind, ahead) = if k < inner {
                (0.0, 0.0)
            } else {
                let d = k as f64 * step;
                (margin * floor.at(d), margin * floor.at(-d))
            };
            self.residual_behind.push(behind);
            self.residual_ahead.push(ahead);
        }
    }

    /// The residual floor at cell `c` relative to a target at cell `at` (margin included; 0
    /// within its main lobe, beyond the profile's reach or without a residual profile).
    fn residual_at(&self, c: usize, at: usize) -> f64 {
        let side = if c >= at {
            &self.residual_behind
        } else {
            &self.residual_ahead
        };
        side.get(c.abs_diff(at)).copied().unwrap_or(0.0)
    }

    /// The highest chain floor at cell `x`, leaving out a target at `skip` (and any within a
    /// cell of it: the target itself after a refit). Within the chain's extent the floor is
    /// `chain_floor_db` under the target; out to twice the extent (the echo's own echo, a second
    /// round trip of the standing wave) twice that many dB under it.
    fn chain_floor(&self, x: f64, skip: Option<f64>) -> f64 {
        let rho = 10f64.powf(self.options.chain_floor_db / 10.0);
        self.mismatched
            .iter()
            .filter(|(at, _)| skip.is_none_or(|s| (at - s).abs() > 1.0))
            .map(|(at, p)| {
                let d = (x - at).abs();
                if d <= self.chain_extent {
                    rho * p
                } else if d <= 2.0 * self.chain_extent {
                    rho * rho * p
                } else {
                    0.0
                }
            })
            .fold(0.0, f64::max)
    }

    /// CLEAN's threshold at `cell` without target `i`'s own floors: what it has to pass.
    fn others_threshold(&self, i: usize, cell: usize, rho: f64) -> f64 {
        let c = self.model.comps[i];
        let chain = if self.mismatched.is_empty() {
            0.0
        } else {
            self.chain_floor(cell as f64, None) - self.chain_floor(cell as f64, Some(c.x))
        };
        self.threshold[cell] - rho * c.a.norm_sqr() - chain
    }
}

/// Marks the cells within `radius` of `x`.
fn mark(exclude: &mut [bool], x: f64, radius: f64) {
    let n = exclude.len() as isize;
    let lo = ((x - radius).floor() as isize).clamp(0, n);
    let hi = ((x + radius).ceil() as isize + 1).clamp(0, n);
    for e in &mut exclude[lo as usize..hi as usize] {
        *e = true;
    }
}

/// A local maximum of `power` (an end cell counts when above its one neighbour).
fn is_peak(power: &[f64], c: usize) -> bool {
    let left = c == 0 || power[c] >= power[c - 1];
    let right = c + 1 == power.len() || power[c] > power[c + 1];
    left && right
}

/// Sub-cell position of the maximum at `c` from a parabola through the three dB values.
fn parabolic(power: &[f64], c: usize) -> f64 {
    if c == 0 || c + 1 >= power.len() {
        return c as f64;
    }
    let db = |p: f64| 10.0 * p.max(1e-300).log10();
    let (a, b, d) = (db(power[c - 1]), db(power[c]), db(power[c + 1]));
    let denom = a - 2.0 * b + d;
    if denom >= 0.0 {
        return c as f64;
    }
    c as f64 + (0.5 * (a - d) / denom).clamp(-0.5, 0.5)
}
