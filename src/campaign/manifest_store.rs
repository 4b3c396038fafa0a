//! Storing `manifest.toml` after every step without holding every step's record in memory.
//!
//! A run of N steps stores its manifest N times, and the manifest holds a table per step (about
//! 3 kB: what the instruments applied, every file with its hash). Kept in memory as records, as
//! their text, in the worker's copy and in every step's snapshot, they made a campaign grow by
//! about 55 kB a step (234 to 509 MB over 5000 steps; docs/campaign.md, "Retries"). Here a
//! step's table is serialised once, when its record changes, and then lives only in the file:
//! each store writes the head (everything but the steps) and copies the step tables of the file
//! it wrote last around the one that changed. It keeps their lengths alone (8 bytes a step), and
//! the runner keeps each step's status alone ([`StepRecord::status_only`]).

use super::error::{io, CampaignError};
use super::manifest::{Manifest, StepRecord, MANIFEST_FILE};
use crate::storage::atomic::AtomicFile;
use std::os::unix::fs::FileExt;
use std::path::Path;

/// Bytes copied at a time from the last manifest to the new one.
const COPY_CHUNK: usize = 256 * 1024;

/// Writes a run's manifest, keeping where its step tables lie in the file it wrote last.
#[derive(Debug, Default)]
pub struct ManifestStore {
    /// Where the step tables begin in the file last written (after the head).
    tables_at: u64,
    /// Each step's table length in that file, in step order; empty before the first store.
    lengths: Vec<u64>,
}

impl ManifestStore {
    /// Stores `manifest` whole (head and every step's table, from its records), atomically.
    /// The first store of a session: the later ones copy these tables.
    pub fn store_whole(
        &mut self,
        manifest: &mut Manifest,
        dir: &Path,
    ) -> Result<(), CampaignError> {
        let head = manifest.head_text(dir)?;
        let path = dir.join(MANIFEST_FILE);
        let mut file = AtomicFile::create(&path)?;
        file.write(head.as_bytes())?;
        let mut lengths = Vec::with_capacity(manifest.steps.len());
        for step in &manifest.steps {
            let table = Manifest::step_table(step, dir)?;
            file.write(table.as_bytes())?;
            lengths.push(table.len() as u64);
        }
        file.commit()?;
        self.tables_at = head.len() as u64;
        self.lengths = lengths;
        Ok(())
    }

    /// Stores `manifest`'s head (its `steps` are not read) with the step tables of the last
    /// store, `changed`'s replaced by its record's, atomically.
    pub fn store(
        &mut self,
        manifest: &mut Manifest,
        dir: &Path,
        changed: Option<&StepRecord>,
    ) -> Result<(), CampaignError> {
        let path = dir.join(MANIFEST_FILE);
        let bug = |message: String| CampaignError::Manifest {
            path: path.clone(),
            message: format!("{message} (a radbench bug, please report it)"),
        };
        if self.lengths.is_empty() {
            return Err(bug("stored by steps before it was stored whole".into()));
        }
        let head = manifest.head_text(dir)?;
        let last = std::fs::File::open(&path).map_err(io(&path))?;
        let expected = self.tables_at + self.lengths.iter().sum::<u64>();
        let found = last.metadata().map_err(io(&path))?.len();
        if found != expected {
            return Err(bug(format!(
                "is {found} bytes long, not the {expected} this session wrote"
            )));
        }
        let (index, table) = match changed {
            Some(step) if (1..=self.lengths.len()).contains(&step.index) => {
                (step.index, Manifest::step_table(step, dir)?)
            }
            Some(step) => return Err(bug(format!("has no step {}", step.index))),
            None => (0, String::new()),
        };
        let mut file = AtomicFile::create(&path)?;
        file.write(head.as_bytes())?;
        let mut buf = vec![0u8; COPY_CHUNK];
        let before: u64 = self.lengths[..index.saturating_sub(1)].iter().sum();
        let mut copy = |from: u64, len: u64, file: &mut AtomicFile| {
            let mut done = 0;
            while done < len {
                let n = ((len - done) as usize).min(COPY_CHUNK);
                last.read_exact_at(&mut buf[..n], from + done)
                    .map_err(io(&path))?;
                file.write(&buf[..n])?;
                done += n as u64;
            }
            Ok::<_, CampaignError>(())
        };
        if index == 0 {
            copy(self.tables_at, expected - self.tables_at, &mut file)?;
        } else {
            let old = self.lengths[index - 1];
            copy(self.tables_at, before, &mut file)?;
            file.write(table.as_bytes())?;
            let after = self.tables_at + before + old;
            copy(after, expected - after, &mut file)?;
        }
        file.commit()?;
        self.tables_at = head.len() as u64;
        if index > 0 {
            self.lengths[index - 1] = table.len() as u64;
        }
        Ok(())
    }
}
