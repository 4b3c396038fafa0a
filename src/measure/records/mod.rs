//! A measurement's files and what is read back from them: writing SigMF, `.trc`, profiles, plots
//! and `summary.json`; saved captures through the pipeline again, their arrays for notebooks, and
//! repetitions' averages and spread.
//!
//! | module | what it holds |
//! |---|---|
//! | `record` | a measurement's files: SigMF, `.trc`, profiles, plots, `summary.json` |
//! | `recorder` | one capture from its take to its files: the raw recording beside the processing, then each algorithm's files |
//! | `figure` | what a measurement's plot and profile table show |
//! | `export` | a saved capture's arrays for a notebook (I/Q, profiles, detections, transmission), got through `reprocess` |
//! | `reprocess` | saved captures (capture folders, SigMF, `.trc` pairs) through the pipeline again |
//! | `repeat` | several repetitions: coherent average and spread |

pub(crate) mod export;
pub(crate) mod figure;
pub(crate) mod record;
pub(crate) mod recorder;
pub(crate) mod repeat;
pub(crate) mod reprocess;
