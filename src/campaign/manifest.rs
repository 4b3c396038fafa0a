//! `manifest.toml`: everything needed to trust, reproduce and resume a run. The inputs (spec and
//! bench file, copied into the run folder, with their SHA-256), the resolved plan, radbench's
//! version and git commit, the instruments' identities, each step's state, what the instruments
//! reported applying and every file written with its SHA-256, the sessions (first run, resumes)
//! and the status: `running` while a process works on it, then `complete` or `interrupted` with
//! the reason and the step where it stopped (never left at `running` after a stop: see below).
//!
//! It is rewritten atomically after each step and fsynced with its folder (`write_atomic` syncs
//! both).
//!
//! A status that never lies: the file opens with its status room, the first [`STATUS_ROOM`]
//! bytes (one disk sector), holding `format`, `status`, `reason`, `stopped_at_step` and
//! `exit_code`, padded with a comment line. When the session's end cannot be written atomically
//! (a full disk: the new file needs blocks the disk no longer has), the runner rewrites that room
//! in place ([`Manifest::store_status_in_place`]): the same bytes of the same file, blocks it
//! already owns, so `interrupted` and the reason reach the disk whatever the space left. Where
//! even that is impossible (a read-only file system, a crash, SIGKILL, a power loss), a reader
//! is not fooled either: [`Manifest::load`] reports a `running` manifest whose folder lock no
//! process holds as `interrupted` (see [`STALE_REASON`]).

use super::error::{io, CampaignError};
use super::plan::Plan;
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

/// The manifest's step journal in a run folder: while a session runs, one JSON line per step
/// recorded since the session stored `manifest.toml` whole (see [`JournalLine`]). Gone once the
/// session's end is stored whole; readers merge what is left ([`Manifest::load`]).
pub const STEPS_JOURNAL: &str = "manifest-steps.jsonl";

/// Bytes at the start of `manifest.toml` that hold the status and are rewritten in place when
/// the whole file cannot be (one 512-byte sector: a device writes it whole or not at all).
pub(crate) const STATUS_ROOM: usize = 512;

/// The reason [`Manifest::load`] gives a `running` manifest that no process works on.
pub(crate) const STALE_REASON: &str =
    "the process that ran it stopped without recording its end (a \
     crash, SIGKILL, a power loss, or a file system that refused the last write): no process \
     holds the run folder's lock";

/// The comment that pads the status room.
const ROOM_PAD: &str = "# status room, rewritten in place when this file cannot be replaced";

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
    /// Who ran it: the spec's `[run] operator`, else `$USER` or `$LOGNAME` at the start, else
    /// `unknown` (absent in runs from before it).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub operator: Option<String>,
    /// `*IDN?` of each instrument at the first connection.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub instruments: Option<Instruments>,
    /// A simulated bench of a bench file: the scene read from it at the start (every step sets
    /// it again with its own seed, targets and SNR).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub base_scene: Option<crate::measure::bench::scene_control::Scene>,
    pub plan: Plan,
    pub sessions: Vec<Session>,
    /// Never empty in a stored manifest (a plan has steps); skipped when empty so that
    /// [`ManifestStore`](super::ManifestStore) can append the steps' tables itself.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub steps: Vec<StepRecord>,
    /// The run's own files (results, report, journals), hashed when last written.
    pub files: Vec<FileRecord>,
    /// Every retry of a step after a transient fault, in order (`[run] retries`).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub retries: Vec<super::retry::RetryRecord>,
}

/// One line of the step journal ([`STEPS_JOURNAL`]): a step recorded done by session
/// `session` (1-based, as `sessions` counts them), with the retries met since the line before
/// and the session's timing and `updated` at that moment. A reader merges a line into
/// `manifest.toml` only when the file's last session is `session` and has not ended (else the
/// file already holds it: a journal its session's end did not get to remove).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct JournalLine {
    pub session: usize,
    pub updated: String,
    pub step: StepRecord,
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub retries: Vec<super::retry::RetryRecord>,
    pub timing: Timing,
}

impl JournalLine {
    /// The complete, well-formed lines at the start of `text`, each with the offset just past
    /// it. A line without its newline (a write cut short by a crash or a full disk), one that
    /// does not parse, or a step the plan does not have ends the journal there: what follows is
    /// not trusted (a step not recorded is measured again by a resume).
    pub(crate) fn parse_all(text: &[u8], steps: usize) -> Vec<(JournalLine, u64)> {
        let mut lines = Vec::new();
        let mut at = 0usize;
        while let Some(end) = text[at..].iter().position(|&b| b == b'\n') {
            let Ok(line) = serde_json::from_slice::<JournalLine>(&text[at..at + end]) else {
                break;
            };
            if !(1..=steps).contains(&line.step.index) || line.step.status != StepStatus::Done {
                break;
            }
            at += end + 1;
            lines.push((line, at as u64));
        }
        lines
    }

    /// Applies this line to `m` (see the type's docs); `false` when it does not belong to `m`'s
    /// last session or that session has ended.
    pub(crate) fn apply(self, m: &mut Manifest) -> bool {
        let open = m.sessions.len() == self.session
            && m.sessions.last().is_some_and(|s| s.ended.is_none());
        if !open {
            return false;
        }
        let index = self.step.index;
        m.steps[index - 1] = self.step;
        for r in self.retries {
            if !m.retries.contains(&r) {
                m.retries.push(r);
            }
        }
        m.updated = self.updated;
        m.session_mut().timing = self.timing;
        true
    }
}

/// Who runs a campaign: `planned` (the spec's `[run] operator`), else the environment's
/// `$USER` or `$LOGNAME`, else `unknown`.
pub(crate) fn operator(planned: Option<&str>) -> String {
    planned
        .map(str::to_owned)
        .or_else(|| {
            ["USER", "LOGNAME"]
                .iter()
                .filter_map(|k| std::env::var(k).ok())
                .find(|v| !v.trim().is_empty())
        })
        .unwrap_or_else(|| "unknown".into())
}

/// The fields of the status room, in the manifest's order (serialised as the manifest
/// serialises them, so the manifest's text starts with this one's).
#[derive(Serialize)]
struct Head<'a> {
    format: u32,
    status: Status,
    #[serde(skip_serializing_if = "Option::is_none")]
    reason: Option<&'a str>,
    #[serde(skip_serializing_if = "Option::is_none")]
    stopped_at_step: Option<usize>,
    #[serde(skip_serializing_if = "Option::is_none")]
    exit_code: Option<i32>,
}

impl<'a> Head<'a> {
    fn of(m: &'a Manifest) -> Head<'a> {
        Head {
            format: m.format,
            status: m.status,
            reason: m.reason.as_deref(),
            stopped_at_step: m.stopped_at_step,
            exit_code: m.exit_code,
        }
    }

    /// The status room's bytes: this head, its reason shortened when it does not fit, padded
    /// to [`STATUS_ROOM`] bytes.
    fn room(&self) -> Result<String, toml::ser::Error> {
        let mut reason = self.reason.map(str::to_owned);
        loop {
            let head = Head {
                reason: reason.as_deref(),
                ..*self
            };
            let text = toml::to_string(&head)?;
            // The pad: at least "#\n".
            let free = STATUS_ROOM as isize - text.len() as isize - 2;
            if free >= 0 {
                let free = free as usize;
                let pad = &ROOM_PAD[..ROOM_PAD.len().min(free + 1)];
                let spaces = " ".repeat(STATUS_ROOM - text.len() - pad.len() - 1);
                return Ok(format!("{text}{pad}{spaces}\n"));
            }
            // Too long: cut the reason (escaping may take more bytes, hence the loop).
            let Some(r) = reason.as_mut() else {
                unreachable!("a head without a reason fits the status room");
            };
            let mut keep = r.len().saturating_sub(free.unsigned_abs() + 3);
            while !r.is_char_boundary(keep) {
                keep -= 1;
            }
            r.truncate(keep);
            r.push('…');
        }
    }
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
    /// `rx`, `tx` or `both`.
    pub mode: crate::measure::CorrectionMode,
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

impl StepRecord {
    /// The record without what the instruments applied and its files: what the runner keeps of
    /// a step once its table is in the manifest file ([`ManifestStore`](super::ManifestStore)).
    pub(crate) fn status_only(&self) -> StepRecord {
        StepRecord {
            index: self.index,
            status: self.status,
            dir: self.dir.clone(),
            measured_at: self.measured_at.clone(),
            applied: None,
            files: Vec::new(),
        }
    }
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

/// A manifest the serialiser refused (a radbench bug).
fn unwritable(dir: &Path, e: toml::ser::Error) -> CampaignError {
    CampaignError::Manifest {
        path: dir.join(MANIFEST_FILE),
        message: format!("cannot be written: {e} (a radbench bug, please report it)"),
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
        let mut manifest: Manifest =
            toml::from_str(&text).map_err(|e| CampaignError::Manifest {
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
        manifest.merge_steps_journal(dir)?;
        if manifest.status == Status::Running && !super::folder::lock_is_held(dir) {
            manifest.status = Status::Interrupted;
            manifest.reason.get_or_insert_with(|| STALE_REASON.into());
        }
        Ok(manifest)
    }

    /// Merges `dir`'s step journal ([`STEPS_JOURNAL`]), when there is one, into this manifest
    /// read from `dir/manifest.toml`: the steps recorded since the file was stored whole.
    fn merge_steps_journal(&mut self, dir: &Path) -> Result<(), CampaignError> {
        let path = dir.join(STEPS_JOURNAL);
        let text = match std::fs::read(&path) {
            Ok(t) => t,
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(()),
            Err(e) => {
                return Err(CampaignError::Manifest {
                    path,
                    message: format!("cannot read it ({e})"),
                })
            }
        };
        if self.steps.len() != self.plan.steps.len() {
            return Ok(());
        }
        for (line, _) in JournalLine::parse_all(&text, self.steps.len()) {
            if !line.apply(self) {
                break;
            }
        }
        Ok(())
    }

    /// The manifest's text: the status room, then the rest as `text` (the whole manifest
    /// serialised) has it.
    fn laid_out(&self, text: String) -> Result<String, toml::ser::Error> {
        let head = Head::of(self);
        let serialised = toml::to_string(&head)?;
        let Some(body) = text.strip_prefix(&serialised) else {
            // The serialiser wrote the head's fields otherwise than alone: no room, no harm
            // (only the in-place rewrite is then refused).
            debug_assert!(false, "the manifest does not start with its head");
            return Ok(text);
        };
        let mut out = head.room()?;
        out.push_str(body);
        Ok(out)
    }

    /// Rewrites the status room of `dir/manifest.toml` in place with this manifest's status,
    /// reason, step and exit code (the rest of the file stays as last stored). For a session's
    /// end that could not be stored whole: it needs no new block on the disk. Refused when the
    /// file on disk has no status room (written by an older radbench).
    pub(crate) fn store_status_in_place(&self, dir: &Path) -> Result<(), CampaignError> {
        use std::os::unix::fs::FileExt;
        let path = dir.join(MANIFEST_FILE);
        let room = Head::of(self).room().map_err(|e| CampaignError::Manifest {
            path: path.clone(),
            message: format!("cannot be written: {e} (a radbench bug, please report it)"),
        })?;
        let file = std::fs::OpenOptions::new()
            .read(true)
            .write(true)
            .open(&path)
            .map_err(io(&path))?;
        let mut old = vec![0u8; STATUS_ROOM + 32];
        let mut got = 0;
        while got < old.len() {
            match file
                .read_at(&mut old[got..], got as u64)
                .map_err(io(&path))?
            {
                0 => break,
                n => got += n,
            }
        }
        let has_room = got > STATUS_ROOM
            && old[STATUS_ROOM - 1] == b'\n'
            && old[..STATUS_ROOM].windows(2).any(|w| w == b"\n#")
            && old[STATUS_ROOM..got].starts_with(b"radbench_version = ");
        if !has_room {
            return Err(CampaignError::Manifest {
                path,
                message: "has no status room to record the run's end in (written by an older \
                          radbench)"
                    .into(),
            });
        }
        file.write_all_at(room.as_bytes(), 0).map_err(io(&path))?;
        file.sync_all().map_err(io(&path))?;
        Ok(())
    }

    /// Writes `dir/manifest.toml` atomically and makes it durable with its folder, then removes
    /// the step journal (this manifest holds its steps: it was merged on loading).
    pub fn store(&mut self, dir: &Path) -> Result<(), CampaignError> {
        self.updated = crate::time::rfc3339_millis(std::time::SystemTime::now());
        let text = toml::to_string(self)
            .and_then(|text| self.laid_out(text))
            .map_err(|e| unwritable(dir, e))?;
        // write_atomic makes the file and its folder entry durable (fsync of both).
        write_atomic(&dir.join(MANIFEST_FILE), text.as_bytes())?;
        // Every step is in the file now (the journal's were merged when it was loaded).
        remove_journal(dir)
    }

    /// The manifest's text without its steps (the status room, then every other field), with
    /// `updated` set to now: what [`ManifestStore`](super::ManifestStore) writes before the
    /// step tables.
    pub(crate) fn head_text(&mut self, dir: &Path) -> Result<String, CampaignError> {
        self.updated = crate::time::rfc3339_millis(std::time::SystemTime::now());
        let steps = std::mem::take(&mut self.steps);
        let head = toml::to_string(self);
        self.steps = steps;
        head.and_then(|h| self.laid_out(h))
            .map_err(|e| unwritable(dir, e))
    }

    /// One step's table as the manifest holds it (a blank line, then `[[steps]]`).
    pub(crate) fn step_table(step: &StepRecord, dir: &Path) -> Result<String, CampaignError> {
        #[derive(Serialize)]
        struct One<'a> {
            steps: [&'a StepRecord; 1],
        }
        let table = toml::to_string(&One { steps: [step] }).map_err(|e| unwritable(dir, e))?;
        Ok(format!("\n{table}"))
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

/// Removes `dir`'s step journal, if any, durably (`manifest.toml` holds its steps now).
pub(crate) fn remove_journal(dir: &Path) -> Result<(), CampaignError> {
    let path = dir.join(STEPS_JOURNAL);
    match std::fs::remove_file(&path) {
        Ok(()) => std::fs::File::open(dir)
            .and_then(|folder| folder.sync_all())
            .map_err(io(dir)),
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => Ok(()),
        Err(e) => Err(io(&path)(e)),
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

    fn manifest() -> Manifest {
        use crate::campaign::plan::{plan, BenchInfo};
        use crate::campaign::spec::SpecFile;
        let spec = SpecFile::parse(
            "[sweep]\nparameter = \"position\"\nvalues = [1.0, 0.9]\n",
            Path::new("t.toml"),
        )
        .unwrap();
        let bench = BenchInfo::load(&spec, None).unwrap();
        let plan = plan(&spec, &bench).unwrap();
        let file = InputFile {
            path: "t.toml".into(),
            copy: "spec.toml".into(),
            sha256: "00".into(),
        };
        Manifest {
            format: FORMAT,
            status: Status::Running,
            reason: None,
            stopped_at_step: None,
            exit_code: None,
            radbench_version: "0".into(),
            git_commit: None,
            created: "c".into(),
            updated: "u".into(),
            spec: file,
            bench_file: None,
            bench_catalog: Vec::new(),
            calibration: None,
            operator: None,
            instruments: None,
            base_scene: None,
            steps: plan
                .steps
                .iter()
                .map(|s| StepRecord {
                    index: s.index,
                    status: StepStatus::Pending,
                    dir: s.dir_name().into(),
                    measured_at: None,
                    applied: None,
                    files: Vec::new(),
                })
                .collect(),
            plan,
            sessions: Vec::new(),
            files: Vec::new(),
            retries: Vec::new(),
        }
    }

    /// Holds the folder's lock as a run does, so that `load` reads `running` as it is.
    fn locked(dir: &Path) -> crate::campaign::folder::Lock {
        crate::campaign::folder::lock(dir).unwrap()
    }

    #[test]
    fn the_manifest_starts_with_its_status_room() {
        let dir = tempfile::tempdir().unwrap();
        let _lock = locked(dir.path());
        let mut m = manifest();
        m.store(dir.path()).unwrap();
        let text = std::fs::read_to_string(dir.path().join(MANIFEST_FILE)).unwrap();
        assert!(
            text.starts_with("format = 1\nstatus = \"running\"\n"),
            "{text}"
        );
        assert_eq!(&text[STATUS_ROOM - 1..STATUS_ROOM], "\n");
        assert!(
            text[STATUS_ROOM..].starts_with("radbench_version = "),
            "{text}"
        );
        let back = Manifest::load(dir.path()).unwrap();
        m.updated = back.updated.clone();
        assert_eq!(back, m);
        // The step-by-step writer lays it out the same, a recorded step's table replaced.
        let mut store = super::super::ManifestStore::default();
        store.store_whole(&mut m, dir.path()).unwrap();
        let cached = std::fs::read_to_string(dir.path().join(MANIFEST_FILE)).unwrap();
        assert!(cached[STATUS_ROOM..].starts_with("radbench_version = "));
        assert_eq!(Manifest::load(dir.path()).unwrap().steps, m.steps);
        m.sessions.push(session());
        store.store_whole(&mut m, dir.path()).unwrap();
        let changed = done_step(&m, 1);
        store
            .record_step(&line(&m, changed.clone()), dir.path())
            .unwrap();
        let mut head = Manifest {
            steps: Vec::new(),
            ..m.clone()
        };
        store.store(&mut head, dir.path()).unwrap();
        assert!(!dir.path().join(STEPS_JOURNAL).exists());
        let back = Manifest::load(dir.path()).unwrap();
        assert_eq!(back.steps[0], changed);
        assert_eq!(back.steps[1..], m.steps[1..]);
    }

    fn session() -> Session {
        Session {
            kind: "run".into(),
            started: "s".into(),
            ended: None,
            journal: "io-journal.jsonl".into(),
            skipped: Vec::new(),
            remeasured: Vec::new(),
            forced: None,
            final_safe_state: None,
            timing: Timing::default(),
        }
    }

    /// Step `index` of `m` done, with what the instruments applied and a file.
    fn done_step(m: &Manifest, index: usize) -> StepRecord {
        let mut applied = toml::map::Map::new();
        applied.insert("sample_rate_hz".into(), toml::Value::Float(8e10));
        applied.insert("points".into(), toml::Value::Integer(800_000));
        applied.insert("volts".into(), toml::Value::Float(1.0));
        StepRecord {
            status: StepStatus::Done,
            measured_at: Some(format!("2026-12-06T00:00:0{index}.000Z")),
            applied: Some(toml::Value::Table(applied)),
            files: vec![FileRecord {
                path: format!("step-00{index}/result.json").into(),
                bytes: 10,
                sha256: "ab".repeat(32),
            }],
            ..m.steps[index - 1].clone()
        }
    }

    fn line(m: &Manifest, step: StepRecord) -> JournalLine {
        JournalLine {
            session: m.sessions.len(),
            updated: format!("u{}", step.index),
            step,
            retries: Vec::new(),
            timing: Timing {
                bench_s: 1.5,
                ..Timing::default()
            },
        }
    }

    #[test]
    fn steps_are_appended_to_the_journal_and_read_back_merged() {
        let dir = tempfile::tempdir().unwrap();
        let _lock = locked(dir.path());
        let mut m = manifest();
        m.sessions.push(session());
        let mut store = super::super::ManifestStore::default();
        store.store_whole(&mut m, dir.path()).unwrap();
        let file = std::fs::read(dir.path().join(MANIFEST_FILE)).unwrap();
        // A step recorded: the manifest is not rewritten, a line is appended.
        let one = done_step(&m, 1);
        let mut first = line(&m, one.clone());
        first.retries.push(super::super::RetryRecord {
            step: 1,
            attempt: 1,
            instrument: "awg".into(),
            fault: "connection closed".into(),
            at: "t".into(),
            safe_state: "done".into(),
            wait_s: 0.5,
        });
        store.record_step(&first, dir.path()).unwrap();
        assert_eq!(std::fs::read(dir.path().join(MANIFEST_FILE)).unwrap(), file);
        let journal = std::fs::read_to_string(dir.path().join(STEPS_JOURNAL)).unwrap();
        assert_eq!(journal.lines().count(), 1);
        let back = Manifest::load(dir.path()).unwrap();
        assert_eq!(back.steps[0], one);
        assert_eq!(back.steps[1], m.steps[1]);
        assert_eq!(back.retries, first.retries);
        assert_eq!(back.updated, "u1");
        assert_eq!(back.sessions[0].timing.bench_s, 1.5);
        // A second step, then a line cut short (a crash mid-append): the whole lines count.
        let two = done_step(&m, 2);
        store
            .record_step(&line(&m, two.clone()), dir.path())
            .unwrap();
        let path = dir.path().join(STEPS_JOURNAL);
        let whole = std::fs::read(&path).unwrap();
        let cut = whole.len() - 5;
        std::fs::write(&path, &whole[..cut]).unwrap();
        let back = Manifest::load(dir.path()).unwrap();
        assert_eq!(back.steps[0], one);
        assert_eq!(back.steps[1], m.steps[1], "a line cut short is not read");
        std::fs::write(&path, &whole).unwrap();
        assert_eq!(Manifest::load(dir.path()).unwrap().steps[1], two);
        // Stored whole at the end: the file holds both steps, the journal is gone, the retry
        // is there once.
        let mut head = back.clone();
        head.retries = first.retries.clone();
        head.steps = Vec::new();
        store.store(&mut head, dir.path()).unwrap();
        assert!(!path.exists());
        let back = Manifest::load(dir.path()).unwrap();
        assert_eq!(back.steps, vec![one.clone(), two.clone()]);
        assert_eq!(back.retries.len(), 1);
        // A journal its session's end did not get to remove is not applied again once the
        // session has ended (the file holds it), nor one of an earlier session.
        std::fs::write(&path, &whole).unwrap();
        let mut ended = back.clone();
        ended.session_mut().ended = Some("e".into());
        ended.steps[0].measured_at = Some("later".into());
        ended.store(dir.path()).unwrap();
        assert!(!path.exists(), "a whole store removes the journal");
        std::fs::write(&path, &whole).unwrap();
        assert_eq!(Manifest::load(dir.path()).unwrap().steps[0], ended.steps[0]);
        let mut resumed = ended.clone();
        resumed.sessions.push(session());
        std::fs::write(
            dir.path().join(MANIFEST_FILE),
            toml::to_string(&resumed).unwrap(),
        )
        .unwrap();
        assert_eq!(Manifest::load(dir.path()).unwrap().steps[0], ended.steps[0]);
    }

    #[test]
    fn a_step_the_plan_does_not_have_is_not_appended() {
        let dir = tempfile::tempdir().unwrap();
        let mut m = manifest();
        m.sessions.push(session());
        let mut store = super::super::ManifestStore::default();
        store.store_whole(&mut m, dir.path()).unwrap();
        store
            .record_step(&line(&m, done_step(&m, 1)), dir.path())
            .unwrap();
        let path = dir.path().join(STEPS_JOURNAL);
        let before = std::fs::read(&path).unwrap();
        // A step the plan does not have is refused before anything is written.
        let mut wrong = done_step(&m, 2);
        wrong.index = 9;
        assert!(store.record_step(&line(&m, wrong), dir.path()).is_err());
        assert_eq!(std::fs::read(&path).unwrap(), before);
    }

    #[test]
    fn the_status_is_rewritten_in_place_in_the_same_bytes() {
        let dir = tempfile::tempdir().unwrap();
        let _lock = locked(dir.path());
        let mut m = manifest();
        m.store(dir.path()).unwrap();
        let path = dir.path().join(MANIFEST_FILE);
        let before = std::fs::read(&path).unwrap();
        m.status = Status::Interrupted;
        m.reason = Some(format!(
            "step 2 of 2: {}",
            "a \"long\" reason é ".repeat(60)
        ));
        m.stopped_at_step = Some(2);
        m.exit_code = Some(4);
        m.store_status_in_place(dir.path()).unwrap();
        let after = std::fs::read(&path).unwrap();
        assert_eq!(after.len(), before.len());
        assert_eq!(after[STATUS_ROOM..], before[STATUS_ROOM..]);
        let back = Manifest::load(dir.path()).unwrap();
        assert_eq!(back.status, Status::Interrupted);
        assert_eq!(back.stopped_at_step, Some(2));
        assert_eq!(back.exit_code, Some(4));
        let reason = back.reason.unwrap();
        assert!(reason.starts_with("step 2 of 2: a \"long\"") && reason.ends_with('…'));
        assert_eq!(back.steps, m.steps);
    }

    #[test]
    fn a_manifest_without_a_status_room_is_not_patched() {
        let dir = tempfile::tempdir().unwrap();
        let m = manifest();
        let path = dir.path().join(MANIFEST_FILE);
        std::fs::write(&path, toml::to_string(&m).unwrap()).unwrap();
        let before = std::fs::read(&path).unwrap();
        let err = m.store_status_in_place(dir.path()).unwrap_err().to_string();
        assert!(err.contains("no status room"), "{err}");
        assert_eq!(std::fs::read(&path).unwrap(), before);
    }

    #[test]
    fn a_running_manifest_nobody_works_on_reads_as_interrupted() {
        let dir = tempfile::tempdir().unwrap();
        let mut m = manifest();
        {
            let _lock = locked(dir.path());
            m.store(dir.path()).unwrap();
            assert_eq!(Manifest::load(dir.path()).unwrap().status, Status::Running);
        }
        let back = Manifest::load(dir.path()).unwrap();
        assert_eq!(back.status, Status::Interrupted);
        assert_eq!(back.reason.as_deref(), Some(STALE_REASON));
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
