//! The transmission and what the receiver makes of it: the waveform families, the processing
//! options and choices, and the one pipeline every command goes through. Processing reads no file
//! (`tests/house/reads_no_file.rs`): the calibration comes loaded with the options.
//!
//! | module | what it holds |
//! |---|---|
//! | `transmit` | the waveform as AWG codes plus what the receiver needs |
//! | `family` | each waveform family's behaviour in one room (`family/msk_lfm.rs`, `family/ofdm.rs`): overrides, transmission, payload decoder, algorithms; `family::of` is the one `match` over the families |
//! | `receiver` | one family's communication receiver as the rooms implement it and `payload` drives it: the generator as the receivers use it, the decoder, what it recovered, the link's plots |
//! | `payload` | the communication receivers of the pipeline |
//! | `options` | the processing options (algorithm, window, M/p, ranges, Pfa) as plain data, and their defaults |
//! | `choices` | the processing choices a user makes, declared once: command-line options, a campaign's `[processing]`, Python's keywords |
//! | `listed` | library enums taken by name on the command line and in files, and clap's parser of them |
//! | `pipeline` | decimation, alignment, background, range profile, detection, metrics, payload |
//! | `detect` | the detection stage of the pipeline |
//! | `range_result` | what range processing gives for one record (the detector's input) |
//! | `ranging` | each target's standard uncertainty of range, and `--ranging phase`: the envelope's range refined by the echo's carrier phase |
//! | `clipping` | samples at the ADC's rails, the advice, and conservative detection when a record clipped |
//! | `ambiguity` | a waveform's ambiguity function as uploaded, a capture's cross-ambiguity |
//! | `numbers` | measured numbers as people read them: a zero is `0`, never `0.00e0` nor `-0.0` |

pub(crate) mod ambiguity;
pub(crate) mod choices;
pub(crate) mod clipping;
pub(crate) mod detect;
pub(crate) mod family;
pub(crate) mod listed;
pub(crate) mod numbers;
pub(crate) mod options;
pub(crate) mod payload;
pub(crate) mod pipeline;
pub(crate) mod range_result;
pub(crate) mod ranging;
pub(crate) mod receiver;
pub(crate) mod transmit;
