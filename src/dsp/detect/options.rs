//! What a detector is asked for: the method, its noise estimate and the limits.

use crate::dsp::metrics::threshold::CfarKind;
use crate::dsp::DspError;

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
    /// CLEAN: what a calibration's correction leaves around every path, for the window in use
    /// (its residual profile); beyond a target's main lobe, anything under it plus
    /// `RESIDUAL_MARGIN_DB` (6 dB) relative to the target is not a target of its own. `None` (no
    /// calibration, or one written before it recorded the profile): no such floor.
    pub residual_floor: Option<ResidualFloor>,
}

/// The residual floor stands this far above the calibration's residual profile, dB: the profile
/// is one measurement (the reference's noise is in it, 73-95 dB under the pillar) of a residue
/// that moves with the target's sub-cell position and the capture's noise; the residues seen in
/// captures lay within 2 dB of it (docs/detection.md).
pub(crate) const RESIDUAL_MARGIN_DB: f64 = 6.0;

/// A calibration's residual profile for one window (`dsp::residual`): the largest power the
/// correction leaves relative to the target's, in bins of range offset behind it and ahead of it.
#[derive(Debug, Clone, PartialEq)]
pub struct ResidualFloor {
    bin_m: f64,
    behind: Vec<f64>,
    ahead: Vec<f64>,
}

impl ResidualFloor {
    /// From levels in dB relative to the target, bins of `bin_m` (bin `j`: `[j bin_m, (j + 1)
    /// bin_m)` of offset); `None` when the bins are not positive or a level is not finite.
    pub(crate) fn from_db(bin_m: f64, behind_db: &[f64], ahead_db: &[f64]) -> Option<Self> {
        let lin = |v: &[f64]| -> Option<Vec<f64>> {
            v.iter()
                .map(|d| d.is_finite().then(|| 10f64.powf(d.min(0.0) / 10.0)))
                .collect()
        };
        (bin_m.is_finite() && bin_m > 0.0).then_some(())?;
        Some(Self {
            bin_m,
            behind: lin(behind_db)?,
            ahead: lin(ahead_db)?,
        })
    }

    /// How far it reaches either side, m.
    pub(crate) fn reach_m(&self) -> f64 {
        self.bin_m * self.behind.len().max(self.ahead.len()) as f64
    }

    /// The profile's own bin `offset_m` behind the target (negative: ahead), relative to it; 0
    /// beyond the profile.
    pub(crate) fn bin_at(&self, offset_m: f64) -> f64 {
        self.side(offset_m)
            .get((offset_m.abs() / self.bin_m) as usize)
            .copied()
            .unwrap_or(0.0)
    }

    /// The bins on `offset_m`'s side of the target: behind it (positive) or ahead.
    fn side(&self, offset_m: f64) -> &[f64] {
        if offset_m >= 0.0 {
            &self.behind
        } else {
            &self.ahead
        }
    }

    /// The floor, relative to the target, `offset_m` behind it (negative: ahead): the largest of
    /// the bin it falls in and its two neighbours (a target's position within a bin is not the
    /// reference's); 0 beyond the profile.
    pub(crate) fn at(&self, offset_m: f64) -> f64 {
        let side = self.side(offset_m);
        let j = (offset_m.abs() / self.bin_m) as usize;
        (j.saturating_sub(1)..=j + 1)
            .filter_map(|b| side.get(b))
            .copied()
            .fold(0.0, f64::max)
    }
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
            residual_floor: None,
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
