//! The campaign fault matrix on the built-in mock lab: the run folder renamed, deleted, made
//! read-only, and its disk full, each at three moments of a three-step campaign. Every case is a
//! clear stop: exit 4, a message naming the folder and saying what to do, the bench left in its
//! safe state, the manifest on disk true (every file it lists there with its SHA-256) and
//! `interrupted`, never `complete` nor `running` (a full disk: written in the manifest's status
//! room in place; read-only: read so, no process holding the folder's lock); and `campaign resume`, once the fault is removed (remounted read-write, space
//! freed, at the folder's new path), finishes the run into a true `complete` whose
//! `results.json` equals an uninterrupted run's. A deleted folder has nothing left to resume:
//! the message says so, and the old path is not re-created.
//!
//! | moment  | the fault strikes at the positioner of | the first write refused |
//! |---------|----------------------------------------|-------------------------|
//! | `First` | step 1 (nothing of a step written yet) | step 1's files |
//! | `Mid`   | step 2, once step 1 is recorded        | step 2's files; a full disk has room for them, not for the manifest's journal line recording them |
//! | `Last`  | step 3, once step 2 is recorded        | step 3's files; a full disk has room for them and their journal line, not for the report (`results.json`, `results.csv` and `report.md` fit, `report.html` does not) |
//!
//! Every later write of the session is refused too (the next steps' files, `results.json`, the
//! report, the manifest).
//!
//! The faults come from the positioner program (`fault.sh`, run before each step's capture): it
//! waits (polling, at most 10 s) until the step before is recorded, so the folder holds exactly
//! the steps before and no write is in flight, then strikes once. A read-only folder and a full
//! disk need a file system of their own: those cases run radbench, the fault and its removal in
//! a user and mount namespace (`unshare -rm`) with the run folder on a 64 MiB tmpfs, and the
//! test reads the folder through `/proc/PID/root`. Read-only is a read-only bind mount of the
//! tmpfs over itself (a read-only remount is refused while radbench holds a file open for
//! writing there, its lock; as root, `chmod` makes nothing read-only); removing it is `umount`.
//! The full disk is a filler file leaving a number of pages computed from an uninterrupted run's
//! files (the same relative paths, so the same sizes). Without `unshare` those cases fail,
//! saying so. The I/O journal is kept outside the run folder (`--trace-io`), so it tells the
//! bench's last commands whatever became of the folder.

use radbench::campaign::{Manifest, Status, StepStatus};
use serde_json::Value;
use std::path::{Path, PathBuf};
use std::process::Stdio;
use std::time::Duration;
use tokio::io::{AsyncBufReadExt, AsyncWriteExt, BufReader, Lines};
use tokio::process::{Child, ChildStdin, ChildStdout, Command};

const BIN: &str = env!("CARGO_BIN_EXE_radbench");
/// Longest any shell command of a case may take (radbench itself is given 60 s).
const LIMIT: Duration = Duration::from_secs(90);

/// Three steps, each moving the target, so the positioner runs before every step.
const SPEC: &str = "name = \"faults\"\n\
    [positioner]\nkind = \"command\"\nprogram = \"sh\"\nargs = [\"fault.sh\", \"{step}\"]\n\
    timeout_s = 30\n\
    [sweep]\nparameter = \"position\"\nvalues = [1.0, 0.97, 0.94]\n";

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Fault {
    Renamed,
    Deleted,
    ReadOnly,
    DiskFull,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Moment {
    First,
    Mid,
    Last,
}

impl Moment {
    /// The step whose positioner strikes.
    fn step(self) -> usize {
        match self {
            Moment::First => 1,
            Moment::Mid => 2,
            Moment::Last => 3,
        }
    }
}

/// The uninterrupted run: its results, and the pages its files take on a tmpfs.
struct Reference {
    results: Value,
    /// Each step's files.
    step_pages: Vec<u64>,
    /// The complete manifest.
    manifest_pages: u64,
}

/// The tmpfs's block: a page.
fn page() -> u64 {
    // SAFETY: sysconf reads a constant of the system.
    unsafe { libc::sysconf(libc::_SC_PAGESIZE) as u64 }
}

fn pages(path: &Path) -> u64 {
    let m = std::fs::metadata(path).unwrap();
    if m.is_dir() {
        std::fs::read_dir(path)
            .unwrap()
            .map(|e| pages(&e.unwrap().path()))
            .sum()
    } else {
        m.len().div_ceil(page())
    }
}

/// The uninterrupted run (once for every case), with the cases' relative paths.
async fn reference() -> &'static Reference {
    static REFERENCE: tokio::sync::OnceCell<(tempfile::TempDir, Reference)> =
        tokio::sync::OnceCell::const_new();
    &REFERENCE
        .get_or_init(|| async {
            let tmp = tempfile::tempdir().unwrap();
            let d = tmp.path();
            std::fs::write(d.join("spec.toml"), SPEC).unwrap();
            std::fs::write(d.join("fault.sh"), "exit 0\n").unwrap();
            std::fs::create_dir(d.join("mnt")).unwrap();
            let child = Command::new(BIN)
                // The run folder's pages are counted: no run catalog beside it (its own
                // full-disk behaviour is tests/cli/runs_catalog.rs's).
                .env("RADBENCH_CATALOG", "off")
                .args([
                    "campaign",
                    "run",
                    "spec.toml",
                    "--allow-rf",
                    "--out",
                    "mnt/run",
                ])
                .current_dir(d)
                .stdin(Stdio::null())
                .stdout(Stdio::null())
                .stderr(Stdio::piped())
                .kill_on_drop(true)
                .spawn()
                .unwrap();
            let out = tokio::time::timeout(LIMIT, child.wait_with_output())
                .await
                .expect("the uninterrupted run finishes in time")
                .unwrap();
            let err = String::from_utf8_lossy(&out.stderr);
            assert_eq!(out.status.code(), Some(0), "{err}");
            let run = d.join("mnt/run");
            let m = Manifest::load(&run).unwrap();
            assert_eq!(m.status, Status::Complete);
            let reference = Reference {
                results: read_json(&run.join("results.json")),
                step_pages: m.steps.iter().map(|s| pages(&run.join(&s.dir))).collect(),
                manifest_pages: pages(&run.join("manifest.toml")),
            };
            (tmp, reference)
        })
        .await
        .1
}

fn read_json(path: &Path) -> Value {
    let text = std::fs::read_to_string(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    serde_json::from_str(&text).unwrap()
}

/// A shell in a case's folder that runs radbench, makes the fault and removes it: plain, or in a
/// user and mount namespace of its own with `mnt` a tmpfs.
struct Shell {
    child: Child,
    stdin: ChildStdin,
    stdout: Lines<BufReader<ChildStdout>>,
    dir: PathBuf,
}

impl Shell {
    async fn start(dir: &Path, namespace: bool) -> Shell {
        let log = std::fs::File::create(dir.join("shell.log")).unwrap();
        let mut command = if namespace {
            let mut c = Command::new("unshare");
            c.args(["-rm", "sh"]);
            c
        } else {
            Command::new("sh")
        };
        let mut child = command
            .current_dir(dir)
            // As the reference run: no run catalog beside the counted run folder.
            .env("RADBENCH_CATALOG", "off")
            .stdin(Stdio::piped())
            .stdout(Stdio::piped())
            .stderr(log)
            .kill_on_drop(true)
            .spawn()
            .unwrap_or_else(|e| {
                panic!(
                    "cannot start {}: {e}",
                    if namespace { "`unshare -rm sh`" } else { "sh" }
                )
            });
        let stdin = child.stdin.take().unwrap();
        let stdout = BufReader::new(child.stdout.take().unwrap()).lines();
        let mut shell = Shell {
            child,
            stdin,
            stdout,
            dir: dir.to_path_buf(),
        };
        if namespace {
            let code = shell
                .try_run("mount -t tmpfs -o size=64m,huge=never faults mnt")
                .await;
            if code != Some(0) {
                panic!(
                    "\n\n*** THE READ-ONLY AND DISK-FULL CASES OF THE FAULT MATRIX DID NOT RUN ***\n\
                     They need a user and mount namespace with a tmpfs of their own \
                     (`unshare -rm sh -c 'mount -t tmpfs tmpfs DIR'`), which this machine \
                     refused: {}\n\
                     Allow unprivileged user namespaces (sysctl kernel.unprivileged_userns_clone=1, \
                     or on Ubuntu kernel.apparmor_restrict_unprivileged_userns=0), or run as root.\n",
                    shell.log()
                );
            }
        }
        shell
    }

    /// What the shell and its commands printed.
    fn log(&self) -> String {
        std::fs::read_to_string(self.dir.join("shell.log")).unwrap_or_default()
    }

    /// Runs `command` (its output to `shell.log`); its exit status, `None` when the shell is gone.
    async fn try_run(&mut self, command: &str) -> Option<i32> {
        let line = format!("{{ {command}\n}} </dev/null >>shell.log 2>&1; echo \"status $?\"\n");
        let exchange = async {
            self.stdin.write_all(line.as_bytes()).await.ok()?;
            self.stdin.flush().await.ok()?;
            while let Some(out) = self.stdout.next_line().await.ok()? {
                if let Some(code) = out.strip_prefix("status ") {
                    return code.trim().parse().ok();
                }
            }
            None
        };
        tokio::time::timeout(LIMIT, exchange)
            .await
            .unwrap_or_else(|_| panic!("`{command}` finishes within {LIMIT:?}"))
    }

    async fn run(&mut self, command: &str) -> i32 {
        match self.try_run(command).await {
            Some(code) => code,
            None => panic!("the shell ended at `{command}`: {}", self.log()),
        }
    }

    /// `radbench ARGS` with its output in `NAME.out` and `NAME.err`: (exit code, stderr).
    async fn radbench(&mut self, name: &str, args: &str) -> (i32, String) {
        let code = self
            .run(&format!(
                "timeout -k 5 60 '{BIN}' {args} >{name}.out 2>{name}.err"
            ))
            .await;
        let err = std::fs::read_to_string(self.dir.join(format!("{name}.err"))).unwrap();
        (code, err)
    }

    /// Where the test sees `path` (relative to the case's folder) as the shell sees it.
    fn view(&self, path: &str) -> PathBuf {
        let pid = self.child.id().expect("the shell runs");
        let root = PathBuf::from(format!("/proc/{pid}/root"));
        root.join(self.dir.strip_prefix("/").unwrap()).join(path)
    }
}

/// The positioner program of a case: the fault, once, at the positioner of the moment's step,
/// when every step before is recorded in the manifest.
fn fault_script(fault: Fault, moment: Moment, reference: &Reference) -> String {
    let at = moment.step();
    let before = at - 1;
    let strike = match fault {
        Fault::Renamed => "mv mnt/run mnt/moved".to_string(),
        Fault::Deleted => "rm -rf mnt/run".to_string(),
        Fault::ReadOnly => "mount --bind mnt mnt && mount -o remount,bind,ro mnt".to_string(),
        Fault::DiskFull => {
            // Pages left free: none; room for step 2's files alone; room for step 3's files and
            // its manifest (and a page), where the report's HTML (10 pages) does not fit.
            let leave = match moment {
                Moment::First => 0,
                Moment::Mid => reference.step_pages[1],
                Moment::Last => reference.step_pages[2] + reference.manifest_pages + 1,
            };
            format!(
                "fallocate -l $(( ($(stat -f -c %a mnt) - {leave}) * $(stat -f -c %S mnt) )) \
                 mnt/filler"
            )
        }
    };
    format!(
        "# The fault of this case, once: {fault:?} at the positioner of step {at}.\n\
         [ \"$1\" = {at} ] && [ -e armed ] || exit 0\n\
         rm armed\n\
         i=0\n\
         until [ \"$(cat mnt/run/manifest.toml mnt/run/manifest-steps.jsonl 2>/dev/null \
         | grep -c -e '^status = \"done\"' -e '\"status\":\"done\"')\" -ge {before} ]; do\n\
         \x20 i=$((i + 1))\n\
         \x20 [ $i -le 2000 ] || {{ echo \"fault.sh: step {before} not recorded within 10 s\" >&2; exit 9; }}\n\
         \x20 sleep 0.005\n\
         done\n\
         {strike} || {{ echo 'fault.sh: the fault could not be made' >&2; exit 8; }}\n"
    )
}

/// After the last RF-on, the AWG's output off and the AWG stopped.
fn bench_left_safe(journal: &Path, what: &str) {
    let text = std::fs::read_to_string(journal).unwrap();
    let last_on = text
        .rfind(":OUTP1 ON")
        .unwrap_or_else(|| panic!("{what}: RF never on"));
    let after = &text[last_on..];
    assert!(
        after.contains(":OUTP1 OFF") && after.contains(":ABOR"),
        "{what}: the bench was not left in its safe state"
    );
}

/// Every file the manifest lists is in `run` with its SHA-256 (and no temporary is left).
fn manifest_true(m: &Manifest, run: &Path, what: &str) {
    let steps = m
        .steps
        .iter()
        .filter(|s| s.status == StepStatus::Done)
        .flat_map(|s| s.files.iter());
    for f in m.files.iter().chain(steps) {
        assert_eq!(f.check(run), None, "{what}: {}", f.path.display());
    }
    for dir in std::iter::once(run.to_path_buf()).chain(m.steps.iter().map(|s| run.join(&s.dir))) {
        for e in std::fs::read_dir(&dir).into_iter().flatten() {
            let name = e.unwrap().file_name().to_string_lossy().into_owned();
            assert!(
                !name.contains("radbench-tmp"),
                "{what}: a temporary was left: {name}"
            );
        }
    }
}

fn done(m: &Manifest) -> Vec<usize> {
    m.steps
        .iter()
        .filter(|s| s.status == StepStatus::Done)
        .map(|s| s.index)
        .collect()
}

async fn case(fault: Fault, moment: Moment) {
    let reference = reference().await;
    let what = format!("{fault:?} at {moment:?}");
    let tmp = tempfile::tempdir().unwrap();
    let d = tmp.path();
    std::fs::write(d.join("spec.toml"), SPEC).unwrap();
    std::fs::write(d.join("fault.sh"), fault_script(fault, moment, reference)).unwrap();
    std::fs::write(d.join("armed"), "").unwrap();
    std::fs::create_dir(d.join("mnt")).unwrap();
    let on_tmpfs = matches!(fault, Fault::ReadOnly | Fault::DiskFull);
    let mut sh = Shell::start(d, on_tmpfs).await;

    // The run, and its stop.
    // (A relative --trace-io is taken relative to the run folder.)
    let journal = d.join("journal.jsonl");
    let (code, err) = sh
        .radbench(
            "run",
            &format!(
                "campaign run spec.toml --allow-rf --out mnt/run --trace-io '{}'",
                journal.display()
            ),
        )
        .await;
    assert!(!d.join("armed").exists(), "{what}: no fault: {err}");
    assert_eq!(code, 4, "{what}: {err}");
    bench_left_safe(&journal, &what);
    // What the first refused write was, as the message tells it.
    let (first, then) = match (fault, moment) {
        (Fault::Renamed | Fault::Deleted, _) => (
            "the run folder mnt/run was moved or deleted while the campaign ran",
            "radbench campaign resume DIR",
        ),
        (Fault::ReadOnly, Moment::First) => (
            "The run had stopped: step 1 of 3: mnt/run/step-001: Read-only file system",
            "its file system is read-only: remount it read-write",
        ),
        (Fault::ReadOnly, Moment::Mid) => (
            "The run had stopped: step 2 of 3: mnt/run/step-002: Read-only file system",
            "its file system is read-only: remount it read-write",
        ),
        (Fault::ReadOnly, Moment::Last) => (
            "The run had stopped: step 3 of 3: mnt/run/step-003: Read-only file system",
            "its file system is read-only: remount it read-write",
        ),
        (Fault::DiskFull, Moment::First) => (
            "The run had stopped: step 1 of 3: cannot write mnt/run/step-001/",
            "its disk is full: free space on it",
        ),
        (Fault::DiskFull, Moment::Mid) => (
            "The run had stopped: step 2 of 3: cannot write mnt/run/manifest-steps.jsonl: No space",
            "its disk is full: free space on it",
        ),
        (Fault::DiskFull, Moment::Last) => (
            "cannot write mnt/run/report.html: No space",
            "Every step had been measured",
        ),
    };
    assert!(err.contains(first), "{what}: {err}");
    assert!(err.contains(then), "{what}: {err}");
    assert!(err.contains("safe state"), "{what}: {err}");
    if on_tmpfs {
        assert!(
            err.contains("the run could not write its end there")
                && err.contains("The bench is in its safe state")
                && err.contains("continue with `radbench campaign resume mnt/run --allow-rf`"),
            "{what}: {err}"
        );
    }
    if matches!(fault, Fault::Renamed | Fault::Deleted) {
        assert!(
            !sh.view("mnt/run").exists(),
            "{what}: the old path was re-created"
        );
        // Nothing to resume there (and, deleted, nowhere).
        let (code, err) = sh
            .radbench("resume-old", "campaign resume mnt/run --allow-rf")
            .await;
        assert_eq!(code, 2, "{what}: {err}");
        assert!(
            err.contains("mnt/run/manifest.toml: cannot read it"),
            "{what}: {err}"
        );
        if fault == Fault::Deleted {
            return;
        }
    }
    let folder = if fault == Fault::Renamed {
        "mnt/moved"
    } else {
        "mnt/run"
    };
    let run = sh.view(folder);

    // The manifest on disk at the stop: the steps written before, each file true.
    let m = Manifest::load(&run).unwrap();
    assert_eq!(m.status, Status::Interrupted, "{what}");
    if fault == Fault::DiskFull {
        // Recorded in the file itself (its status room, rewritten in place), not only read so
        // because no process holds the folder's lock.
        let text = std::fs::read_to_string(run.join("manifest.toml")).unwrap();
        assert!(
            text.contains("\nstatus = \"interrupted\"\n") && text.contains("\nexit_code = 4\n"),
            "{what}: {text}"
        );
        assert!(
            !m.reason.as_deref().unwrap_or("").contains("lock"),
            "{what}: {m:?}"
        );
    }
    let written: Vec<usize> = match (fault, moment) {
        (Fault::DiskFull, Moment::Last) => vec![1, 2, 3],
        (_, moment) => (1..moment.step()).collect(),
    };
    assert_eq!(done(&m), written, "{what}");
    manifest_true(&m, &run, &what);
    if (fault, moment) == (Fault::DiskFull, Moment::Mid) {
        // Step 2's files are whole and in place, only not recorded: resumed, it is measured again.
        assert!(run.join("step-002/result.json").is_file(), "{what}");
    }

    if on_tmpfs {
        // Resumed before the fault is removed: refused, the folder as it was.
        let before = std::fs::read(run.join("manifest.toml")).unwrap();
        let (code, err) = sh
            .radbench("resume-early", "campaign resume mnt/run --allow-rf")
            .await;
        assert_eq!(code, 4, "{what}: {err}");
        let remedy = match fault {
            Fault::ReadOnly => "its file system is read-only: remount it read-write",
            _ => "its disk is full: free space on it",
        };
        assert!(
            err.contains("mnt/run/") && err.contains(remedy),
            "{what}: {err}"
        );
        assert_eq!(
            std::fs::read(run.join("manifest.toml")).unwrap(),
            before,
            "{what}"
        );
        let remove = match fault {
            Fault::ReadOnly => "umount mnt",
            _ => "rm mnt/filler",
        };
        assert_eq!(sh.run(remove).await, 0, "{what}: {}", sh.log());
    }

    // Resumed: only what is missing is measured, and the run is truly complete.
    let (code, err) = sh
        .radbench("resume", &format!("campaign resume {folder} --allow-rf"))
        .await;
    assert_eq!(code, 0, "{what}: {err}");
    let m = Manifest::load(&run).unwrap();
    assert_eq!(m.status, Status::Complete, "{what}");
    assert_eq!(done(&m), vec![1, 2, 3], "{what}");
    assert_eq!(m.sessions.len(), 2, "{what}");
    assert_eq!(m.sessions[1].skipped, written, "{what}");
    assert!(m.sessions[1].remeasured.is_empty(), "{what}");
    if let Some(last) = &m.sessions[1].final_safe_state {
        assert!(!last.contains("failed"), "{what}: {last}");
    }
    manifest_true(&m, &run, &what);
    for name in ["results.json", "results.csv", "report.md", "report.html"] {
        assert!(
            m.files.iter().any(|f| f.path == Path::new(name)),
            "{what}: {name} is not in the manifest"
        );
    }
    assert_eq!(
        read_json(&run.join("results.json")),
        reference.results,
        "{what}: results differ from an uninterrupted run's"
    );
}

macro_rules! matrix {
    ($($name:ident: $fault:ident at $moment:ident;)*) => {$(
        #[tokio::test(flavor = "multi_thread", worker_threads = 2)]
        async fn $name() {
            case(Fault::$fault, Moment::$moment).await;
        }
    )*};
}

matrix! {
    renamed_before_step_1: Renamed at First;
    renamed_at_step_2: Renamed at Mid;
    renamed_at_the_last_step: Renamed at Last;
    deleted_before_step_1: Deleted at First;
    deleted_at_step_2: Deleted at Mid;
    deleted_at_the_last_step: Deleted at Last;
    read_only_before_step_1: ReadOnly at First;
    read_only_at_step_2: ReadOnly at Mid;
    read_only_at_the_last_step: ReadOnly at Last;
    disk_full_before_step_1: DiskFull at First;
    disk_full_between_step_2_and_its_manifest: DiskFull at Mid;
    disk_full_before_the_report: DiskFull at Last;
}
