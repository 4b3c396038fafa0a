//! `manifest.toml`: everything needed to trust, reproduce and resume a run. The inputs (spec and
//! bench file, copied into the run folder, with their SHA-256), the resolved plan, radbench's
//! version and git commit, the instruments' identities, each step's state, what the instruments
//! reported applying and every file written with its SHA-256, the sessions (first run, resumes)
//! and the status: `running` while a process works on it, then `complete` or `interrupted` with
//! the reason and the step where it stopped. A manifest left at `running` means the process died
//! without a word (a crash, SIGKILL, power loss); resume treats it as interrupted.
//!
//! It is rewritten atomically after each step and fsynced with its folder (`write_atomic` syncs
//! both).

use super::plan::Plan;
use super::{io, CampaignError};
use crate::measure::Identities;
use crate::storage::write_atomic;
use serde::{Deserialize, Serialize};
use sha2::{Digest, Sha256};
use std::io::Read;
use std::path::{Path, PathBuf};

/// Version of the manifest's layout.
pub(crate) const FORMAT: u32 = 1;

/// The manifest's file name in a run folder.
pub const MANIFEST_FILE: &str = "manifest.toml";

#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Status {
    Running,
    Complete,
    Interrupted,
}

impl Status {
    pub fn name(self) -> &'static str {
        match self {
            Status::Running => "running",
            Status::Complete => "complete",
            Status::Interrupted => "interrupted",
        }
    }
}

/// The whole manifest.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Manifest {
    pub format: u32,
    pub status: Status,
    /// Why the run stopped (interrupted runs).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub reason: Option<String>,
    /// The step it stopped at: the first step not done.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub stopped_at_step: Option<usize>,
    /// The exit code the run ended with (interrupted runs).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub exit_code: Option<i32>,
    pub radbench_version: String,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub git_commit: Option<String>,
    pub created: String,
    pub updated: String,
    pub spec: InputFile,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub bench_file: Option<InputFile>,
    /// The instrument files of the bench file's `catalog` folder, as the run read them.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub bench_catalog: Vec<InputFile>,
    /// The response calibration every step corrects with (`processing.correction = "rx"`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub calibration: Option<CalibrationRecord>,
    /// `*IDN?` of each instrument at the first connection.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub instruments: Option<Instruments>,
    /// A simulated bench of a bench file: the scene read from it at the start (every step sets
    /// it again with its own seed, targets and SNR).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub base_scene: Option<crate::measure::scene_control::Scene>,
    pub plan: Plan,
    pub sessions: Vec<Session>,
    /// Never empty in a stored manifest (a plan has steps); skipped when empty so that
    /// [`store_cached`](Self::store_cached) can append the steps' tables itself.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub steps: Vec<StepRecord>,
    /// The run's own files (results, report, journals), hashed when last written.
    pub files: Vec<FileRecord>,
}

/// An input file: where it came from, its copy in the run folder, its SHA-256.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct InputFile {
    /// The original path (absolute when it could be made so).
    pub path: PathBuf,
    /// The copy, relative to the run folder.
    pub copy: PathBuf,
    pub sha256: String,
}

/// The response calibration a run corrects with: where it came from, its copy in the run folder
/// (header and table; a resume whose original changed goes on with the copy), its SHA-256 and
/// when it was measured.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct CalibrationRecord {
    /// `rx`.
    pub mode: String,
    /// The calibration header as the plan named it (absolute).
    pub path: PathBuf,
    /// The header's copy, relative to the run folder.
    pub copy: PathBuf,
    /// The table's copy (`.npy`), relative to the run folder.
    pub table_copy: PathBuf,
    /// SHA-256 of the header (which holds its table's SHA-256), as every step records it.
    pub sha256: String,
    /// When the calibration was measured (RFC 3339).
    pub measured_at: String,
}

/// `*IDN?` of every instrument.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Instruments {
    pub awg: String,
    pub scope: String,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub tx: Option<String>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub rx: Option<String>,
}

impl From<&Identities> for Instruments {
    fn from(i: &Identities) -> Self {
        Self {
            awg: i.awg.clone(),
            scope: i.scope.clone(),
            tx: i.tx.clone(),
            rx: i.rx.clone(),
        }
    }
}

/// One process working on the run: the first run, or a resume.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Session {
    /// `run` or `resume`.
    pub kind: String,
    pub started: String,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub ended: Option<String>,
    /// The I/O journal of this session, relative to the run folder (or absolute).
    pub journal: PathBuf,
    /// Steps skipped because their files were intact (resume).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub skipped: Vec<usize>,
    /// Steps measured again, and why (a resume found their files changed or missing).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub remeasured: Vec<String>,
    /// `--force`: what differed and was accepted.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub forced: Option<String>,
    /// The safe-state sequence run on the bench at the end of the session (step by step).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub final_safe_state: Option<String>,
    #[serde(default)]
    pub timing: Timing,
}

/// Where a session's time went, seconds.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct Timing {
    /// Generating the waveforms and building every pipeline, once (what a single capture does
    /// too).
    #[serde(default)]
    pub prepare_s: f64,
    /// Connecting, positioning, uploading and capturing.
    pub bench_s: f64,
    /// Processing with every algorithm, on the step's worker thread while the next step is
    /// captured.
    pub processing_s: f64,
    /// Writing the steps' capture and profile files (as `radbench capture` writes them), on the
    /// step's worker thread after the processing.
    pub files_s: f64,
    /// The campaign's own work: the run folder, hashing, manifest, results, report (the per-step
    /// part beside the files, while the next step is measured).
    pub overhead_s: f64,
    /// How long the steps waited for the worker: the part of `processing_s`, `files_s` and
    /// `overhead_s` the next step's capture did not hide.
    #[serde(default)]
    pub wait_s: f64,
    /// The session from start to end.
    #[serde(default)]
    pub total_s: f64,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum StepStatus {
    Pending,
    Done,
}

/// Step tables already serialised by [`Manifest::store_cached`], by step index.
#[derive(Debug, Default)]
pub struct StepTables(std::collections::HashMap<usize, (StepRecord, String)>);

/// One step's state.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct StepRecord {
    pub index: usize,
    pub status: StepStatus,
    /// The step's folder, relative to the run folder.
    pub dir: PathBuf,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub measured_at: Option<String>,
    /// What each instrument reported applying (AWG, segment, scope, Tx, Rx).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub applied: Option<toml::Value>,
    /// Every file of the step, relative to the run folder.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub files: Vec<FileRecord>,
}

/// A file and its SHA-256.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct FileRecord {
    pub path: PathBuf,
    pub bytes: u64,
    pub sha256: String,
}

impl FileRecord {
    /// Hashes `dir/path`.
    pub fn of(dir: &Path, path: &Path) -> Result<FileRecord, CampaignError> {
        let (bytes, sha256) = sha256_file(&dir.join(path))?;
        Ok(FileRecord {
            path: path.to_path_buf(),
            bytes,
            sha256,
        })
    }

    /// Why the file no longer matches, if it does not.
    pub fn check(&self, dir: &Path) -> Option<String> {
        match sha256_file(&dir.join(&self.path)) {
            Err(_) => Some(format!("{} is missing or unreadable", self.path.display())),
            Ok((_, h)) if h != self.sha256 => Some(format!(
                "{} changed since it was written (SHA-256 differs)",
                self.path.display()
            )),
            Ok(_) => None,
        }
    }
}

/// Length and SHA-256 (lower-case hex) of a file.
pub(crate) fn sha256_file(path: &Path) -> Result<(u64, String), CampaignError> {
    let mut f = std::fs::File::open(path).map_err(io(path))?;
    let mut hasher = Sha256::new();
    let mut buf = vec![0u8; 1 << 20];
    let mut total = 0u64;
    loop {
        let n = f.read(&mut buf).map_err(io(path))?;
        if n == 0 {
            break;
        }
        total += n as u64;
        hasher.update(&buf[..n]);
    }
    Ok((total, hex(&hasher.finalize())))
}

/// SHA-256 of bytes (lower-case hex).
pub(crate) fn sha256_bytes(bytes: &[u8]) -> String {
    hex(&Sha256::digest(bytes))
}

fn hex(bytes: &[u8]) -> String {
    bytes.iter().map(|b| format!("{b:02x}")).collect()
}

/// The git commit radbench was built from, when the build knew it.
pub(crate) fn git_commit() -> Option<String> {
    option_env!("RADBENCH_GIT_COMMIT")
        .filter(|s| !s.is_empty())
        .map(String::from)
}

/// A JSON value as TOML (nulls dropped: TOML has none).
pub(crate) fn json_to_toml(v: &serde_json::Value) -> Option<toml::Value> {
    use serde_json::Value as J;
    Some(match v {
        J::Null => return None,
        J::Bool(b) => toml::Value::Boolean(*b),
        J::Number(n) => match n.as_i64() {
            Some(i) => toml::Value::Integer(i),
            None => toml::Value::Float(n.as_f64()?),
        },
        J::String(s) => toml::Value::String(s.clone()),
        J::Array(a) => toml::Value::Array(a.iter().filter_map(json_to_toml).collect()),
        J::Object(o) => toml::Value::Table(
            o.iter()
                .filter_map(|(k, v)| Some((k.clone(), json_to_toml(v)?)))
                .collect(),
        ),
    })
}

impl Manifest {
    /// Reads `dir/manifest.toml`.
    pub fn load(dir: &Path) -> Result<Manifest, CampaignError> {
        let path = dir.join(MANIFEST_FILE);
        let text = std::fs::read_to_string(&path).map_err(|e| CampaignError::Manifest {
            path: path.clone(),
            message: format!(
                "cannot read it ({e}): RUN_DIR must be a folder `radbench campaign run` wrote"
            ),
        })?;
        let manifest: Manifest = toml::from_str(&text).map_err(|e| CampaignError::Manifest {
            path: path.clone(),
            message: format!(
                "not a campaign manifest this radbench ({}) reads: {}",
                env!("CARGO_PKG_VERSION"),
                e.message()
            ),
        })?;
        if manifest.format != FORMAT {
            return Err(CampaignError::Manifest {
                path,
                message: format!(
                    "manifest format {} (this radbench writes and reads format {FORMAT})",
                    manifest.format
                ),
            });
        }
        Ok(manifest)
    }

    /// Writes `dir/manifest.toml` atomically and makes it durable with its folder.
    pub fn store(&mut self, dir: &Path) -> Result<(), CampaignError> {
        self.updated = crate::time::rfc3339_millis(std::time::SystemTime::now());
        let text = toml::to_string(self).map_err(|e| CampaignError::Manifest {
            path: dir.join(MANIFEST_FILE),
            message: format!("cannot be written: {e} (a radbench bug, please report it)"),
        })?;
        // write_atomic makes the file and its folder entry durable (fsync of both).
        write_atomic(&dir.join(MANIFEST_FILE), text.as_bytes())?;
        Ok(())
    }

    /// [`store`](Self::store), serialising only the steps whose record changed since the last
    /// call with the same `cache` (a finished step's table is kept as text): a run of N steps
    /// writes its manifest N times, and each would otherwise serialise every step again.
    pub fn store_cached(
        &mut self,
        dir: &Path,
        cache: &mut StepTables,
    ) -> Result<(), CampaignError> {
        self.updated = crate::time::rfc3339_millis(std::time::SystemTime::now());
        let unwritable = |e: toml::ser::Error| CampaignError::Manifest {
            path: dir.join(MANIFEST_FILE),
            message: format!("cannot be written: {e} (a radbench bug, please report it)"),
        };
        let steps = std::mem::take(&mut self.steps);
        let head = toml::to_string(self);
        self.steps = steps;
        let mut text = head.map_err(unwritable)?;
        for step in &self.steps {
            match cache.0.get(&step.index) {
                Some((record, table)) if record == step => text.push_str(table),
                _ => {
                    #[derive(Serialize)]
                    struct One<'a> {
                        steps: [&'a StepRecord; 1],
                    }
                    let table = toml::to_string(&One { steps: [step] }).map_err(unwritable)?;
                    text.push('\n');
                    text.push_str(&table);
                    cache
                        .0
                        .insert(step.index, (step.clone(), format!("\n{table}")));
                }
            }
        }
        write_atomic(&dir.join(MANIFEST_FILE), text.as_bytes())?;
        Ok(())
    }

    /// The record of step `index` (1-based).
    pub(crate) fn step_mut(&mut self, index: usize) -> &mut StepRecord {
        &mut self.steps[index - 1]
    }

    /// The current session.
    pub(crate) fn session_mut(&mut self) -> &mut Session {
        self.sessions.last_mut().expect("a session is open")
    }

    /// Replaces or adds a run-level file record.
    pub(crate) fn set_file(&mut self, record: FileRecord) {
        match self.files.iter_mut().find(|f| f.path == record.path) {
            Some(f) => *f = record,
            None => self.files.push(record),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn json_nulls_are_dropped_and_numbers_kept() {
        let v = serde_json::json!({"a": 1, "b": null, "c": [1.5, null], "d": {"e": "x"}});
        let t = json_to_toml(&v).unwrap();
        assert_eq!(
            toml::to_string(&t).unwrap(),
            "a = 1\nc = [1.5]\n\n[d]\ne = \"x\"\n"
        );
    }

    #[test]
    fn a_changed_file_is_noticed() {
        let dir = tempfile::tempdir().unwrap();
        std::fs::write(dir.path().join("a"), b"one").unwrap();
        let rec = FileRecord::of(dir.path(), Path::new("a")).unwrap();
        assert_eq!(rec.bytes, 3);
        assert_eq!(rec.check(dir.path()), None);
        std::fs::write(dir.path().join("a"), b"two").unwrap();
        assert!(rec.check(dir.path()).unwrap().contains("SHA-256"));
        std::fs::remove_file(dir.path().join("a")).unwrap();
        assert!(rec.check(dir.path()).unwrap().contains("missing"));
    }
}
