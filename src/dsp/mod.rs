//! Pure signal processing: decimation, correlation, OFDM range processing, MUSIC, windows, metrics,
//! target detection.

#![warn(clippy::missing_errors_doc, clippy::missing_panics_doc)]

use crate::exit::{Classify, ExitClass};

/// A processing failure or an unusable processing parameter.
#[derive(Debug, thiserror::Error)]
pub enum DspError {
    /// A parameter is out of range; the message names it and what is allowed.
    #[error("{0}")]
    Param(String),
    /// The data could not be processed.
    #[error("{0}")]
    Processing(String),
}

impl Classify for DspError {
    fn exit_class(&self) -> ExitClass {
        match self {
            DspError::Param(_) => ExitClass::BadInput,
            DspError::Processing(_) => ExitClass::Processing,
        }
    }
}

pub(crate) mod ambiguity;
pub(crate) mod carrier_phase;
pub(crate) mod chain_echoes;
pub(crate) mod correlate;
pub(crate) mod decimate;
pub(crate) mod detect;
pub(crate) mod iq_image;
pub(crate) mod link_quality;
pub(crate) mod metrics;
pub(crate) mod music;
pub(crate) mod ofdm_radar;
pub(crate) mod phasor;
pub(crate) mod plans;
pub(crate) mod range_profile;
pub(crate) mod residual;
pub(crate) mod response;
pub(crate) mod toeplitz;
pub(crate) mod window;

pub use correlate::{fast_fft_len, CrossCorrelator, Strategy};
pub use decimate::{Alignment, Decimator, DecimatorConfig, LowPassSpec, PeriodicDecimator};
pub use detect::{
    CfarKind, DetectOptions, DetectedTarget, Detections, Detector, Method, NoiseEstimate,
    PointSpread, PsfShape, ResidualFloor, Sidelobes, SpectralLines, TabulatedPsf,
};
pub use metrics::{
    find_peaks, interpolate_peak, resolve_targets, sidelobe_levels, width_3db, Axis, CaCfar,
    CfarDetection, Interpolation, Peak, Resolution, SidelobeLevels,
};
pub use music::{HermitianEigen, ModelOrder, Music, MusicConfig, MusicSpectrum, OrderCriterion};
pub use ofdm_radar::{
    Averaging, FftPrecision, IDiv, OfdmRadar, OfdmRadarConfig, RangeDoppler, RangeDopplerConfig,
    RangeDopplerMap, RangeProfile,
};
pub use range_profile::{CorrelationProfiler, Profile};
pub use window::Window;

/// Speed of light in vacuum, m/s (defined in [`crate::physics`]).
pub use crate::physics::C0;
