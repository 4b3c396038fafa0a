//! Recording a run's steps in `manifest.toml` at a cost per step that does not grow with the run.
//!
//! A run of N steps records N steps, and the manifest holds a table per step (about 3 kB: what
//! the instruments applied, every file with its hash) beside the plan (a few hundred bytes a
//! step). Rewriting the whole file after every step, as radbench did, wrote O(N) bytes a step and
//! O(N²) in all: 15 MB a step and 37 GB over a 5000-step night, the late steps' manifest taking
//! longer than their capture (docs/campaign.md, "Long runs"). Here:
//!
//! - at a session's start ([`ManifestStore::store_whole`]) and end ([`ManifestStore::store`]),
//!   `manifest.toml` is written whole, atomically, as always;
//! - in between, each step done is appended to the step journal ([`STEPS_JOURNAL`]) as one JSON
//!   line ([`JournalLine`]: the step's table, the retries since the line before, the session's
//!   timing), fdatasync'ed before the step counts as recorded: a few kB a step, whatever the
//!   run's length;
//! - once the end is stored whole, the journal is removed: a run folder at rest is as before.
//!
//! Readers ([`Manifest::load`], the Python package's `read_run`) merge the journal's complete
//! lines into the file; a line cut short (a crash, a full disk) ends it, and its step is measured
//! again by a resume. A full disk at the end leaves the journal and the status room rewritten in
//! place (docs/campaign.md, "A status that never lies").
//!
//! Memory stays flat as well: the tables live only in the files. The store keeps where each
//! step's table lies (in the last `manifest.toml` or in the journal, 16 bytes a step) and copies
//! them at the end; the runner keeps each step's status alone ([`StepRecord::status_only`]).

use super::error::{io, CampaignError};
use super::manifest::{remove_journal, JournalLine, Manifest, MANIFEST_FILE, STEPS_JOURNAL};
use crate::storage::atomic::AtomicFile;
use std::io::Write;
use std::os::unix::fs::{FileExt, OpenOptionsExt};
use std::path::Path;

/// Bytes copied at a time from the last manifest to the new one.
const COPY_CHUNK: usize = 256 * 1024;

/// Where a step's table is.
#[derive(Debug, Clone, Copy)]
enum Table {
    /// In the last `manifest.toml`, as TOML: its offset and length.
    File { at: u64, len: u64 },
    /// In the step journal, as a JSON line: its offset and length (newline included).
    Journal { at: u64, len: u64 },
}

/// Writes a run's manifest and its step journal, keeping where every step's table lies.
#[derive(Debug, Default)]
pub struct ManifestStore {
    /// Each step's table, in step order; empty before the first store.
    tables: Vec<Table>,
    /// The length of the last `manifest.toml` this store wrote.
    file_len: u64,
    /// The step journal, open for appending (and reading back at the end).
    journal: Option<std::fs::File>,
    /// Its length: everything in it is complete lines.
    journal_len: u64,
}

impl ManifestStore {
    /// Stores `manifest` whole (head and every step's table, from its records), atomically,
    /// then removes the step journal (the file holds what it had). The first store of a session.
    pub fn store_whole(
        &mut self,
        manifest: &mut Manifest,
        dir: &Path,
    ) -> Result<(), CampaignError> {
        let head = manifest.head_text(dir)?;
        let path = dir.join(MANIFEST_FILE);
        let mut file = AtomicFile::create(&path)?;
        file.write(head.as_bytes())?;
        let mut tables = Vec::with_capacity(manifest.steps.len());
        let mut at = head.len() as u64;
        for step in &manifest.steps {
            let table = Manifest::step_table(step, dir)?;
            file.write(table.as_bytes())?;
            let len = table.len() as u64;
            tables.push(Table::File { at, len });
            at += len;
        }
        file.commit()?;
        self.tables = tables;
        self.file_len = at;
        self.close_journal(dir)
    }

    /// Records step `line.step` done: appends `line` to the step journal and makes it durable
    /// (the journal's folder entry too, when this creates it). A write refused (a full disk)
    /// takes the journal back to its last complete line and fails.
    pub fn record_step(&mut self, line: &JournalLine, dir: &Path) -> Result<(), CampaignError> {
        let path = dir.join(STEPS_JOURNAL);
        let index = line.step.index;
        if !(1..=self.tables.len()).contains(&index) {
            return Err(self.bug(dir, format!("has no step {index}")));
        }
        let mut text = serde_json::to_string(line).map_err(|e| CampaignError::Manifest {
            path: path.clone(),
            message: format!("cannot be written: {e} (a radbench bug, please report it)"),
        })?;
        text.push('\n');
        let created = self.journal.is_none();
        if created {
            let file = std::fs::OpenOptions::new()
                .read(true)
                .append(true)
                .create_new(true)
                .custom_flags(libc::O_NOFOLLOW)
                .open(&path)
                .map_err(refused(&path))?;
            self.journal = Some(file);
            self.journal_len = 0;
        }
        let file = self.journal.as_mut().expect("opened above");
        let written = file
            .write_all(text.as_bytes())
            .and_then(|()| file.sync_data());
        if let Err(e) = written {
            // Nothing half written stays: the next line (a step settled after this one) would
            // follow it, and a reader stops at the first line that is not whole.
            let _ = file.set_len(self.journal_len);
            return Err(refused(&path)(e));
        }
        if created {
            sync_folder(dir).map_err(refused(dir))?;
        }
        let len = text.len() as u64;
        self.tables[index - 1] = Table::Journal {
            at: self.journal_len,
            len,
        };
        self.journal_len += len;
        Ok(())
    }

    /// Stores `manifest`'s head (its `steps` are not read) with every step's table as last
    /// recorded (in the last file or the journal), atomically, then removes the journal. A
    /// session's end.
    pub fn store(&mut self, manifest: &mut Manifest, dir: &Path) -> Result<(), CampaignError> {
        let path = dir.join(MANIFEST_FILE);
        if self.tables.is_empty() {
            return Err(self.bug(dir, "stored by steps before it was stored whole".into()));
        }
        let head = manifest.head_text(dir)?;
        let last = std::fs::File::open(&path).map_err(io(&path))?;
        let found = last.metadata().map_err(io(&path))?.len();
        if found != self.file_len {
            return Err(self.bug(
                dir,
                format!(
                    "is {found} bytes long, not the {} this session wrote",
                    self.file_len
                ),
            ));
        }
        let mut file = AtomicFile::create(&path)?;
        file.write(head.as_bytes())?;
        let mut buf = vec![0u8; COPY_CHUNK];
        let mut tables = Vec::with_capacity(self.tables.len());
        let mut at = head.len() as u64;
        // Runs of tables that follow each other in the last file are copied in one go.
        let mut run: Option<(u64, u64)> = None;
        let copy = |from: u64, len: u64, file: &mut AtomicFile, buf: &mut [u8]| {
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
        for table in &self.tables {
            match *table {
                Table::File { at: from, len } => {
                    run = match run {
                        Some((start, n)) if start + n == from => Some((start, n + len)),
                        Some((start, n)) => {
                            copy(start, n, &mut file, &mut buf)?;
                            Some((from, len))
                        }
                        None => Some((from, len)),
                    };
                    tables.push(Table::File { at, len });
                    at += len;
                }
                Table::Journal { at: from, len } => {
                    if let Some((start, n)) = run.take() {
                        copy(start, n, &mut file, &mut buf)?;
                    }
                    let text = self.journal_table(dir, from, len)?;
                    file.write(text.as_bytes())?;
                    let len = text.len() as u64;
                    tables.push(Table::File { at, len });
                    at += len;
                }
            }
        }
        if let Some((start, n)) = run {
            copy(start, n, &mut file, &mut buf)?;
        }
        file.commit()?;
        self.tables = tables;
        self.file_len = at;
        self.close_journal(dir)
    }

    /// The TOML table of the journal's line at `at` (`len` bytes).
    fn journal_table(&self, dir: &Path, at: u64, len: u64) -> Result<String, CampaignError> {
        let path = dir.join(STEPS_JOURNAL);
        let Some(journal) = &self.journal else {
            return Err(self.bug(dir, "has a step in a journal it does not hold".into()));
        };
        let mut line = vec![0u8; len as usize];
        journal.read_exact_at(&mut line, at).map_err(io(&path))?;
        let line: JournalLine =
            serde_json::from_slice(&line).map_err(|e| CampaignError::Manifest {
                path: path.clone(),
                message: format!("a line this session wrote does not read back: {e}"),
            })?;
        Manifest::step_table(&line.step, dir)
    }

    /// Closes and removes the step journal, once `manifest.toml` holds its steps.
    fn close_journal(&mut self, dir: &Path) -> Result<(), CampaignError> {
        self.journal = None;
        self.journal_len = 0;
        remove_journal(dir)
    }

    fn bug(&self, dir: &Path, message: String) -> CampaignError {
        CampaignError::Manifest {
            path: dir.join(MANIFEST_FILE),
            message: format!("{message} (a radbench bug, please report it)"),
        }
    }
}

/// A write refused (a full disk, a read-only file system), said as every refused write is
/// (`cannot write PATH: ...`, with the remedy).
fn refused(path: &Path) -> impl FnOnce(std::io::Error) -> CampaignError {
    let path = path.to_path_buf();
    move |source| CampaignError::Storage(crate::storage::StorageError::Io { path, source })
}

fn sync_folder(dir: &Path) -> std::io::Result<()> {
    std::fs::File::open(dir)?.sync_all()
}
