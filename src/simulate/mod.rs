//! Simulations: the thesis' chapter-4 scenarios and free-form runs, built on `waveform` and `dsp`.
//!
//! | module | what |
//! |---|---|
//! | `scene` | targets, carrier-phase conventions, exact echo synthesis (fractional delay, upsampling) |
//! | `scene_bench` | `simulate run --scene`: the built-in mock lab's capture of a scene file, in-process (same synthesis, scope and pipeline) |
//! | `noise` | complex white noise at a per-sample SNR |
//! | `spec` | what a run asks for ([`spec::RunSpec`]) and reports ([`spec::ScenarioResult`], the JSON) |
//! | `run` | the engine: transmit, echoes, capture chain, noise, then the measurement pipeline ([`crate::measure::Pipeline`], the same as a bench capture), metrics, trials |
//! | `accuracy` | the accuracy steps of thesis 4.4.2 through the 80 -> 16 GSa/s chain |
//! | `thesis` | every chapter-4 simulation, compared with the thesis |
//! | `ber` | BER against Eb/N0 for both waveforms, next to theory |
//! | `report` | plain-text reports |
//! | `kernels` | the DSP kernels `radbench bench` times, and their seeded inputs |

use crate::exit::{Classify, ExitClass};

pub(crate) mod accuracy;
pub(crate) mod ber;
pub(crate) mod kernels;
pub(crate) mod noise;
pub(crate) mod report;
pub(crate) mod run;
pub(crate) mod scene;
pub(crate) mod scene_bench;
pub(crate) mod spec;
pub(crate) mod thesis;

pub use accuracy::{run_steps, AccuracySpec, AccuracyStep, AccuracyStudy};
pub use ber::{plot_series, run_curves, BerCurvePoint};
pub use kernels::{time_all, KernelInputs, KernelTiming, Kernels, XCORR_LAGS};
pub use report::{ber_text, scenario_text};
pub use run::{echoes, first_trial, pipeline, process_options, simulate, transmission, SimOutcome};
pub use scene::{parse_targets, CarrierPhase, Target};
pub use scene_bench::{simulate_scene, SceneOutcome, SceneSpec};
pub use spec::{
    Algorithm, FftPrecisionName, ProcessOptions, RunSpec, ScenarioResult, WaveformSpec, WindowName,
};
pub use thesis::{mean_psl_and_width, run_all, ThesisRow, ThesisTable};

/// Why a simulation could not run.
#[derive(Debug, thiserror::Error)]
pub enum SimError {
    /// A simulation parameter is unusable; names the CLI field and what is allowed.
    #[error("{field}: {reason}")]
    Param { field: &'static str, reason: String },
    /// The waveform layer refused its parameters.
    #[error(transparent)]
    Waveform(#[from] crate::waveform::ParamError),
    /// The processing layer refused its parameters or the data.
    #[error(transparent)]
    Dsp(#[from] crate::dsp::DspError),
    /// The measurement pipeline refused the run's options or failed.
    #[error(transparent)]
    Measure(#[from] crate::measure::MeasureError),
    /// An output (plot, profile) could not be written.
    #[error(transparent)]
    Storage(#[from] crate::storage::StorageError),
}

impl Classify for SimError {
    fn exit_class(&self) -> ExitClass {
        match self {
            SimError::Param { .. } => ExitClass::BadInput,
            SimError::Waveform(e) => e.exit_class(),
            SimError::Dsp(e) => e.exit_class(),
            SimError::Storage(e) => e.exit_class(),
            SimError::Measure(e) => e.exit_class(),
        }
    }
}
