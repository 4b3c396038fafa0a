//! A campaign from a warm session (`Bench.campaign(spec).run()`): `radbench campaign run` and
//! `resume`, each step's result handed to the caller as it lands ([`CampaignEvents`]).

use crate::campaign::{self, BenchInfo, CampaignError, NewRun, Observer, SpecFile, StepDone};
use crate::driver::RfPermit;
use crate::exit::bad_input;
use crate::measure::Interrupt;
use serde_json::{json, Value};
use std::path::{Path, PathBuf};
use std::sync::mpsc;
use std::time::Duration;

/// A campaign spec: its file, or the spec as a JSON object (a Python dict; relative paths in it
/// are relative to the working folder).
#[derive(Debug, Clone)]
pub enum CampaignSpec {
    File(PathBuf),
    Json(String),
}

impl CampaignSpec {
    fn load(&self) -> anyhow::Result<SpecFile> {
        match self {
            CampaignSpec::File(path) => Ok(SpecFile::load(path)?),
            CampaignSpec::Json(text) => {
                let value: toml::Value = serde_json::from_str(text)
                    .map_err(|e| bad_input(format!("spec: not a campaign spec as a dict: {e}")))?;
                let text = toml::to_string(&value)
                    .map_err(|e| bad_input(format!("spec: cannot be written as TOML: {e}")))?;
                let path = std::env::current_dir()?.join("<spec given as a dict>.toml");
                Ok(SpecFile::parse(&text, &path)?)
            }
        }
    }
}

/// Longest wait for the caller to take a step (its callback), in slices of [`ACK_SLICE`].
const ACK_TIMEOUT: Duration = Duration::from_secs(600);
const ACK_SLICE: Duration = Duration::from_millis(20);

/// Where a campaign's events go: `events` gets `{"event": "start", "dir"}`, then each finished
/// step; with `acks`, the run waits after each step until the caller has taken it (one `()`:
/// its callback ran), so that a stop the callback asks for comes before the next step.
pub struct CampaignEvents {
    pub events: mpsc::Sender<Value>,
    pub acks: Option<mpsc::Receiver<()>>,
}

/// Hands every finished step to the caller; notes go to stderr, as the command prints them.
struct Forward {
    to: CampaignEvents,
    /// A stop ends the wait for the caller at once.
    interrupt: Interrupt,
}

impl Observer for Forward {
    fn step_done(&mut self, done: &StepDone<'_>) {
        let sent = self.to.events.send(json!({
            "index": done.step.index,
            "of": done.of,
            "dir": done.dir,
            "skipped": done.skipped,
            "result": done.result,
        }));
        let Some(acks) = self.to.acks.as_ref().filter(|_| sent.is_ok()) else {
            return;
        };
        let t = std::time::Instant::now();
        while self.interrupt.received().is_none() && t.elapsed() < ACK_TIMEOUT {
            match acks.recv_timeout(ACK_SLICE) {
                Ok(()) | Err(mpsc::RecvTimeoutError::Disconnected) => return,
                Err(mpsc::RecvTimeoutError::Timeout) => {}
            }
        }
    }

    fn note(&mut self, text: &str) {
        eprintln!("{text}");
    }
}

/// The run folder's name when none is given: `runs/<UTC time>-<campaign name>`, as the command.
fn default_out(name: &str) -> PathBuf {
    let name: String = name
        .chars()
        .take(64)
        .map(|c| {
            if c.is_ascii_alphanumeric() || "._-".contains(c) {
                c
            } else {
                '-'
            }
        })
        .collect();
    let stamp = crate::storage::utc_now_rfc3339()
        .replace([':', '-'], "")
        .replace('.', "_");
    PathBuf::from("runs").join(format!("{stamp}-{name}"))
}

/// How a run ended, for the caller: the run folder, or the error that stopped it (the manifest
/// says the same; the folder is resumable).
fn concluded(finished: campaign::Finished) -> anyhow::Result<PathBuf> {
    match finished.stopped {
        None => Ok(finished.dir),
        Some(stop) => Err(stop.into()),
    }
}

/// `radbench campaign run SPEC [--bench FILE] [--out DIR] [--retries N]`.
pub(super) async fn run(
    spec: CampaignSpec,
    bench_file: Option<&Path>,
    out: Option<PathBuf>,
    retries: Option<usize>,
    to: CampaignEvents,
    permit: RfPermit,
    interrupt: Interrupt,
) -> anyhow::Result<PathBuf> {
    let spec = spec.load()?;
    let bench = BenchInfo::load(&spec, bench_file)?;
    let mut plan = campaign::plan(&spec, &bench)?;
    if let Some(n) = retries {
        plan.retries = n;
    }
    let out = out.unwrap_or_else(|| default_out(&plan.name));
    let _ = to.events.send(json!({"event": "start", "dir": out}));
    let mut observer = Forward {
        to,
        interrupt: interrupt.clone(),
    };
    let finished = campaign::start(
        NewRun {
            spec,
            bench,
            plan,
            out,
            journal: None,
            permit,
            interrupt,
            input: None,
        },
        &mut observer,
    )
    .await?;
    concluded(finished)
}

/// `radbench campaign resume DIR`.
pub(super) async fn resume(
    dir: &Path,
    to: CampaignEvents,
    permit: RfPermit,
    interrupt: Interrupt,
) -> anyhow::Result<PathBuf> {
    let _ = to.events.send(json!({"event": "start", "dir": dir}));
    let mut observer = Forward {
        to,
        interrupt: interrupt.clone(),
    };
    let finished = campaign::resume(dir, permit, false, None, interrupt, None, &mut observer).await;
    match finished {
        Ok(f) => concluded(f),
        // Nothing left to measure: the run is what the caller wanted.
        Err(CampaignError::Complete { dir }) => Ok(dir),
        Err(e) => Err(e.into()),
    }
}
