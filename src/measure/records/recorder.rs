//! One capture from its take to its files (issue 42): the raw recording, then each algorithm's
//! files from the take and what that algorithm made of it. `radbench capture` (once and
//! `--repeat`), a campaign's step and the Python package's warm session all record through
//! [`Recorder`]; `align` and `calibrate` write no file and only measure
//! ([`Rig::measure`](crate::measure::capture::Rig::measure)).
//!
//! Two ways through, for two kinds of caller:
//! * [`Recorder::record`] (a capture on the command line): the raw recording is written and made
//!   durable on a thread of its own while the capture is processed, so that a capture whose
//!   processing fails is still kept; the processed files follow, the link figure drawn beside
//!   the profiles.
//! * [`Recorder::write`] (a measurement processed already: a campaign's step, processed on the
//!   campaign's worker while the next step is captured, or the warm session): every file on the
//!   calling thread, in its write group (a campaign's manifest hashes them), writing only the
//!   files a `keep` list keeps.

use super::record::{self, CaptureFiles, Keep, Provenance, RawFiles};
use crate::measure::capture::{process_with, Measurement, Prepared, Processing, Taken};
use crate::measure::error::MeasureError;
use crate::storage::{write_group, write_group_open};
use serde_json::Value;
use std::path::Path;
use std::sync::Arc;

/// Where one capture's files go and where it came from.
#[derive(Debug, Clone, Copy)]
pub struct Recorder<'a> {
    out: &'a Path,
    provenance: &'a Provenance,
}

/// A capture processed and its files written.
pub struct Recorded {
    pub measurement: Measurement,
    /// What `summary.json` holds (and `capture --json` prints).
    pub summary: Value,
}

/// Why a capture's files were not all written.
#[derive(Debug)]
pub struct NotRecorded {
    pub error: MeasureError,
    /// The processing failed after the raw recording was written: it is kept in the output
    /// folder, for `radbench process` to process again.
    pub raw_kept: bool,
}

impl From<MeasureError> for NotRecorded {
    fn from(error: MeasureError) -> NotRecorded {
        NotRecorded {
            error,
            raw_kept: false,
        }
    }
}

impl<'a> Recorder<'a> {
    /// Records into `out` (created when missing).
    pub fn new(out: &'a Path, provenance: &'a Provenance) -> Recorder<'a> {
        Recorder { out, provenance }
    }

    /// Processes `taken` through `prepared` while its raw recording is written and made durable
    /// (a write group of its own, on a blocking thread: on two cores the files cost no time);
    /// then `amend` adds to the measurement (the calibration's warnings) before the processed
    /// files are written, `summary.json` last, the link figure drawn beside the profiles.
    pub async fn record(
        &self,
        taken: Taken,
        prepared: &mut Prepared,
        amend: impl FnOnce(&mut Measurement),
    ) -> Result<Recorded, NotRecorded> {
        let taken = Arc::new(taken);
        let raw_writer = {
            let (out, taken) = (self.out.to_path_buf(), taken.clone());
            let provenance = self.provenance.clone();
            let options = prepared.options_for(&taken.captured);
            tokio::task::spawn_blocking(move || {
                // Not hashed: a capture lists no written file's SHA-256 (the SigMF data's
                // SHA-512 is in its metadata).
                let (raw, group) = write_group_open(|| {
                    record::write_raw(&out, &taken, &options, &provenance, &record::keep_all)
                })?;
                group.finish().map_err(MeasureError::from)?;
                Ok::<_, MeasureError>(raw)
            })
        };
        let processing = process_with(prepared, &taken.captured).await;
        let raw = raw_writer
            .await
            .map_err(|e| MeasureError::Worker(format!("writing the raw capture: {e}")))??;
        let processing = processing.map_err(|error| NotRecorded {
            error,
            raw_kept: true,
        })?;
        let taken = Arc::try_unwrap(taken)
            .map_err(|_| MeasureError::Worker("the raw capture is still being written".into()))?;
        let mut measurement = taken.with(processing);
        amend(&mut measurement);
        let ((_, summary), group) = write_group_open(|| {
            record::write_processed(
                self.out,
                &measurement,
                &raw,
                self.provenance,
                true,
                &record::keep_all,
            )
        })?;
        group.finish().map_err(MeasureError::from)?;
        Ok(Recorded {
            measurement,
            summary,
        })
    }

    /// Writes the files of `m`, processed already, on the calling thread as one write group (or
    /// in the caller's, when it has one: a campaign's manifest lists them): the raw recording and the profiles of `m`'s
    /// algorithm in the output folder, those of each further algorithm (`others`, with its
    /// name) in a subfolder named after it; only the files `keep` keeps (`summary.json`
    /// names them all). Returns the primary algorithm's files and summary.
    pub(crate) fn write(
        &self,
        m: &mut Measurement,
        others: &mut [(&str, Processing)],
        keep: Keep<'_>,
    ) -> Result<(CaptureFiles, Value), MeasureError> {
        let (primary, _) = write_group(|| {
            let raw = record::write_raw(
                self.out,
                &m.taken,
                &m.processing.options,
                self.provenance,
                keep,
            )?;
            let primary = self.write_processed(self.out, m, &raw, keep)?;
            for (name, processing) in others.iter_mut() {
                // A further algorithm's files are written from the same take: its processing
                // stands in for the primary's while they are.
                std::mem::swap(&mut m.processing, processing);
                let written = self.write_processed(&self.out.join(&**name), m, &raw, keep);
                std::mem::swap(&mut m.processing, processing);
                written?;
            }
            Ok::<_, MeasureError>(primary)
        })?;
        Ok(primary)
    }

    fn write_processed(
        &self,
        out: &Path,
        m: &Measurement,
        raw: &RawFiles,
        keep: Keep<'_>,
    ) -> Result<(CaptureFiles, Value), MeasureError> {
        record::write_processed(out, m, raw, self.provenance, false, keep)
    }
}
