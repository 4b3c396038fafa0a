//! Telling someone: a program run when a run ends (complete, failed or stopped), with the run
//! folder, the status and a one-line summary in its environment. Bounded (its process group is
//! killed past the bound), logged (`notify.log` in the run folder, and standard error), and
//! never the run's failure: whatever it does, the run's exit code stays.

use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

/// The longest a notify program may run by default, seconds.
pub const DEFAULT_NOTIFY_TIMEOUT_S: f64 = 30.0;

/// Who to tell, and how long they may take.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct NotifyPlan {
    /// The program and its arguments (empty: only the bound is given, for `--notify`).
    pub command: Vec<String>,
    /// The folder it runs in (the spec's, for `[run] notify`); `None`: the current one.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub workdir: Option<PathBuf>,
    pub timeout_s: f64,
}

/// The file of the run folder each notification is logged in.
pub(crate) const NOTIFY_LOG: &str = "notify.log";

/// Runs the notify program for the run in `dir`; returns the line logged.
pub async fn notify(n: &NotifyPlan, dir: &Path, status: &str, summary: &str) -> String {
    let t = Instant::now();
    let outcome = run(n, dir, status, summary).await;
    let line = format!(
        "notify: {:?} ({status}): {outcome} after {:.1} s",
        n.command,
        t.elapsed().as_secs_f64()
    );
    log(dir, &line);
    line
}

async fn run(n: &NotifyPlan, dir: &Path, status: &str, summary: &str) -> String {
    let Some((program, args)) = n.command.split_first() else {
        return "no program given".into();
    };
    let mut cmd = tokio::process::Command::new(program);
    cmd.args(args)
        .env("RADBENCH_RUN_DIR", dir)
        .env("RADBENCH_STATUS", status)
        .env("RADBENCH_SUMMARY", summary)
        .stdin(std::process::Stdio::null())
        .stdout(std::process::Stdio::null())
        .stderr(std::process::Stdio::null())
        .kill_on_drop(true);
    if let Some(w) = &n.workdir {
        cmd.current_dir(w);
    }
    // A group of its own: past the bound, the program and whatever it started go together.
    #[cfg(unix)]
    cmd.process_group(0);
    let mut child = match cmd.spawn() {
        Ok(c) => c,
        Err(e) => return format!("could not start: {e}"),
    };
    let bound = Duration::from_secs_f64(n.timeout_s.clamp(0.0, 3600.0));
    match tokio::time::timeout(bound, child.wait()).await {
        Ok(Ok(s)) if s.success() => "delivered (exit 0)".into(),
        Ok(Ok(s)) => format!("the program failed ({s})"),
        Ok(Err(e)) => format!("could not wait for it: {e}"),
        Err(_) => {
            kill_group(&child);
            let _ = tokio::time::timeout(Duration::from_secs(5), child.wait()).await;
            format!("killed after its bound of {} s", n.timeout_s)
        }
    }
}

#[cfg(unix)]
fn kill_group(child: &tokio::process::Child) {
    if let Some(pid) = child.id().and_then(|p| i32::try_from(p).ok()) {
        // SAFETY: signalling a process group this process created; no memory is touched.
        unsafe {
            libc::kill(-pid, libc::SIGKILL);
        }
    }
}

#[cfg(not(unix))]
fn kill_group(_: &tokio::process::Child) {}

/// Appends `line` to the run folder's notify log (a folder gone or read-only: standard error
/// has it still).
fn log(dir: &Path, line: &str) {
    use std::io::Write as _;
    let stamp = crate::time::rfc3339_millis(std::time::SystemTime::now());
    let _ = std::fs::OpenOptions::new()
        .append(true)
        .create(true)
        .open(dir.join(NOTIFY_LOG))
        .and_then(|mut f| writeln!(f, "{stamp} {line}"));
}
