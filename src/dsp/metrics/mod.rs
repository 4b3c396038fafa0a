//! Range-profile metrics (thesis 2.1): peaks with prominence, CA-CFAR, sub-sample interpolation,
//! interpolated -3 dB width, peak and integrated side-lobe levels, and the "resolved" rule.
//!
//! Every function takes plain slices: a profile is `values[i]` at the uniform axis
//! `x0 + i * dx` (metres for range profiles). Amplitude profiles are linear magnitudes (not power);
//! functions that work in dB say so. Profiles are treated as finite, not circular: a lobe that
//! runs into either end of the slice stops there.

mod cfar;
mod lobes;
mod peaks;
mod resolve;
pub(crate) mod threshold;

pub use cfar::{CaCfar, CfarDetection};
pub use lobes::{sidelobe_levels, width_3db, SidelobeLevels};
pub(crate) use peaks::local_maxima;
pub use peaks::{find_peaks, interpolate_peak, Interpolation, Peak};
pub use resolve::{resolve_targets, Resolution};

/// 20 log10 of an amplitude, floored at -400 dB so a zero stays finite.
pub(crate) fn amplitude_db(amplitude: f64) -> f64 {
    20.0 * amplitude.max(1e-20).log10()
}

/// Fills `out` with [`amplitude_db`] of `amplitude`.
pub(crate) fn to_db(amplitude: &[f64], out: &mut [f64]) {
    for (o, &a) in out.iter_mut().zip(amplitude) {
        *o = amplitude_db(a);
    }
}

/// A uniform axis: `x(i) = start + i * step`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Axis {
    pub start: f64,
    pub step: f64,
}

impl Axis {
    /// The axis position of a (fractional) sample index.
    pub fn at(&self, index: f64) -> f64 {
        self.start + index * self.step
    }

    /// Infers the axis from a sampled, uniform axis vector (at least two points, else step 1).
    pub fn from_samples(x: &[f64]) -> Self {
        match x {
            [] => Axis {
                start: 0.0,
                step: 1.0,
            },
            [a] => Axis {
                start: *a,
                step: 1.0,
            },
            [a, .., b] => Axis {
                start: *a,
                step: (b - a) / (x.len() - 1) as f64,
            },
        }
    }
}
