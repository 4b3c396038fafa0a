//! What range processing gives for one record: a file of its own so that the detector, which
//! reads it, does not depend on the pipeline that makes it.

use crate::dsp::range_profile::Profile;
use num_complex::Complex64;

/// What the range processing gives for one record.
#[derive(Debug, Clone)]
pub(crate) struct RangeResult {
    /// Primary profile first (MUSIC over Fourier when both; Fourier for the grid-free
    /// estimators), ranges from the antennas, amplitudes relative to a unit-gain path.
    pub profiles: Vec<Profile>,
    /// Ranges estimated without a grid (root-MUSIC, ESPRIT) or refined off it (MUSIC's peaks).
    pub estimates_m: Option<Vec<f64>>,
    /// The primary profile's complex values, on its scale (correlation and Fourier): what the
    /// detector fits targets to.
    pub complex: Option<Vec<Complex64>>,
}

impl RangeResult {
    /// The primary profile.
    pub(crate) fn primary(&self) -> &Profile {
        &self.profiles[0]
    }
}
