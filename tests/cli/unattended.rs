//! Unattended overnight (issue 40): a campaign rides out a glitching instrument (each transient
//! fault once in the middle of the accuracy campaign: retried, the run completes with the results
//! of an undisturbed run; the same fault held past the retries: a clean, resumable stop), and a
//! rehearsal on a simulated bench runs as the bench will (a `command` positioner's placement
//! stands).
//!
//! The faults are switched on the built-in lab as its control channel would (`drop`, `stall`,
//! `power_cycle`, `marker_cable`; the JSON requests themselves are tested in mock_lab's
//! `lab.rs`), when the step's capture is about to start (`Observer::step_starting`), or, for a
//! module power-cycled during the capture, when its marker edge triggers the scope
//! (`Bench::at_next_trigger`): the capture then holds no echo and nothing in it fails, and only
//! the modules read back after it tell.

use radbench::campaign::{self, BenchInfo, Manifest, NewRun, Observer, Quiet, SpecFile, Status};
use radbench::campaign::{RetryRecord, Step};
use radbench::driver::RfPermit;
use radbench::exit::Classify;
use radbench::measure::{Bench, Interrupt};
use serde_json::Value;
use std::path::{Path, PathBuf};
use std::sync::atomic::Ordering;
use std::time::Duration;

/// Longest a campaign of a test may take.
const LIMIT: Duration = Duration::from_secs(120);

fn read_json(path: &Path) -> Value {
    let text = std::fs::read_to_string(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    serde_json::from_str(&text).unwrap()
}

/// Plans the campaign of `spec` and runs it into `out`, within the time limit.
async fn run(spec: &Path, out: &Path) -> campaign::Finished {
    run_observed(spec, out, &mut Quiet).await
}

async fn run_observed(spec: &Path, out: &Path, observer: &mut dyn Observer) -> campaign::Finished {
    let spec = SpecFile::load(spec).unwrap();
    let bench = BenchInfo::load(&spec, None).unwrap();
    let plan = campaign::plan(&spec, &bench).unwrap();
    let new = NewRun {
        spec,
        bench,
        plan,
        out: out.to_path_buf(),
        journal: None,
        permit: RfPermit::granted_by_user(),
        interrupt: Interrupt::never(),
        input: None,
    };
    tokio::time::timeout(LIMIT, campaign::start(new, observer))
        .await
        .expect("the run ends within the time limit")
        .unwrap()
}

/// A stage script's stand-in: moves the simulated pillar (target 0) to the step's position over
/// the lab's control channel (bash's /dev/tcp, loopback only).
fn stage_script(control: std::net::SocketAddr) -> String {
    format!(
        "exec 3<>/dev/tcp/{}/{}\n\
         printf '{{\"cmd\":\"move\",\"target\":0,\"range_m\":%s}}\\n' \"$RADBENCH_POSITION_M\" >&3\n\
         read -r reply <&3\n\
         case \"$reply\" in *'\"ok\":true'*) ;; *) echo \"stage: $reply\" >&2; exit 1 ;; esac\n",
        control.ip(),
        control.port()
    )
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_command_positioner_s_placement_stands_on_a_simulated_bench() {
    let lab = tokio::time::timeout(
        Duration::from_secs(10),
        mock_lab::lab::start(mock_lab::lab::LabOptions::default()),
    )
    .await
    .expect("the lab starts")
    .unwrap();
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    super::support::lab_bench_file(d, &lab);
    std::fs::write(d.join("stage.sh"), stage_script(lab.control)).unwrap();
    let spec = d.join("spec.toml");
    std::fs::write(
        &spec,
        "name = \"rehearsal\"\n[bench]\nfile = \"bench.toml\"\n\
         [positioner]\nkind = \"command\"\nprogram = \"bash\"\nargs = [\"stage.sh\"]\n\
         timeout_s = 20\n\
         [sweep]\nparameter = \"position\"\nvalues = [1.2, 1.1, 0.95]\n",
    )
    .unwrap();
    let out = d.join("run");
    let finished = run(&spec, &out).await;
    assert!(finished.stopped.is_none(), "{:?}", finished.stopped);
    assert_eq!(Manifest::load(&out).unwrap().status, Status::Complete);
    let results = read_json(&out.join("results.json"));
    let steps = results["steps"].as_array().unwrap();
    let truth: Vec<f64> = steps
        .iter()
        .map(|s| s["truth"]["targets"][0]["range_m"].as_f64().unwrap())
        .collect();
    // Each step measured where the stage put the pillar, not where the scene read at the
    // start had it (1.0 m).
    assert_eq!(truth, vec![1.2, 1.1, 0.95]);
    // And the radar saw it there: the strongest echo follows the pillar (this bench file has no
    // [calibration], so every range holds the same system delay).
    let offsets: Vec<f64> = steps
        .iter()
        .zip(&truth)
        .map(|(s, truth)| {
            let strongest = s["algorithms"]["correlation"]["targets"]
                .as_array()
                .unwrap()
                .iter()
                .max_by(|a, b| {
                    let level = |t: &Value| t["level_db"].as_f64().unwrap_or(f64::MIN);
                    level(a).total_cmp(&level(b))
                })
                .unwrap()["range_m"]
                .as_f64()
                .unwrap();
            strongest - truth
        })
        .collect();
    assert!(
        offsets.iter().all(|o| (o - offsets[0]).abs() < 0.01),
        "{offsets:?}"
    );
    // The noise is still the runner's: the last capture had the last step's seed.
    let m = Manifest::load(&out).unwrap();
    let (_, last) = lab.bench.scene.last_capture();
    assert_eq!(Some(last.unwrap().seed), m.plan.steps[2].noise_seed);
}

/// The accuracy campaign (examples/accuracy.toml) with a short wait for the marker edge and a
/// short first wait before a retry, written into `dir`.
fn accuracy_spec(dir: &Path) -> PathBuf {
    let example = Path::new(env!("CARGO_MANIFEST_DIR")).join("examples/accuracy.toml");
    let text = std::fs::read_to_string(example).unwrap();
    let path = dir.join("accuracy.toml");
    std::fs::write(
        &path,
        format!("wait_s = 1.5\n{text}\n[run]\nretries = 2\nretry_backoff_s = 0.2\n"),
    )
    .unwrap();
    path
}

/// The undisturbed run's `results.json` (once for every case).
async fn reference() -> &'static Value {
    static REFERENCE: tokio::sync::OnceCell<Value> = tokio::sync::OnceCell::const_new();
    REFERENCE
        .get_or_init(|| async {
            let dir = tempfile::tempdir().unwrap();
            let out = dir.path().join("run");
            let finished = run(&accuracy_spec(dir.path()), &out).await;
            assert!(finished.stopped.is_none(), "{:?}", finished.stopped);
            assert!(Manifest::load(&out).unwrap().retries.is_empty());
            read_json(&out.join("results.json"))
        })
        .await
}

/// A transient fault of one instrument.
#[derive(Debug, Clone, Copy)]
enum Glitch {
    /// `{"cmd":"fault","drop":"awg"}`
    DropAwg,
    /// `{"cmd":"fault","drop":"scope"}`
    DropScope,
    /// `{"cmd":"fault","stall":"scope","for_s":30}` (past every wait of the scope's: its 10 s
    /// reply timeout, the acquisition's `wait_s` + 5 s + 10 s)
    StallScope,
    /// `{"cmd":"fault","power_cycle":"tx","for_s":5}`
    PowerCycleTx,
    /// `{"cmd":"fault","marker_cable":false}` (past `wait_s`)
    MarkerOut,
    /// The Tx power-cycled during the capture, once the marker edge has triggered it (RF on):
    /// as `{"cmd":"fault","power_cycle":"tx","for_s":0.5}` landing mid-capture. Nothing in the
    /// capture fails; the Tx read back after it is silent or back at power-on.
    PowerCycleTxInCapture,
    /// The same for the Rx, back at once (`for_s` 0): it answers as at power-on.
    PowerCycleRxInCapture,
}

impl Glitch {
    fn strike(self, lab: &mock_lab::lab::Lab) {
        match self {
            Glitch::DropAwg => lab.awg_faults.drop_next_reply_midway(),
            Glitch::DropScope => lab.scope_faults.drop_next_reply_midway(),
            Glitch::StallScope => lab.scope_faults.stall_for(Duration::from_secs(30)),
            Glitch::PowerCycleTx => {
                lab.bench.tx.power_cycle();
                lab.tx_faults.silence_for(Duration::from_secs(5));
            }
            Glitch::MarkerOut => lab.bench.marker_cable.store(false, Ordering::SeqCst),
            Glitch::PowerCycleTxInCapture => {
                let (tx, faults) = (lab.bench.tx.clone(), lab.tx_faults.clone());
                lab.bench.at_next_trigger(move || {
                    tx.power_cycle();
                    faults.silence_for(Duration::from_millis(500));
                });
            }
            Glitch::PowerCycleRxInCapture => {
                let rx = lab.bench.rx.clone();
                lab.bench.at_next_trigger(move || rx.power_cycle());
            }
        }
    }

    /// The instrument the retry names.
    fn instrument(self) -> &'static str {
        match self {
            Glitch::DropAwg => "awg",
            Glitch::DropScope | Glitch::StallScope | Glitch::MarkerOut => "scope",
            Glitch::PowerCycleTx | Glitch::PowerCycleTxInCapture => "tx",
            Glitch::PowerCycleRxInCapture => "rx",
        }
    }

    /// What the retry's fault must say, beyond naming the instrument.
    fn fault_says(self) -> &'static [&'static str] {
        match self {
            // Silent for 0.5 s, then at power-on: which of the two the read-back meets depends
            // on how long the capture's transfer took.
            Glitch::PowerCycleTxInCapture => &["tx: ", "reset or lost power during the capture"],
            Glitch::PowerCycleRxInCapture => &[
                "rx: the module answers without the CRC-8 framing it was switched to, as at \
                 power-on",
                "it was reset or lost power during the capture, which is not used",
            ],
            _ => &[],
        }
    }

    /// The safe-state step a module without power fails, if this glitch cuts one. A module back
    /// at power-on, in the other line mode (the Rx here), is switched off in plain lines: its
    /// step is done.
    fn module_off(self) -> Option<&'static str> {
        match self {
            Glitch::PowerCycleTx | Glitch::PowerCycleTxInCapture => Some("Tx RF off: FAILED"),
            _ => None,
        }
    }
}

/// Strikes at step `at`'s capture: at its first attempt only, or (`held`) at every attempt.
struct Saboteur {
    glitch: Glitch,
    at: usize,
    held: bool,
    struck: usize,
    notes: Vec<String>,
}

impl Observer for Saboteur {
    fn step_starting(&mut self, step: &Step, _of: usize, bench: &Bench) {
        if step.index == self.at && (self.held || self.struck == 0) {
            self.struck += 1;
            self.glitch
                .strike(bench.lab.as_ref().expect("the built-in lab"));
        }
    }

    fn note(&mut self, text: &str) {
        self.notes.push(text.to_string());
    }
}

/// Between one RF-on and the next, the bench was put in its safe state (AWG output off, AWG
/// stopped); and after the last one too.
fn safe_between_captures(journal: &Path) -> usize {
    let text = std::fs::read_to_string(journal).unwrap();
    let parts: Vec<&str> = text.split(":OUTP1 ON").collect();
    for (k, after) in parts.iter().enumerate().skip(1) {
        assert!(
            after.contains(":OUTP1 OFF") && after.contains(":ABOR"),
            "RF-on {k} of {} was not followed by the safe state",
            parts.len() - 1
        );
    }
    parts.len() - 1
}

async fn ridden_out(glitch: Glitch) {
    let expected = reference().await;
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("run");
    let mut saboteur = Saboteur {
        glitch,
        at: 3,
        held: false,
        struck: 0,
        notes: Vec::new(),
    };
    let finished = run_observed(&accuracy_spec(dir.path()), &out, &mut saboteur).await;
    assert!(
        finished.stopped.is_none(),
        "{glitch:?}: {:?}",
        finished.stopped
    );
    let m = Manifest::load(&out).unwrap();
    assert_eq!(m.status, Status::Complete);
    assert_eq!(
        read_json(&out.join("results.json")),
        *expected,
        "{glitch:?}"
    );
    // One retry of step 3, recorded, told, the bench safe before it.
    let [retry]: [RetryRecord; 1] = m.retries.clone().try_into().unwrap_or_else(|r| {
        panic!("{glitch:?}: one retry expected: {r:?}");
    });
    assert_eq!((retry.step, retry.attempt), (3, 1), "{retry:?}");
    assert_eq!(retry.instrument, glitch.instrument(), "{retry:?}");
    for says in glitch.fault_says() {
        assert!(retry.fault.contains(says), "{glitch:?}: {retry:?}");
    }
    assert!(
        retry.safe_state.contains("AWG outputs off and :ABOR: done"),
        "{retry:?}"
    );
    // A module without power cannot be told to switch off (it is off): only its step may fail.
    let failed = retry.safe_state.matches("FAILED").count();
    let module_off = glitch
        .module_off()
        .is_some_and(|step| retry.safe_state.contains(step));
    assert!(failed == 0 || (failed == 1 && module_off), "{retry:?}");
    assert!(
        saboteur
            .notes
            .iter()
            .any(|n| n.starts_with("step 3 of 6: ") && n.contains("retry 1 of 2")),
        "{glitch:?}: {:?}",
        saboteur.notes
    );
    safe_between_captures(&out.join("io-journal.jsonl"));
    let report = std::fs::read_to_string(out.join("report.md")).unwrap();
    assert!(report.contains("## Retries"), "{report}");
}

async fn held_past_the_retries(glitch: Glitch) {
    let expected = reference().await;
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("run");
    let mut saboteur = Saboteur {
        glitch,
        at: 3,
        held: true,
        struck: 0,
        notes: Vec::new(),
    };
    let finished = run_observed(&accuracy_spec(dir.path()), &out, &mut saboteur).await;
    let err = finished.stopped.expect("the fault outlasts the retries");
    assert_eq!(err.exit_class().code(), 3, "{err}");
    assert_eq!(saboteur.struck, 3, "the first attempt and two retries");
    let m = Manifest::load(&out).unwrap();
    assert_eq!(m.status, Status::Interrupted);
    assert_eq!(m.stopped_at_step, Some(3));
    assert_eq!(m.retries.len(), 2, "{:?}", m.retries);
    safe_between_captures(&out.join("io-journal.jsonl"));
    // Resumed without the fault (and with more retries from now on, as `campaign resume
    // --retries 4` asks): the run completes as an undisturbed one.
    let finished = tokio::time::timeout(
        LIMIT,
        campaign::resume(
            &out,
            RfPermit::granted_by_user(),
            false,
            Some(4),
            Interrupt::never(),
            None,
            &mut Quiet,
        ),
    )
    .await
    .expect("the resume ends")
    .unwrap();
    assert!(finished.stopped.is_none(), "{:?}", finished.stopped);
    assert_eq!(
        read_json(&out.join("results.json")),
        *expected,
        "{glitch:?}"
    );
    assert_eq!(Manifest::load(&out).unwrap().plan.retries, 4);
}

macro_rules! glitches {
    ($($name:ident: $how:ident $glitch:ident;)*) => {$(
        #[tokio::test(flavor = "multi_thread", worker_threads = 2)]
        async fn $name() {
            $how(Glitch::$glitch).await;
        }
    )*};
}

glitches! {
    a_dropped_awg_connection_is_ridden_out: ridden_out DropAwg;
    a_dropped_scope_connection_is_ridden_out: ridden_out DropScope;
    a_stalled_scope_is_ridden_out: ridden_out StallScope;
    a_power_cycled_tx_is_ridden_out: ridden_out PowerCycleTx;
    a_tx_power_cycled_during_the_capture_is_ridden_out: ridden_out PowerCycleTxInCapture;
    a_rx_power_cycled_during_the_capture_is_ridden_out: ridden_out PowerCycleRxInCapture;
    a_missing_marker_edge_is_ridden_out: ridden_out MarkerOut;
    a_dropped_scope_connection_held_stops_resumably: held_past_the_retries DropScope;
    a_missing_marker_edge_held_stops_resumably: held_past_the_retries MarkerOut;
}

/// `campaign run --json` prints each retry as an event, between the step's `start` and its
/// `step`: `{"event":"retry","index","of","attempt","retries","instrument","fault","at",
/// "safe_state","wait_s"}` (the CLI against a lab of this process, whose AWG drops its
/// connection once, mid-step).
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn campaign_json_prints_each_retry_as_an_event() {
    use tokio::io::AsyncBufReadExt;
    let lab = tokio::time::timeout(
        Duration::from_secs(10),
        mock_lab::lab::start(mock_lab::lab::LabOptions::default()),
    )
    .await
    .expect("the lab starts")
    .unwrap();
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    super::support::lab_bench_file(d, &lab);
    let spec = d.join("spec.toml");
    std::fs::write(
        &spec,
        "name = \"glitch\"\nwait_s = 1.5\n[bench]\nfile = \"bench.toml\"\n\
         [sweep]\nparameter = \"position\"\nvalues = [1.0, 1.1, 1.2]\n\
         [run]\nretries = 2\nretry_backoff_s = 0.1\n",
    )
    .unwrap();
    let mut child = tokio::process::Command::new(env!("CARGO_BIN_EXE_radbench"))
        .args(["campaign", "run", "--allow-rf", "--json", "--out"])
        .arg(d.join("run"))
        .arg(&spec)
        .stdin(std::process::Stdio::null())
        .stdout(std::process::Stdio::piped())
        .stderr(std::process::Stdio::null())
        .kill_on_drop(true)
        .spawn()
        .unwrap();
    let mut lines = tokio::io::BufReader::new(child.stdout.take().unwrap()).lines();
    let mut events: Vec<Value> = Vec::new();
    let read = async {
        while let Some(line) = lines.next_line().await.unwrap() {
            let event: Value = serde_json::from_str(&line).unwrap();
            let first_start_of_2 = event["event"] == "start"
                && event["index"] == 2
                && events.iter().all(|e| e["index"] != 2);
            if first_start_of_2 {
                lab.awg_faults.drop_next_reply_midway();
            }
            events.push(event);
        }
        child.wait().await.unwrap()
    };
    let status = tokio::time::timeout(LIMIT, read)
        .await
        .expect("the run ends");
    assert!(status.success(), "{events:?}");
    let kinds: Vec<(String, u64)> = events
        .iter()
        .map(|e| {
            let kind = e["event"].as_str().unwrap().to_string();
            (kind, e["index"].as_u64().unwrap_or(0))
        })
        .collect();
    let retry = events
        .iter()
        .find(|e| e["event"] == "retry")
        .unwrap_or_else(|| panic!("no retry event: {kinds:?}"));
    assert_eq!(retry["index"], 2, "{retry}");
    assert_eq!(retry["of"], 3, "{retry}");
    assert_eq!(retry["attempt"], 1, "{retry}");
    assert_eq!(retry["retries"], 2, "{retry}");
    assert_eq!(retry["instrument"], "awg", "{retry}");
    let safe = retry["safe_state"].as_str().unwrap();
    assert!(safe.contains("AWG outputs off"), "{retry}");
    assert_eq!(retry["wait_s"], 0.1, "{retry}");
    // After the step's start, before its step event; the run completes.
    let at = |kind: &str, index: u64| {
        kinds
            .iter()
            .position(|k| k.0 == kind && k.1 == index)
            .unwrap_or_else(|| panic!("no {kind} {index}: {kinds:?}"))
    };
    let retry_at = at("retry", 2);
    assert!(
        at("start", 2) < retry_at && retry_at < at("step", 2),
        "{kinds:?}"
    );
    assert_eq!(events.last().unwrap()["status"], "complete", "{kinds:?}");
    let m = Manifest::load(&d.join("run")).unwrap();
    assert_eq!(m.retries.len(), 1, "{:?}", m.retries);
}

/// `campaign resume --retries N` is checked as `campaign run --retries` is: exit 2 naming the
/// flag and what is allowed, before anything is read or connected.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn resume_retries_past_the_most_is_bad_input() {
    let dir = tempfile::tempdir().unwrap();
    let out = tokio::process::Command::new(env!("CARGO_BIN_EXE_radbench"))
        .args(["campaign", "resume", "--allow-rf", "--retries", "11"])
        .arg(dir.path())
        .output();
    let out = tokio::time::timeout(LIMIT, out).await.unwrap().unwrap();
    assert_eq!(out.status.code(), Some(2));
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("--retries 11: allowed 0..=10"), "{err}");
}
