//! One bench measurement: generate the waveform, configure the AWG and the scope, enable RF (with
//! the user's permit), capture one marker-triggered repetition, then process it ([`process`]).
//!
//! | module | what it holds |
//! |---|---|
//! | [`bench_file`] | the bench file: instruments, resources, calibration |
//! | [`transmit`] | the waveform as AWG codes plus what the receiver needs |
//! | [`process`] | decimation, alignment, background, range profile, detection, payload |
//! | [`run`] | connecting the drivers and running one capture under the safe-state guard |

pub mod bench_file;
pub mod process;
pub mod run;
pub mod transmit;

use crate::exit::{Classify, ExitClass};

/// Why a measurement failed.
#[derive(Debug, thiserror::Error)]
pub enum MeasureError {
    /// A bad parameter (names it and what is allowed).
    #[error("{0}")]
    Param(String),
    /// The waveform could not be made.
    #[error(transparent)]
    Waveform(#[from] crate::waveform::ParamError),
    /// An instrument refused or its link failed.
    #[error(transparent)]
    Driver(#[from] crate::driver::DriverError),
    /// The bench file is unusable.
    #[error(transparent)]
    BenchFile(#[from] bench_file::BenchFileError),
    /// The catalog is unusable.
    #[error(transparent)]
    Catalog(#[from] crate::catalog::CatalogError),
    /// Range processing failed.
    #[error(transparent)]
    Dsp(#[from] crate::dsp::DspError),
    /// The data could not be processed into a result.
    #[error("{0}")]
    Processing(String),
    /// The user stopped the measurement (the bench was put in its safe state).
    #[error("interrupted: the bench was put in its safe state ({0})")]
    Interrupted(String),
}

impl Classify for MeasureError {
    fn exit_class(&self) -> ExitClass {
        match self {
            MeasureError::Param(_) | MeasureError::Waveform(_) => ExitClass::BadInput,
            MeasureError::Driver(e) => e.exit_class(),
            MeasureError::BenchFile(e) => e.exit_class(),
            MeasureError::Catalog(e) => e.exit_class(),
            MeasureError::Dsp(e) => e.exit_class(),
            MeasureError::Processing(_) => ExitClass::Processing,
            MeasureError::Interrupted(_) => ExitClass::Interrupted,
        }
    }
}
