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
pub mod correlate;
pub mod decimate;
pub mod detect;
pub(crate) mod iq_image;
pub(crate) mod link_quality;
pub mod metrics;
pub mod music;
pub mod ofdm_radar;
pub mod range_profile;
pub(crate) mod response;
pub mod window;

/// Speed of light in vacuum, m/s (defined in [`crate::physics`]).
pub use crate::physics::C0;
