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
//! # Per-target metrics
//! Width and peak side-lobe level are measured on a target's **own response**: the profile minus
//! every other fitted target, over the region of the spread's highest side-lobes
//! ([`PsfShape::psl_span`]). [`Sidelobes`] says when that is not meaningful: another target's
//! subtraction error could reach within 10 dB of this target's side-lobes, the side-lobes are
//! within 10 dB of the noise, or the region runs off the profile.

mod fit;
pub(crate) mod psf;

pub use super::metrics::threshold::CfarKind;
pub use psf::{PointSpread, PsfShape, SpectralLines, TabulatedPsf};

use std::ops::RangeInclusive;

use num_complex::Complex64;
use serde::Serialize;

use super::metrics::threshold::{global_noise, LocalCfar};
use super::metrics::{sidelobe_levels, width_3db, Axis, Interpolation};
use super::DspError;
use fit::{FitWindow, Model};

/// How the noise part of CLEAN's threshold is estimated.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum NoiseEstimate {
    /// One level for the whole profile, from the median of the residual (default): right for the
    /// stationary noise of a capture.
    Global,
    /// A sliding-window CFAR on the residual, for noise that varies along the profile.
    Local(CfarKind),
}

/// The detection algorithm.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Method {
    /// Subtract each target's fitted response and search again (default).
    Clean { noise: NoiseEstimate },
    /// Peaks over a CFAR threshold, side-lobes masked by the spread's envelope.
    Cfar { kind: CfarKind },
}

impl Method {
    /// A short name for reports: `clean`, `clean+os(0.75)`, `cfar-os(0.75)`, ...
    pub fn name(&self) -> String {
        match self {
            Method::Clean {
                noise: NoiseEstimate::Global,
            } => "clean".into(),
            Method::Clean {
                noise: NoiseEstimate::Local(k),
            } => format!("clean+{}", k.name()),
            Method::Cfar { kind } => format!("cfar-{}", kind.name()),
        }
    }
}

/// Detector settings; [`Default`] is what a capture uses.
#[derive(Debug, Clone, PartialEq)]
pub struct DetectOptions {
    pub method: Method,
    /// False-alarm probability per cell (see the module docs), default 1e-6.
    pub pfa: f64,
    /// Targets closer than this are not separated (the weaker is dropped), metres. `None`: 0.75
    /// resolution cells of the spread.
    pub min_separation_m: Option<f64>,
    /// Most targets fitted (leakage and targets outside the window count), default 32.
    pub max_targets: usize,
    /// Residue tolerated under each fitted target, relative to its own side-lobe envelope, dB
    /// (default -30; lower for a better-known spread, e.g. -60 in simulations).
    pub model_floor_db: f64,
    /// Independent training samples per side of a CFAR window (default 8).
    pub cfar_training: usize,
    /// [`Method::Cfar`]: a peak within this of a stronger target's side-lobe envelope is a
    /// side-lobe, dB (default 3).
    pub sidelobe_margin_db: f64,
    /// CLEAN: where a target's main lobe shows that the bench's spread is not the model's, what
    /// lies within [`DetectOptions::chain_extent_m`] of it must be stronger than this, relative
    /// to it, to count as a target of its own, dB (default -17: the chain's own echoes, up to
    /// -18.8 dB for a 2 dB p-p standing wave, are part of its response). See the module docs.
    pub chain_floor_db: f64,
    /// How far from a target the chain's echoes reach, m (default 1.6: a standing wave over up
    /// to 10 ns of line, and the main lobe); out to twice as far its second round trip is taken
    /// at twice the floor in dB.
    pub chain_extent_m: f64,
}

impl Default for DetectOptions {
    fn default() -> Self {
        Self {
            method: Method::Clean {
                noise: NoiseEstimate::Global,
            },
            pfa: 1e-6,
            min_separation_m: None,
            max_targets: 32,
            model_floor_db: -30.0,
            cfar_training: 8,
            sidelobe_margin_db: 3.0,
            chain_floor_db: -17.0,
            chain_extent_m: 1.6,
        }
    }
}

impl DetectOptions {
    /// Checks every field; the message names it and what is allowed.
    pub(crate) fn validate(&self) -> Result<(), DspError> {
        let bad = |m: String| Err(DspError::Param(m));
        if !(self.pfa > 0.0 && self.pfa < 0.5) {
            return bad(format!(
                "detection: pfa = {}; allowed: a false-alarm probability per cell in (0, 0.5), \
                 e.g. 1e-6",
                self.pfa
            ));
        }
        if let Some(s) = self.min_separation_m {
            if !(s.is_finite() && s >= 0.0) {
                return bad(format!(
                    "detection: min_separation_m = {s}; allowed: a distance >= 0 in metres"
                ));
            }
        }
        if self.max_targets == 0 || self.max_targets > 4096 {
            return bad(format!(
                "detection: max_targets = {}; allowed: 1 to 4096",
                self.max_targets
            ));
        }
        if !(self.model_floor_db.is_finite() && self.model_floor_db < 0.0) {
            return bad(format!(
                "detection: model_floor_db = {}; allowed: a level below 0 dB (e.g. -30)",
                self.model_floor_db
            ));
        }
        if !(self.chain_floor_db.is_finite() && self.chain_floor_db <= 0.0) {
            return bad(format!(
                "detection: chain_floor_db = {}; allowed: a level <= 0 dB (e.g. -17; -200 turns \
                 the chain floor off)",
                self.chain_floor_db
            ));
        }
        if !(self.chain_extent_m.is_finite() && self.chain_extent_m >= 0.0) {
            return bad(format!(
                "detection: chain_extent_m = {}; allowed: a distance >= 0 in metres",
                self.chain_extent_m
            ));
        }
        if self.cfar_training == 0 || self.cfar_training > 256 {
            return bad(format!(
                "detection: cfar_training = {}; allowed: 1 to 256 samples per side",
                self.cfar_training
            ));
        }
        if !(self.sidelobe_margin_db.is_finite() && self.sidelobe_margin_db >= 0.0) {
            return bad(format!(
                "detection: sidelobe_margin_db = {}; allowed: a margin >= 0 dB",
                self.sidelobe_margin_db
            ));
        }
        Ok(())
    }
}

/// The side-lobe measurement of one target, or why there is none.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
#[serde(tag = "status", rename_all = "snake_case")]
pub enum Sidelobes {
    /// Peak and integrated side-lobe levels of the target's own response, dB.
    Measured { psl_db: f64, isl_db: f64 },
    /// Another target's subtraction error could reach within 10 dB of this one's side-lobes.
    Shared {
        /// The other target's range, m, and how much stronger it is, dB.
        with_range_m: f64,
        stronger_db: f64,
    },
    /// The expected side-lobes lie within 10 dB of the noise.
    BelowNoise,
    /// The side-lobe region runs off the profile.
    AtEdge,
    /// No side-lobe outside the main lobe could be found.
    Undefined,
}

impl Sidelobes {
    /// The PSL when it was measured.
    pub fn psl_db(&self) -> Option<f64> {
        match self {
            Sidelobes::Measured { psl_db, .. } => Some(*psl_db),
            _ => None,
        }
    }

    /// Why there is no PSL, in words (empty when measured).
    pub fn reason(&self) -> String {
        match self {
            Sidelobes::Measured { .. } => String::new(),
            Sidelobes::Shared {
                with_range_m,
                stronger_db,
            } => format!(
                "side-lobe region shared with the target at {with_range_m:.3} m \
                 ({stronger_db:+.1} dB)"
            ),
            Sidelobes::BelowNoise => "side-lobes within 10 dB of the noise".into(),
            Sidelobes::AtEdge => "side-lobe region runs off the profile".into(),
            Sidelobes::Undefined => "no side-lobe found".into(),
        }
    }
}

/// One detected target.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct DetectedTarget {
    /// Range on the profile's axis, m.
    pub range_m: f64,
    /// Fractional cell of the profile.
    pub cell: f64,
    /// Fitted complex amplitude, profile units (a target of amplitude `a` peaks at `|a|`).
    #[serde(skip)]
    pub amplitude: Complex64,
    /// 20 log10 |amplitude|, dB.
    pub level_db: f64,
    /// Phase of the amplitude, degrees.
    pub phase_deg: f64,
    /// |amplitude|^2 over the noise power per cell, dB (`None` when the noise could not be
    /// estimated: too few cells free of targets).
    pub snr_db: Option<f64>,
    /// |amplitude|^2 over the threshold at the target (noise plus the other targets' floors), dB.
    pub above_threshold_db: f64,
    /// -3 dB width of the own response, m.
    pub width_3db_m: Option<f64>,
    pub sidelobes: Sidelobes,
}

/// Everything [`Detector::detect`] found.
#[derive(Debug, Clone, Default)]
pub struct Detections {
    /// Targets inside the range window, ascending range.
    pub targets: Vec<DetectedTarget>,
    /// Targets fitted outside the window (leakage near 0 m, ...), removed from the profile with
    /// their side-lobes, not reported as targets; ascending range.
    pub outside: Vec<DetectedTarget>,
    /// The final threshold per cell as an amplitude (same scale as `|z|`). CLEAN: what a further
    /// target would need at that cell (noise plus every fitted target's floor); CFAR: the CFAR's
    /// threshold raised to the side-lobe mask of the detected peaks.
    pub threshold: Vec<f64>,
    /// Noise power per cell (global estimate on the final residual), `None` when too few cells
    /// were free of targets.
    pub noise_power: Option<f64>,
    /// The profile minus every fitted target.
    pub residual: Vec<Complex64>,
    /// The search stopped at [`DetectOptions::max_targets`]: there may be more.
    pub capped: bool,
}

/// A detector for profiles with one point spread; holds its scratch (no allocation per call
/// beyond the returned report once warmed up).
pub struct Detector {
    psf: Box<dyn PointSpread>,
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
            psf: Box::new(psf),
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

    /// Detects the targets of the complex profile `z` on `axis`, reporting those whose range lies
    /// in `window_m` (metres on the same axis).
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

    /// The CLEAN loop; returns whether it stopped at the target limit.
    fn clean(&mut self, z: &[Complex64], fitw: &FitWindow, min_sep: f64) -> bool {
        let n = z.len();
        let max_iterations = 2 * self.options.max_targets + 8;
        for _ in 0..max_iterations {
            self.model.rebuild(self.psf.as_ref(), n);
            self.model.residual(z, &mut self.residual);
            self.thresholds(n);
            let best = self.best_candidate(min_sep);
            let Some(c) = best else {
                return false;
            };
            if self.model.comps.len() >= self.options.max_targets {
                return true;
            }
            let x_init = parabolic(&self.power, c);
            let psf = self.psf.as_ref();
            let newest = self.model.add(psf, z, x_init, fitw);
            self.model.refine(psf, z, fitw, MAX_SWEEPS);
            if self.merge_close(min_sep) {
                self.rejected.push(x_init);
                self.model.refine(self.psf.as_ref(), z, fitw, MAX_SWEEPS);
            } else if self.is_chain_echo(z, newest) {
                self.model.comps.remove(newest);
                self.rejected.push(x_init);
                self.model.refine(self.psf.as_ref(), z, fitw, MAX_SWEEPS);
            }
        }
        false
    }

    /// Whether the newest component lies under the chain floor of a stronger one whose main lobe,
    /// with the newest fitted, does not certify the model: that one then joins `mismatched` (its
    /// floor keeps its further echoes from being searched at all).
    fn is_chain_echo(&mut self, z: &[Complex64], newest: usize) -> bool {
        let rho = 10f64.powf(self.options.chain_floor_db / 10.0);
        let new = self.model.comps[newest];
        let suspects: Vec<usize> = (0..self.model.comps.len())
            .filter(|&i| {
                let c = self.model.comps[i];
                i != newest
                    && (c.x - new.x).abs() <= 2.0 * self.chain_extent
                    && new.a.norm_sqr() < rho * c.a.norm_sqr()
                    && !self.mismatched.iter().any(|(x, _)| (x - c.x).abs() < 1.0)
            })
            .collect();
        if suspects.is_empty() {
            return false;
        }
        let n = z.len();
        self.model.rebuild(self.psf.as_ref(), n);
        self.model.residual(z, &mut self.residual);
        self.thresholds(n);
        let noise = self.noise_power();
        let mut echo = false;
        for i in suspects {
            let c = self.model.comps[i];
            if !self.certifies(c, noise) {
                self.mismatched.push((c.x, c.a.norm_sqr()));
                echo = true;
            }
        }
        echo && self.chain_floor(new.x, Some(new.x)) > new.a.norm_sqr()
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

    /// Whether target `c`'s inner main lobe (within half the -3 dB width) certifies the model
    /// against the current residual: the residual there is under [`MISFIT_EXACT_DB`] of the
    /// target's energy, and the noise (per cell `noise`) would have let a misfit that size show.
    fn certifies(&mut self, c: fit::Component, noise: f64) -> bool {
        let n = self.residual.len();
        let w = 0.5 * self.shape.width_3db;
        let lo = (c.x - w).ceil().max(0.0) as usize;
        let hi = ((c.x + w).floor().max(0.0) as usize).min(n - 1);
        if hi < lo {
            return true;
        }
        self.g.resize(hi + 1 - lo, Complex64::default());
        self.psf.response(c.x, lo as isize, &mut self.g);
        let left: f64 = self.residual[lo..=hi].iter().map(|v| v.norm_sqr()).sum();
        let own: f64 = self.g.iter().map(|v| (c.a * v).norm_sqr()).sum();
        let cells = (hi + 1 - lo) as f64;
        let exact = 10f64.powf(MISFIT_EXACT_DB / 10.0);
        left <= exact * own && MISFIT_NOISE_FACTOR * noise * cells <= exact * own
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

    /// Peaks over a CFAR threshold, twice (training cells near the first pass's peaks excluded
    /// the second time), side-lobes masked by the envelope; then fitted jointly. Returns whether
    /// the target limit cut the list.
    fn cfar(&mut self, z: &[Complex64], fitw: &FitWindow, min_sep: f64) -> bool {
        let n = z.len();
        self.residual.clear();
        self.residual.extend_from_slice(z);
        self.power.clear();
        self.power.extend(z.iter().map(|v| v.norm_sqr()));
        self.exclude.clear();
        self.exclude.resize(n, false);
        self.noise_thr.resize(n, 0.0);
        let guard = self.shape.first_null;
        let local = self.local.as_mut().expect("a CFAR method has its CFAR");
        let mut peaks: Vec<usize> = Vec::new();
        for pass in 0..2 {
            if pass == 1 {
                for &p in &peaks {
                    mark(&mut self.exclude, p as f64, guard);
                }
            }
            local.thresholds(&self.power, &self.exclude, &mut self.noise_thr);
            peaks.clear();
            peaks.extend(
                (0..n).filter(|&c| is_peak(&self.power, c) && self.power[c] > self.noise_thr[c]),
            );
        }
        peaks.sort_by(|&a, &b| self.power[b].total_cmp(&self.power[a]));
        let margin = 10f64.powf(self.options.sidelobe_margin_db / 10.0);
        let mut kept: Vec<usize> = Vec::new();
        for &c in &peaks {
            let masked = kept.iter().any(|&k| {
                let d = (c as f64 - k as f64).abs();
                d < min_sep || self.power[c] < self.power[k] * self.shape.envelope_at(d) * margin
            });
            if !masked {
                kept.push(c);
            }
        }
        let capped = kept.len() > self.options.max_targets;
        kept.truncate(self.options.max_targets);
        let psf = self.psf.as_ref();
        for &c in &kept {
            let x_init = parabolic(&self.power, c);
            self.model.add(psf, z, x_init, fitw);
        }
        self.model.refine(psf, z, fitw, MAX_SWEEPS);
        self.merge_close(min_sep);
        // The reported threshold: the CFAR's, raised to the side-lobe mask of the kept peaks.
        self.threshold.clear();
        self.threshold.extend_from_slice(&self.noise_thr);
        for &k in &kept {
            for (c, t) in self.threshold.iter_mut().enumerate() {
                let d = (c as f64 - k as f64).abs();
                if d >= 1.0 {
                    *t = t.max(self.power[k] * self.shape.envelope_at(d) * margin);
                }
            }
        }
        // Residual, its power and the cells near targets, for the noise estimate of the report.
        self.model.rebuild(self.psf.as_ref(), n);
        self.model.residual(z, &mut self.residual);
        self.power.clear();
        self.power
            .extend(self.residual.iter().map(|v| v.norm_sqr()));
        self.exclude.fill(false);
        for c in &self.model.comps {
            mark(&mut self.exclude, c.x, self.shape.first_null);
        }
        capped
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
        self.threshold.clear();
        self.threshold
            .extend(self.noise_thr.iter().zip(&self.floor).map(|(a, b)| a + b));
        if !self.mismatched.is_empty() {
            for c in 0..n {
                self.threshold[c] += self.chain_floor(c as f64, None);
            }
        }
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

    /// After the CLEAN search, with every candidate fitted: adds the targets whose main lobe does
    /// not certify the model ([`Detector::certifies`]) to those the search found; around them the
    /// chain's echoes cannot be told from targets, and the chain floor stands.
    fn find_mismatch(&mut self, z: &[Complex64]) {
        let n = z.len();
        self.model.rebuild(self.psf.as_ref(), n);
        self.model.residual(z, &mut self.residual);
        self.thresholds(n);
        let noise = self.noise_power();
        for i in 0..self.model.comps.len() {
            let c = self.model.comps[i];
            let known = self.mismatched.iter().any(|(x, _)| (x - c.x).abs() < 1.0);
            if !known && !self.certifies(c, noise) {
                self.mismatched.push((c.x, c.a.norm_sqr()));
            }
        }
    }

    /// The strongest residual peak over its threshold, away from fitted and rejected targets.
    fn best_candidate(&self, min_sep: f64) -> Option<usize> {
        let near = |c: usize, x: f64| (c as f64 - x).abs() < min_sep;
        (0..self.power.len())
            .filter(|&c| self.power[c] > self.threshold[c] && is_peak(&self.power, c))
            .filter(|&c| {
                !self.model.comps.iter().any(|k| near(c, k.x))
                    && !self.rejected.iter().any(|&x| near(c, x))
            })
            .max_by(|&a, &b| self.power[a].total_cmp(&self.power[b]))
    }

    /// Drops fitted targets that no longer pass their threshold (noise plus the others' floors)
    /// once everything is fitted, weakest first, re-fitting after each drop.
    fn prune(&mut self, z: &[Complex64], fitw: &FitWindow) {
        let n = z.len();
        loop {
            self.model.rebuild(self.psf.as_ref(), n);
            self.model.residual(z, &mut self.residual);
            self.thresholds(n);
            let rho = 10f64.powf(self.options.model_floor_db / 10.0);
            let weakest_failing = (0..self.model.comps.len())
                .filter(|&i| {
                    let c = self.model.comps[i];
                    let cell = (c.x.round().max(0.0) as usize).min(n - 1);
                    c.a.norm_sqr() <= self.others_threshold(i, cell, rho)
                })
                .min_by(|&a, &b| {
                    self.model.comps[a]
                        .a
                        .norm()
                        .total_cmp(&self.model.comps[b].a.norm())
                });
            match weakest_failing {
                Some(i) => {
                    self.model.comps.remove(i);
                    self.model.refine(self.psf.as_ref(), z, fitw, MAX_SWEEPS);
                }
                None => return,
            }
        }
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

    /// The report for the final model (residual and thresholds are current).
    fn report(
        &mut self,
        z: &[Complex64],
        axis: Axis,
        window: RangeInclusive<f64>,
        capped: bool,
    ) -> Detections {
        let n = z.len();
        let noise_power = global_noise(
            &self.power,
            &self.exclude,
            self.shape.noise_cells,
            self.options.pfa,
            &mut self.scratch,
        )
        .map(|(s2, _)| s2);
        let rho = 10f64.powf(self.options.model_floor_db / 10.0);
        let mut targets = Vec::new();
        let mut outside = Vec::new();
        for i in 0..self.model.comps.len() {
            let c = self.model.comps[i];
            let cell = (c.x.round().max(0.0) as usize).min(n - 1);
            let p = c.a.norm_sqr();
            // What the target had to pass: CLEAN's threshold less its own floors; the CFAR's.
            let others = match self.options.method {
                Method::Clean { .. } => self.others_threshold(i, cell, rho),
                Method::Cfar { .. } => self.noise_thr[cell],
            }
            .max(1e-300);
            let (width_3db_m, sidelobes) = self.own_metrics(i, noise_power, axis);
            let t = DetectedTarget {
                range_m: axis.at(c.x),
                cell: c.x,
                amplitude: c.a,
                level_db: 10.0 * p.max(1e-300).log10(),
                phase_deg: c.a.arg().to_degrees(),
                snr_db: noise_power
                    .filter(|&s| s > 0.0)
                    .map(|s| 10.0 * (p / s).log10()),
                above_threshold_db: 10.0 * (p / others).log10(),
                width_3db_m,
                sidelobes,
            };
            if window.contains(&t.range_m) {
                targets.push(t);
            } else {
                outside.push(t);
            }
        }
        targets.sort_by(|a, b| a.range_m.total_cmp(&b.range_m));
        outside.sort_by(|a, b| a.range_m.total_cmp(&b.range_m));
        Detections {
            targets,
            outside,
            threshold: self.threshold.iter().map(|t| t.max(0.0).sqrt()).collect(),
            noise_power,
            residual: self.residual.clone(),
            capped,
        }
    }

    /// -3 dB width (m) and side-lobes of target `i`'s own response.
    fn own_metrics(
        &mut self,
        i: usize,
        noise: Option<f64>,
        axis: Axis,
    ) -> (Option<f64>, Sidelobes) {
        let n = self.residual.len();
        let c = self.model.comps[i];
        let span = self.shape.psl_span;
        let lo = (c.x - span).floor();
        let hi = (c.x + span).ceil();
        let at_edge = lo < 0.0 || hi > (n - 1) as f64;
        let lo = lo.max(0.0) as usize;
        let hi = (hi.min((n - 1) as f64)) as usize;
        if hi < lo + 2 {
            return (None, Sidelobes::AtEdge);
        }
        self.g.resize(hi + 1 - lo, Complex64::default());
        self.psf.response(c.x, lo as isize, &mut self.g);
        self.own.clear();
        self.own.extend(
            self.residual[lo..=hi]
                .iter()
                .zip(&self.g)
                .map(|(r, g)| (r + c.a * g).norm()),
        );
        let mut peak = ((c.x.round() as isize - lo as isize).clamp(0, (hi - lo) as isize)) as usize;
        // Climb to the local maximum (the fitted position is within a fraction of a cell of it).
        loop {
            let up = (peak + 1 < self.own.len() && self.own[peak + 1] > self.own[peak])
                .then(|| peak + 1);
            let down = (peak > 0 && self.own[peak - 1] > self.own[peak]).then(|| peak - 1);
            match up.or(down) {
                Some(p) => peak = p,
                None => break,
            }
        }
        let (_, height) =
            super::metrics::interpolate_peak(&self.own, peak, Interpolation::ParabolicDb);
        let width = width_3db(&self.own, peak, height).map(|w| w * axis.step);
        let p = c.a.norm_sqr();
        let psl_lin = 10f64.powf(self.shape.psl_db / 10.0);
        if at_edge {
            return (width, Sidelobes::AtEdge);
        }
        if let Some(s) = noise {
            if p * psl_lin < 10.0 * s {
                return (width, Sidelobes::BelowNoise);
            }
        }
        let rho = 10f64.powf(self.options.model_floor_db / 10.0);
        let shared = self
            .model
            .comps
            .iter()
            .enumerate()
            .filter(|&(j, _)| j != i)
            .map(|(_, o)| {
                let d = ((o.x - c.x).abs() - span).max(0.0);
                (rho * o.a.norm_sqr() * self.shape.envelope_at(d), o)
            })
            .filter(|(u, _)| *u > p * psl_lin / 10.0)
            .max_by(|a, b| a.0.total_cmp(&b.0));
        if let Some((_, o)) = shared {
            return (
                width,
                Sidelobes::Shared {
                    with_range_m: axis.at(o.x),
                    stronger_db: 10.0 * (o.a.norm_sqr() / p).log10(),
                },
            );
        }
        let s = sidelobe_levels(&self.own, peak, Interpolation::ParabolicDb);
        (
            width,
            s.map_or(Sidelobes::Undefined, |s| Sidelobes::Measured {
                psl_db: s.psl_db,
                isl_db: s.isl_db,
            }),
        )
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
