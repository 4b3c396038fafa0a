//! Bench measurements: the bench in use, the transmission, one capture under the safe-state guard,
//! and the one processing pipeline every command goes through.
//!
//! | module | what it holds |
//! |---|---|
//! | `ambiguity` | a waveform's ambiguity function as uploaded, a capture's cross-ambiguity |
//! | `bench_file` | the bench file: instruments, resources, calibration |
//! | `bench` | the bench in use: a bench file, or the built-in mock lab started in-process |
//! | `family` | each waveform family's behaviour in one room (`family/msk_lfm.rs`, `family/ofdm.rs`): overrides, transmission, payload decoder, algorithms; `family::of` is the one `match` over the families |
//! | `transmit` | the waveform as AWG codes plus what the receiver needs |
//! | `choices` | the processing choices a user makes, declared once: command-line options, a campaign's `[processing]`, Python's keywords |
//! | `listed` | library enums taken by name on the command line and in files, and clap's parser of them |
//! | `options` | the processing options (algorithm, window, M/p, ranges, Pfa) as plain data, and their defaults |
//! | `pipeline` | decimation, alignment, background, range profile, detection, metrics, payload |
//! | `detect` | the detection stage of the pipeline |
//! | `range_result` | what range processing gives for one record (the detector's input) |
//! | [`doctor`] | the bench doctor: every check of a bench that needs no RF, with what to fix; its own room (`measure::doctor::examine`, its `Report`, `Check`, `Status`) |
//! | `clipping` | samples at the ADC's rails, the advice, and conservative detection when a record clipped |
//! | `payload` | the communication receivers of the pipeline |
//! | `receiver` | one family's communication receiver as the rooms implement it and `payload` drives it: the generator as the receivers use it, the decoder, what it recovered, the link's plots |
//! | `scene_control` | the simulated bench's scene, typed: set it, reseed its noise, read it back |
//! | `station` | the connected instruments: plan, upload, RF on, capture, safe state |
//! | `capture` | one complete measurement: prepare (everything checked), capture, process |
//! | `reprocess` | saved captures (capture folders, SigMF, `.trc` pairs) through the pipeline again |
//! | `export` | a saved capture's arrays for a notebook (I/Q, profiles, detections, transmission), got through `reprocess` |
//! | `repeat` | several repetitions: coherent average and spread |
//! | `figure` | what a measurement's plot and profile table show |
//! | `record` | a measurement's files: SigMF, `.trc`, profiles, plots, `summary.json` |
//! | `calibration` | the system delay from a reference target |
//! | `correction` | the correction a measurement uses: its record, and the calibration loaded once where a command resolves its options (processing reads no file) |
//! | `interrupt` | SIGINT, SIGTERM and SIGHUP as a measurement's stop request |
//! | `error` | why a measurement failed, what to do about it and its exit code |
//! | `blocking` | heavy synchronous work (DSP, file writing) run off the async runtime's workers |
//! | `verify_catalog` | `doctor --verify-catalog`: the catalog's inferred values asked of the instruments; override files |
//! | `manual` | front ends with `driver = "manual"`: the operator's instructions, confirmation and exit note |

pub(crate) mod ambiguity;
pub(crate) mod bench;
pub(crate) mod bench_file;
pub(crate) mod blocking;
pub(crate) mod calibration;
pub(crate) mod capture;
pub(crate) mod choices;
pub(crate) mod clipping;
pub(crate) mod correction;
pub(crate) mod detect;
pub mod doctor;
mod error;
pub(crate) mod export;
pub(crate) mod family;
pub(crate) mod figure;
pub(crate) mod interrupt;
pub(crate) mod listed;
pub(crate) mod manual;
pub(crate) mod numbers;
pub(crate) mod options;
pub(crate) mod payload;
pub(crate) mod pipeline;
#[cfg(test)]
mod predistortion_tests;
pub(crate) mod range_result;
pub(crate) mod ranging;
pub(crate) mod receiver;
pub(crate) mod record;
pub(crate) mod repeat;
pub(crate) mod reprocess;
pub(crate) mod response;
pub(crate) mod response_from_capture;
pub(crate) mod response_keep;
pub(crate) mod response_run;
pub(crate) mod scene_capture;
pub(crate) mod scene_control;
pub(crate) mod station;
pub(crate) mod transmit;
pub(crate) mod verify_catalog;

pub use ambiguity::{ambiguity, AmbiguityReport};
pub(crate) use bench::planning_scope_resource;
pub use bench::{AwgLink, Bench, BenchSource, BuiltIn, ScopeLink, ScopeModel};
pub use bench_file::{
    store_calibration, uncalibrated_warning, BenchCalibration, BenchFile, BenchFileError,
    InstrumentEntry, ManualFrontEnd, Simulation,
};
pub(crate) use calibration::default_gate_s;
pub use calibration::{check, estimate_delay, DelayEstimate};
pub(crate) use capture::prepare_uploading;
pub use capture::{
    check_repetitions, prepare, process_with, take, BackgroundFile, CaptureRequest, Generation,
    Measurement, Prepared, Processing, Rig, Taken,
};
pub(crate) use correction::load_recorded;
pub use correction::CorrectionUsed;
pub use export::{export_capture, CaptureExport, Entry};
pub use figure::profile_figure;
pub use interrupt::{Interrupt, StopSignal};
pub use manual::{confirms, manual_exit_note, manual_instructions, manual_refused};
pub use numbers::{rate, signed};
pub use options::{DetectorName, Ranging};
pub use pipeline::{Alignable, Detection, DetectionReport, Losses, PayloadResult, RawWords};
pub(crate) use record::write_reprocessed_by_content;
pub use record::{
    write_capture, write_processed_beside, write_raw, write_reprocessed, CaptureFiles,
    ProfileFiles, Provenance, RawFiles, ReprocessFiles, SourceFile,
};
pub use repeat::{RepetitionResult, Spread, Stat, TargetSpread};
pub use reprocess::{
    discover, sigmf, InputError, Loaded, Record, Reprocessed, Resolved, Source, WaveformChoice,
};
pub use response::{
    Calibration, CorrectionMode, EchoSeen, InstrumentsSeen, PhaseAnchor, ReferenceFigures,
    Response, ResponseFigures, ResponseHeader,
};
pub use response_keep::{check_gate_ns, check_response_out, gate_or_default_s};
pub use response_keep::{response_path, response_report, store_response};
pub use response_run::{calibrate_with, CalibrateRequest, Calibrated};
pub use station::{Applied, CapturePlan, Captured, Identities, RepetitionSource, Uploaded};
pub use verify_catalog::{verify_catalog, write_overrides, CatalogCheck, CatalogValue, Verdict};

// Names two flattened submodules both define, chosen here: the capture's `measure` and the
// re-processing's `Repetition` (`response`'s are the crate's own).
pub use capture::measure;
pub use choices::{ModelOrderChoice, ModelOrderName, ProcessOverrides, ProcessingChoices};
pub use clipping::{ClipDetection, Clipping};
pub use error::MeasureError;
pub use listed::{listed, scope_models, Listed};
pub use options::{Algorithm, FftPrecisionName, ProcessOptions, WindowName};
pub use pipeline::{Aligned, Pipeline, Processed, RawIq, RecordGeometry};
pub use reprocess::Repetition;
pub use transmit::{Dac, Transmission};
