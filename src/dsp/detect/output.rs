//! What a detection returns (built in `report.rs`).

use num_complex::Complex64;
use serde::Serialize;

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
    BelowNoise {
        /// The noise relative to the target, dB: the side-lobes are under this plus 10 dB.
        noise_db: f64,
    },
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
            Sidelobes::BelowNoise { noise_db } => format!(
                "side-lobes within 10 dB of the noise (the noise is {noise_db:.1} dB under the \
                 target: the side-lobe level is under {:.1} dB)",
                -noise_db + 10.0
            ),
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

/// Everything [`Detector::detect`](super::Detector::detect) found.
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
    /// The search stopped at [`DetectOptions::max_targets`](super::DetectOptions::max_targets): there may be more.
    pub capped: bool,
}
