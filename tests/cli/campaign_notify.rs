//! `[run] notify` and `--notify`: the program hears the run folder, the status and a one-line
//! summary when a run completes, fails or is stopped; one that hangs is killed at its bound; the
//! run's exit code never changes.

use std::path::Path;

use super::support::{radbench_in, LIMIT};

/// Writes what the notify program hears to `heard.txt` in the spec's folder.
const NOTIFY: &str = "[run]\nnotify = [\"sh\", \"-c\", \
    \"printf '%s|%s|%s' \\\"$RADBENCH_STATUS\\\" \\\"$RADBENCH_RUN_DIR\\\" \\\"$RADBENCH_SUMMARY\\\" > heard.txt\"]\n";

const SWEEP: &str = "[sweep]\nparameter = \"position\"\nvalues = [1.0, 0.97, 0.94]\n";

fn write(dir: &Path, name: &str, text: &str) -> std::path::PathBuf {
    let p = dir.join(name);
    std::fs::write(&p, text).unwrap();
    p
}

/// (status, run folder, summary) as the notify program heard them.
fn heard(dir: &Path) -> (String, String, String) {
    let text = std::fs::read_to_string(dir.join("heard.txt")).expect("the program was run");
    let mut parts = text.splitn(3, '|').map(str::to_string);
    (
        parts.next().unwrap(),
        parts.next().unwrap(),
        parts.next().unwrap(),
    )
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_complete_run_tells_its_status_folder_and_summary() {
    let dir = tempfile::tempdir().unwrap();
    let spec = write(dir.path(), "spec.toml", &format!("{NOTIFY}{SWEEP}"));
    let out = dir.path().join("run");
    let (code, _, err) = radbench_in(
        None,
        &[
            "campaign",
            "run",
            spec.to_str().unwrap(),
            "--out",
            out.to_str().unwrap(),
            "--allow-rf",
        ],
    )
    .await;
    assert_eq!(code, 0, "{err}");
    let (status, folder, summary) = heard(dir.path());
    assert_eq!(status, "complete");
    assert_eq!(Path::new(&folder), out);
    assert!(summary.contains("3 of 3 steps done"), "{summary}");
    let log = std::fs::read_to_string(out.join("notify.log")).unwrap();
    assert!(log.contains("delivered (exit 0)"), "{log}");
    assert!(err.contains("notify:"), "{err}");
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_failed_run_tells_failed_and_keeps_its_exit_code() {
    let dir = tempfile::tempdir().unwrap();
    let spec = write(
        dir.path(),
        "spec.toml",
        &format!(
            "{NOTIFY}[positioner]\nkind = \"command\"\nprogram = \"sh\"\n\
             args = [\"-c\", \"test {{step}} -lt 2\"]\n{SWEEP}"
        ),
    );
    let out = dir.path().join("run");
    let (code, _, err) = radbench_in(
        None,
        &[
            "campaign",
            "run",
            spec.to_str().unwrap(),
            "--out",
            out.to_str().unwrap(),
            "--allow-rf",
        ],
    )
    .await;
    // As without a notify program: the positioner's failure, exit 3.
    assert_eq!(code, 3, "{err}");
    let (status, _, summary) = heard(dir.path());
    assert_eq!(status, "failed");
    assert!(summary.contains("1 of 3 steps done"), "{summary}");
    assert!(summary.contains("positioner"), "{summary}");
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_stopped_run_tells_stopped() {
    let dir = tempfile::tempdir().unwrap();
    let spec = write(
        dir.path(),
        "spec.toml",
        &format!(
            "{NOTIFY}[sweep]\nparameter = \"position\"\nstart = 1.0\nstep = -0.01\ncount = 40\n"
        ),
    );
    let out = dir.path().join("run");
    let (mut child, mut lines) = super::support::campaign_at_step(&spec, &out, 2).await;
    super::support::signal(&child, "INT");
    let drain = async { while lines.next_line().await.unwrap().is_some() {} };
    tokio::time::timeout(LIMIT, drain)
        .await
        .expect("stdout ends");
    let status = tokio::time::timeout(LIMIT, child.wait())
        .await
        .expect("radbench stops")
        .unwrap();
    assert_eq!(status.code(), Some(130));
    let (status, folder, summary) = heard(dir.path());
    assert_eq!(status, "stopped");
    assert_eq!(Path::new(&folder), out);
    assert!(summary.contains("of 40 steps done"), "{summary}");
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_hanging_notify_program_is_killed_at_its_bound_and_the_exit_code_stays() {
    let dir = tempfile::tempdir().unwrap();
    let hang = write(
        dir.path(),
        "hang.sh",
        "#!/bin/sh\necho $$ > hang.pid\nsleep 300 &\necho $! > sleep.pid\nwait\n",
    );
    std::fs::set_permissions(&hang, std::os::unix::fs::PermissionsExt::from_mode(0o755)).unwrap();
    let spec = write(
        dir.path(),
        "spec.toml",
        &format!("[run]\nnotify_timeout_s = 1\n{SWEEP}"),
    );
    let out = dir.path().join("run");
    let (code, _, err) = radbench_in(
        Some(dir.path()),
        &[
            "campaign",
            "run",
            spec.to_str().unwrap(),
            "--out",
            out.to_str().unwrap(),
            "--allow-rf",
            "--notify",
            hang.to_str().unwrap(),
        ],
    )
    .await;
    assert_eq!(code, 0, "{err}");
    let log = std::fs::read_to_string(out.join("notify.log")).unwrap();
    assert!(log.contains("killed after its bound of 1 s"), "{log}");
    // The program and what it started are gone (the whole group was killed).
    let pid = std::fs::read_to_string(dir.path().join("sleep.pid")).unwrap();
    let alive = Path::new(&format!("/proc/{}", pid.trim())).exists()
        && !std::fs::read_to_string(format!("/proc/{}/stat", pid.trim()))
            .unwrap_or_default()
            .contains(") Z ");
    assert!(
        !alive,
        "the notify program's child {pid} outlived its bound"
    );
}
