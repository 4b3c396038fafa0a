//! Range-profile metrics (thesis 2.1): peaks with prominence, CA-CFAR, sub-sample interpolation,
//! interpolated -3 dB width, peak and integrated side-lobe levels, and the "resolved" rule.
//!
//! Every function takes plain slices: a profile is `values[i]` at the uniform axis
//! `x0 + i * dx` (metres for range profiles). Amplitude profiles are linear magnitudes (not power);
//! functions that work in dB say so. Profiles are treated as finite, not circular: a lobe that
//! runs into either end of the slice stops there.

mod axis;
mod cfar;
mod db;
mod lobes;
mod peaks;
mod resolve;
pub(crate) mod threshold;

pub use axis::Axis;
pub use cfar::{CaCfar, CfarDetection};
pub(crate) use db::amplitude_db;
pub use lobes::{sidelobe_levels, width_3db, SidelobeLevels};
pub(crate) use peaks::local_maxima;
pub use peaks::{find_peaks, interpolate_peak, Interpolation, Peak};
pub use resolve::{resolve_targets, Resolution};
