//! The chain's calibrations: the system delay from a reference target (`delay`), the response
//! (measured on a bench or from a saved capture, stored, loaded once where a command resolves its
//! options) and the correction a measurement uses.
//!
//! | module | what it holds |
//! |---|---|
//! | `delay` | the system delay from a reference target |
//! | `response` | the chain's response calibration: measured on one reference pillar, stored as a TOML header beside a `.npy` table, applied on receive |
//! | `response_from_capture` | a response calibration measured from a saved capture of one reference pillar |
//! | `response_keep` | what `calibrate response` does with a measured response: where it is stored, naming it in the bench file, the report as data |
//! | `response_run` | running a response calibration on a bench: the reference captured with the transmitter on and off, the response measured and tried |
//! | `correction` | the correction a measurement uses: its record, and the calibration loaded once where a command resolves its options (processing reads no file) |
//! | `predistortion_tests` | the transmitter's pre-distortion against the mock lab's realistic chain (tests) |

pub(crate) mod correction;
pub(crate) mod delay;
#[cfg(test)]
mod predistortion_tests;
pub(crate) mod response;
pub(crate) mod response_from_capture;
pub(crate) mod response_keep;
pub(crate) mod response_run;
