//! Running the radbench binary from an async test: exit code, stdout and stderr, with a time
//! limit, and the child killed if the test gives up on it.

use std::path::Path;
use std::process::Stdio;
use std::time::Duration;
use tokio::process::Command;

const BIN: &str = env!("CARGO_BIN_EXE_radbench");

/// Longest any one radbench invocation may take in these tests.
pub const LIMIT: Duration = Duration::from_secs(120);

/// Runs radbench with `args` (in `dir` when given); (exit code, stdout, stderr).
pub async fn radbench_in(dir: Option<&Path>, args: &[&str]) -> (i32, String, String) {
    let mut command = Command::new(BIN);
    command
        .args(args)
        .stdin(Stdio::null())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .kill_on_drop(true);
    if let Some(dir) = dir {
        command.current_dir(dir);
    }
    let child = command.spawn().expect("radbench runs");
    let out = tokio::time::timeout(LIMIT, child.wait_with_output())
        .await
        .unwrap_or_else(|_| panic!("radbench {args:?} finishes within {LIMIT:?}"))
        .unwrap();
    (
        out.status.code().unwrap_or(-1),
        String::from_utf8_lossy(&out.stdout).into_owned(),
        String::from_utf8_lossy(&out.stderr).into_owned(),
    )
}

/// The thesis' waveform of `kind` as a capture request: seed 1, no payload, no background,
/// a 10 s wait for the trigger.
pub fn thesis_request(
    kind: radbench::waveform::WaveformKind,
    options: radbench::measure::ProcessOptions,
    tx_off: bool,
) -> radbench::measure::CaptureRequest {
    radbench::measure::CaptureRequest {
        waveform: kind.thesis_default(),
        payload: None,
        seed: 1,
        options,
        tx_off,
        wait_s: 10.0,
        background: None,
    }
}

/// Polls `cond` every 5 ms until it holds; fails the test after `limit`.
pub async fn until(what: &str, limit: Duration, cond: impl Fn() -> bool) {
    let poll = async {
        while !cond() {
            tokio::time::sleep(Duration::from_millis(5)).await;
        }
    };
    tokio::time::timeout(limit, poll)
        .await
        .unwrap_or_else(|_| panic!("{what} within {limit:?}"));
}

/// Sends signal `name` (`INT`, `TERM`, `HUP`) to `child` with kill(1).
pub fn signal(child: &tokio::process::Child, name: &str) {
    let pid = child.id().unwrap().to_string();
    let ok = std::process::Command::new("kill")
        .args([&format!("-{name}"), &pid])
        .status()
        .unwrap()
        .success();
    assert!(ok, "kill -{name}");
}

/// A mock lab on loopback with an empty scene, for the exit-path tests (bounded start).
pub async fn start_lab() -> mock_lab::lab::Lab {
    start_lab_with(mock_lab::scene::Scene::default()).await
}

/// A mock lab on loopback with `scene` (bounded start).
pub async fn start_lab_with(scene: mock_lab::scene::Scene) -> mock_lab::lab::Lab {
    tokio::time::timeout(
        Duration::from_secs(10),
        mock_lab::lab::start(mock_lab::lab::LabOptions {
            scene,
            ..mock_lab::lab::LabOptions::default()
        }),
    )
    .await
    .expect("lab starts")
    .expect("lab starts")
}

/// `lab`'s bench file (AWG over HiSLIP, scope over VICP) written to `dir/bench.toml`.
pub fn lab_bench_file(dir: &Path, lab: &mock_lab::lab::Lab) -> String {
    use mock_lab::server::launch::Transport;
    let path = dir.join("bench.toml");
    std::fs::write(&path, lab.bench_toml(Transport::Hislip, Transport::Vicp)).unwrap();
    path.display().to_string()
}

/// The `--json` lines a running radbench still has to print.
pub type JsonLines = tokio::io::Lines<tokio::io::BufReader<tokio::process::ChildStdout>>;

/// `radbench campaign run SPEC --allow-rf --json --out OUT` started and watched until step `step`
/// starts: the child (killed if the test gives up on it) and the lines it prints after that.
pub async fn campaign_at_step(
    spec: &Path,
    out: &Path,
    step: u64,
) -> (tokio::process::Child, JsonLines) {
    use tokio::io::AsyncBufReadExt;
    let mut child = Command::new(BIN)
        .args(["campaign", "run"])
        .arg(spec)
        .args(["--allow-rf", "--json", "--out"])
        .arg(out)
        .stdin(Stdio::null())
        .stdout(Stdio::piped())
        .stderr(Stdio::null())
        .kill_on_drop(true)
        .spawn()
        .unwrap();
    let mut lines = tokio::io::BufReader::new(child.stdout.take().unwrap()).lines();
    let started = async {
        while let Some(line) = lines.next_line().await.unwrap() {
            let v: serde_json::Value = serde_json::from_str(&line).unwrap();
            if v["event"] == "start" && v["index"] == step {
                return;
            }
        }
        panic!("the campaign ended before step {step}");
    };
    tokio::time::timeout(LIMIT, started)
        .await
        .unwrap_or_else(|_| panic!("step {step} starts"));
    (child, lines)
}
