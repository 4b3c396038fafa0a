//! Bench measurements: the bench in use, the transmission, one capture under the safe-state guard,
//! and the one processing pipeline every command goes through. Four rooms, and the orchestration
//! that takes, processes and writes through them:
//!
//! | module | what it holds |
//! |---|---|
//! | `bench` | the bench in use and its instruments: the bench file, the connected station (plan, upload, RF on, capture, safe state), the simulated bench's scene, manual front ends, stop signals, the catalog's verification, work off the async runtime |
//! | `processing` | the transmission and what the receiver does with it, reading no file: the waveform families, the processing options and choices, the one pipeline (decimation, alignment, range profile, detection, ranging, clipping, payload) |
//! | `calibration` | the chain's calibrations: the system delay from a reference target, the response (measured, stored, loaded once where a command resolves its options) and the correction a measurement uses |
//! | `records` | a measurement's files and what is read back from them: SigMF, `.trc`, profiles, plots, `summary.json`, and the recorder that writes one capture's from its take; re-processing saved captures, their export for notebooks, repetitions' averages and spread |
//! | `capture` | one complete measurement: prepare (everything checked), capture, process |
//! | `error` | why a measurement failed, what to do about it and its exit code |
//! | [`doctor`] | the bench doctor: every check of a bench that needs no RF, with what to fix; its own room (`measure::doctor::examine`, its `Report`, `Check`, `Status`) |
//!
//! Every public item is re-exported here by name (`radbench::measure::<Name>`); the rooms and
//! their files are the crate's own.

pub(crate) mod bench;
pub(crate) mod calibration;
pub(crate) mod capture;
pub mod doctor;
mod error;
pub(crate) mod processing;
pub(crate) mod records;

pub use bench::bench_file::{
    store_calibration, uncalibrated_warning, BenchCalibration, BenchFile, BenchFileError,
    InstrumentEntry, ManualFrontEnd, Simulation,
};
pub(crate) use bench::in_use::planning_scope_resource;
pub use bench::in_use::{AwgLink, Bench, BenchSource, BuiltIn, ScopeLink, ScopeModel};
pub use bench::interrupt::{Interrupt, StopSignal};
pub use bench::manual::{confirms, manual_exit_note, manual_instructions, manual_refused};
pub use bench::station::{Applied, CapturePlan, Captured, Identities, RepetitionSource, Uploaded};
pub use bench::verify_catalog::{
    verify_catalog, write_overrides, CatalogCheck, CatalogValue, Verdict,
};
pub(crate) use calibration::correction::load_recorded;
pub use calibration::correction::CorrectionUsed;
pub(crate) use calibration::delay::default_gate_s;
pub use calibration::delay::{check, estimate_delay, DelayEstimate};
pub use calibration::response::check_reflector_m;
pub use calibration::response::{
    Calibration, CorrectionMode, EchoSeen, InstrumentsSeen, PhaseAnchor, ReferenceFigures,
    Response, ResponseFigures, ResponseHeader,
};
pub use calibration::response_keep::{check_gate_ns, check_response_out, gate_or_default_s};
pub use calibration::response_keep::{response_path, response_report, store_response};
pub use calibration::response_run::{calibrate_with, CalibrateRequest, Calibrated};
pub(crate) use capture::prepare_uploading;
pub use capture::{
    check_repetitions, prepare, take, BackgroundFile, CaptureRequest, Generation, Measurement,
    Prepared, Processing, Rig, Taken,
};
pub use processing::ambiguity::{ambiguity, AmbiguityReport};
pub use processing::numbers::{rate, signed};
pub use processing::options::{DetectorName, Ranging};
pub use processing::pipeline::{
    Alignable, Detection, DetectionReport, Losses, PayloadResult, RawWords,
};
pub use records::export::{export_capture, CaptureExport, Entry};
pub use records::figure::profile_figure;
pub(crate) use records::record::write_reprocessed_by_content;
pub use records::record::{
    write_reprocessed, ProfileFiles, Provenance, ReprocessFiles, SourceFile,
};
pub use records::recorder::{NotRecorded, Recorded, Recorder};
pub use records::repeat::{RepetitionResult, Spread, Stat, TargetSpread};
pub use records::reprocess::{
    discover, sigmf, InputError, Loaded, Record, Reprocessed, Resolved, Source, WaveformChoice,
};

// Names two flattened submodules both define, chosen here: the capture's `measure` and the
// re-processing's `Repetition` (`response`'s are the crate's own).
pub use capture::measure;
pub use error::MeasureError;
pub use processing::choices::{
    ModelOrderChoice, ModelOrderName, ProcessOverrides, ProcessingChoices,
};
pub use processing::clipping::{ClipDetection, Clipping};
pub use processing::listed::{listed, scope_models, Listed};
pub use processing::options::{Algorithm, FftPrecisionName, ProcessOptions, WindowName};
pub use processing::pipeline::{Aligned, Pipeline, Processed, RawIq, RecordGeometry};
pub use processing::transmit::{Dac, Transmission};
pub use records::reprocess::Repetition;
