//! The CLI tools on every way out: a closed standard output, instrument text with escape
//! sequences, bad options, history and block saving, `mock-lab serve` stopped by signals, and
//! Ctrl-C at the interactive `scpi` prompt (driven through a pseudo-terminal).

use crate::process_support;

use std::io::{BufRead, BufReader, Read, Write};
use std::net::{SocketAddr, TcpListener};
use std::os::fd::{FromRawFd, OwnedFd};
use std::process::{Command, Output, Stdio};
use std::sync::{mpsc, Arc};
use std::time::{Duration, Instant};

use process_support::Spawned;

use mock_lab::emulator::loopback::{Loopback, IDENTITY};
use mock_lab::server::launch::{self, Endpoint, Ports, Running, Transport};
use mock_lab::server::{Handler, ServerOptions};

const BIN: &str = env!("CARGO_BIN_EXE_radbench");
/// Every wait in these tests is bounded by this.
const LIMIT: Duration = Duration::from_secs(30);

/// A mock_lab instrument on 127.0.0.1, served by its own runtime for as long as it lives.
struct Instrument {
    endpoint: Endpoint,
    _server: Running,
    runtime: Option<tokio::runtime::Runtime>,
}

impl Instrument {
    fn start(handler: Arc<dyn Handler>, transport: Transport) -> Instrument {
        let runtime = tokio::runtime::Builder::new_multi_thread()
            .worker_threads(1)
            .enable_all()
            .build()
            .unwrap();
        let (server, endpoint) = runtime
            .block_on(launch::start(
                "loopback",
                handler,
                transport,
                Ports::default(),
                ServerOptions::default(),
            ))
            .unwrap();
        Instrument {
            endpoint,
            _server: server,
            runtime: Some(runtime),
        }
    }

    fn loopback() -> Instrument {
        Instrument::start(Arc::new(Loopback::new()), Transport::Raw)
    }

    fn resource(&self) -> &str {
        &self.endpoint.resource
    }
}

impl Drop for Instrument {
    fn drop(&mut self) {
        // A SLOW? left sleeping on the blocking pool must not hold the test up.
        if let Some(rt) = self.runtime.take() {
            rt.shutdown_background();
        }
    }
}

/// A raw-socket instrument that answers each query line with fixed bytes (escape sequences,
/// blocks): what no well-behaved emulator would send.
fn scripted(replies: &'static [(&'static str, &'static [u8])]) -> SocketAddr {
    let listener = TcpListener::bind("127.0.0.1:0").unwrap();
    let addr = listener.local_addr().unwrap();
    std::thread::spawn(move || {
        for stream in listener.incoming() {
            let Ok(stream) = stream else { return };
            std::thread::spawn(move || {
                let mut writer = stream.try_clone().unwrap();
                for line in BufReader::new(stream).lines() {
                    let Ok(line) = line else { return };
                    if let Some((_, reply)) = replies.iter().find(|(q, _)| *q == line.trim()) {
                        if writer.write_all(reply).is_err() {
                            return;
                        }
                    }
                }
            });
        }
    });
    addr
}

/// Runs radbench to its end with stdin closed, bounded by [`LIMIT`].
fn radbench(args: &[&str]) -> Output {
    radbench_with(args, |_| {})
}

fn radbench_with(args: &[&str], setup: impl FnOnce(&mut Command)) -> Output {
    let mut command = Command::new(BIN);
    command
        .args(args)
        .stdin(Stdio::null())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped());
    setup(&mut command);
    Spawned::new(&mut command).output_within(LIMIT)
}

fn text(bytes: &[u8]) -> String {
    String::from_utf8_lossy(bytes).into_owned()
}

/// The write end of a pipe whose read end is already closed: every write to it fails with
/// EPIPE, deterministically.
fn closed_pipe() -> Stdio {
    let mut fds = [0; 2];
    // SAFETY: pipe fills two new descriptors, which are owned exactly once below.
    assert_eq!(unsafe { libc::pipe(fds.as_mut_ptr()) }, 0);
    // SAFETY: the two descriptors pipe just made, each owned once.
    let (read, write) = unsafe { (OwnedFd::from_raw_fd(fds[0]), OwnedFd::from_raw_fd(fds[1])) };
    drop(read);
    Stdio::from(write)
}

#[test]
fn a_closed_stdout_ends_every_kind_of_command_quietly() {
    let lab = Instrument::loopback();
    let runs: [&[&str]; 4] = [
        &["idn", lab.resource()],
        &["scpi", lab.resource(), "*IDN?", "*IDN?"],
        &[
            "simulate",
            "run",
            "--waveform",
            "msk-lfm",
            "--targets",
            "1.0",
        ],
        &["--version"],
    ];
    for args in runs {
        let out = radbench_with(args, |c| {
            c.stdout(closed_pipe());
        });
        let err = text(&out.stderr);
        assert_eq!(out.status.code(), Some(0), "{args:?}: {err}");
        assert!(!err.contains("panicked"), "{args:?}: {err}");
        assert!(
            !err.to_lowercase().contains("broken pipe"),
            "{args:?}: {err}"
        );
    }
}

#[test]
fn scpi_finishes_its_commands_when_stdout_closes_early() {
    let lab = Instrument::loopback();
    let out = radbench_with(
        &["scpi", lab.resource(), "*IDN?", "DATA #13off", "*OPC?"],
        |c| {
            c.stdout(closed_pipe());
        },
    );
    assert_eq!(out.status.code(), Some(0), "{}", text(&out.stderr));
    // The command after the lost reply still reached the instrument.
    let check = radbench(&["scpi", lab.resource(), "DATA:LEN?"]);
    assert_eq!(text(&check.stdout).trim(), "3");
}

static HOSTILE: &[(&str, &[u8])] = &[
    ("*IDN?", b"\x1b]0;pwned\x07ACME,\x1b[31mMODEL,SN\r1,FW\n"),
    ("ERR?", b"ok\rFAKE PROMPT$ \x1b[2J\n"),
    ("BAD?", b"\x1b[2J\n"),
    ("BLK?", b"#15hello\n"),
    ("IND?", b"#0hi there\n"),
    ("BIN?", b"#14\x1b[2J\n"),
];

#[test]
fn instrument_text_never_reaches_the_terminal_raw() {
    let addr = scripted(HOSTILE);
    let resource = format!("TCPIP::{}::{}::SOCKET", addr.ip(), addr.port());
    let out = radbench(&["idn", &resource, "--timeout", "5"]);
    let stdout = text(&out.stdout);
    assert!(out.status.success(), "{}", text(&out.stderr));
    assert!(
        !stdout.contains('\x1b') && !stdout.contains('\r'),
        "{stdout:?}"
    );
    assert!(stdout.contains("\\x1b]0;pwned\\x07ACME"), "{stdout}");
    assert!(stdout.contains("SN\\x0d1"), "{stdout}");
    let out = radbench(&["scpi", &resource, "ERR?", "BIN?", "--timeout", "5"]);
    let stdout = text(&out.stdout);
    assert!(out.status.success(), "{}", text(&out.stderr));
    assert!(
        !stdout.contains('\x1b') && !stdout.contains('\r'),
        "{stdout:?}"
    );
    assert!(stdout.contains("ok\\x0dFAKE PROMPT$ \\x1b[2J"), "{stdout}");
    assert!(
        stdout.contains("binary block (definite): 4 bytes"),
        "{stdout}"
    );
    // An unparseable identity is an error quoting the reply: escaped on stderr as well.
    let hostile_idn: &'static [(&'static str, &'static [u8])] = &[("*IDN?", b"\x1b[2J\n")];
    let addr = scripted(hostile_idn);
    let resource = format!("TCPIP::{}::{}::SOCKET", addr.ip(), addr.port());
    let out = radbench(&["idn", &resource, "--timeout", "5"]);
    let stderr = text(&out.stderr);
    assert_eq!(out.status.code(), Some(3), "{stderr}");
    assert!(!stderr.contains('\x1b'), "{stderr:?}");
}

#[test]
fn save_binary_keeps_every_block_short_printable_and_indefinite() {
    let addr = scripted(HOSTILE);
    let resource = format!("TCPIP::{}::{}::SOCKET", addr.ip(), addr.port());
    let dir = tempfile::tempdir().unwrap();
    let saved = dir.path().join("reply.bin");
    let out = radbench(&[
        "scpi",
        &resource,
        "BLK?",
        "IND?",
        "BIN?",
        "--save-binary",
        saved.to_str().unwrap(),
        "--timeout",
        "5",
    ]);
    assert!(out.status.success(), "{}", text(&out.stderr));
    let stdout = text(&out.stdout);
    assert!(
        stdout.contains("binary block (indefinite): 8 bytes"),
        "{stdout}"
    );
    let second = dir.path().join("reply.bin.2");
    let third = dir.path().join("reply.bin.3");
    assert_eq!(std::fs::read(&saved).unwrap(), b"hello");
    assert_eq!(std::fs::read(&second).unwrap(), b"hi there");
    assert_eq!(std::fs::read(&third).unwrap(), b"\x1b[2J");
    // Nothing but the three files: no temporary left behind.
    assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 3);
}

#[test]
fn piped_commands_at_the_prompt_leave_no_history() {
    let lab = Instrument::loopback();
    let home = tempfile::tempdir().unwrap();
    let mut child = Spawned::new(
        Command::new(BIN)
            .args(["scpi", lab.resource()])
            .env("HOME", home.path())
            .stdin(Stdio::piped())
            .stdout(Stdio::piped())
            .stderr(Stdio::piped()),
    );
    child
        .stdin
        .take()
        .unwrap()
        .write_all(b"*IDN?\n\\quit\n")
        .unwrap();
    let out = child.output_within(LIMIT);
    assert!(out.status.success(), "{}", text(&out.stderr));
    assert!(
        text(&out.stdout).contains(IDENTITY),
        "{}",
        text(&out.stdout)
    );
    assert!(
        !home.path().join(".radbench_scpi_history").exists(),
        "history written although stdin is a pipe"
    );
}

#[test]
fn baud_zero_is_bad_input_not_a_link_failure() {
    let out = radbench(&["idn", "ASRL/dev/null::INSTR", "--baud", "0"]);
    assert_eq!(out.status.code(), Some(2), "{}", text(&out.stderr));
    assert!(text(&out.stderr).contains("--baud 0"));
}

#[test]
fn mock_lab_serve_options_and_scenes_are_checked_as_bad_input() {
    let out = radbench(&["mock-lab", "serve", "--port-base", "65535"]);
    let stderr = text(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{stderr}");
    assert!(stderr.contains("1 ..= 65526"), "{stderr}");
    assert!(!stderr.contains("bug"), "{stderr}");
    let dir = tempfile::tempdir().unwrap();
    let scene = dir.path().join("scene.toml");
    std::fs::write(
        &scene,
        "snr_db = 20\n[[targets]]\nrange_m = 1.0\namplitude = 1e300\n",
    )
    .unwrap();
    let out = radbench(&["mock-lab", "serve", "--scene", scene.to_str().unwrap()]);
    let stderr = text(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{stderr}");
    for part in ["scene.toml", "line 4", "targets[0].amplitude", "1e300"] {
        assert!(stderr.contains(part), "{part}: {stderr}");
    }
}

#[test]
fn mock_lab_serve_until_stdin_closes_also_stops_on_signals() {
    for signal in [libc::SIGTERM, libc::SIGINT] {
        let mut child = Spawned::new(
            Command::new(BIN)
                .args(["mock-lab", "serve", "--json", "--until-stdin-closes"])
                .stdin(Stdio::piped())
                .stdout(Stdio::piped())
                .stderr(Stdio::null()),
        );
        let stdin = child.stdin.take();
        let line = child.first_line_within(LIMIT);
        let listing: serde_json::Value = serde_json::from_str(&line).unwrap();
        let awg = listing["endpoints"][0]["address"]
            .as_str()
            .unwrap()
            .to_string();
        std::net::TcpStream::connect(&awg).expect("serving");
        // SAFETY: signals our own child.
        assert_eq!(unsafe { libc::kill(child.id() as libc::pid_t, signal) }, 0);
        let status = child.wait_within(LIMIT);
        drop(stdin);
        assert_eq!(status.code(), Some(0), "signal {signal}: {status:?}");
        let err = std::net::TcpStream::connect(&awg).expect_err("stopped");
        assert_eq!(err.kind(), std::io::ErrorKind::ConnectionRefused);
    }
}

// ------------------------------------------------------------------ the prompt, on a terminal

/// The loopback instrument, telling the test when a message arrives (so Ctrl-C is pressed while
/// the command is known to be running).
struct Watched {
    inner: Loopback,
    arrived: std::sync::Mutex<mpsc::Sender<String>>,
}

impl Handler for Watched {
    fn message(&self, data: &[u8]) -> Vec<Vec<u8>> {
        let _ = self
            .arrived
            .lock()
            .unwrap()
            .send(String::from_utf8_lossy(data).into_owned());
        self.inner.message(data)
    }

    fn device_clear(&self) {
        self.inner.device_clear();
    }
}

/// A pseudo-terminal master: what the user types goes in, what radbench shows comes out.
struct Terminal {
    master: std::fs::File,
    seen: Arc<std::sync::Mutex<String>>,
}

impl Terminal {
    /// Spawns `command` as the session leader of a new pseudo-terminal (its controlling
    /// terminal, so Ctrl-C there is SIGINT to it).
    fn spawn(command: &mut Command) -> (Terminal, Spawned) {
        let (mut master, mut slave) = (0, 0);
        // SAFETY: openpty fills two new descriptors; null name/termios/winsize are allowed.
        let rc = unsafe {
            libc::openpty(
                &mut master,
                &mut slave,
                std::ptr::null_mut(),
                std::ptr::null(),
                std::ptr::null(),
            )
        };
        assert_eq!(rc, 0, "openpty");
        // SAFETY: both descriptors are new and owned once each.
        let master = unsafe { std::fs::File::from_raw_fd(master) };
        // SAFETY: as above.
        let slave = unsafe { OwnedFd::from_raw_fd(slave) };
        let io = |fd: &OwnedFd| Stdio::from(fd.try_clone().unwrap());
        command
            .stdin(io(&slave))
            .stdout(io(&slave))
            .stderr(io(&slave));
        // SAFETY: only async-signal-safe calls between fork and exec.
        unsafe {
            use std::os::unix::process::CommandExt;
            command.pre_exec(|| {
                if libc::setsid() < 0 || libc::ioctl(0, libc::TIOCSCTTY as _, 0) < 0 {
                    return Err(std::io::Error::last_os_error());
                }
                Ok(())
            });
        }
        let child = Spawned::new(command);
        drop(slave);
        let seen = Arc::new(std::sync::Mutex::new(String::new()));
        let mut reader = master.try_clone().unwrap();
        let sink = seen.clone();
        std::thread::spawn(move || {
            let mut buf = [0u8; 4096];
            while let Ok(n) = reader.read(&mut buf) {
                if n == 0 {
                    break;
                }
                sink.lock()
                    .unwrap()
                    .push_str(&String::from_utf8_lossy(&buf[..n]));
            }
        });
        (Terminal { master, seen }, child)
    }

    fn type_text(&mut self, keys: &str) {
        self.master.write_all(keys.as_bytes()).unwrap();
    }

    /// Waits (bounded) until the terminal has shown `text` `count` times in all.
    fn wait_for(&self, text: &str, count: usize) {
        let deadline = Instant::now() + LIMIT;
        loop {
            let shown = self.seen.lock().unwrap().matches(text).count();
            if shown >= count {
                return;
            }
            assert!(
                Instant::now() < deadline,
                "the terminal never showed {text:?}:\n{}",
                self.seen.lock().unwrap()
            );
            std::thread::sleep(Duration::from_millis(10));
        }
    }
}

#[test]
fn ctrl_c_at_the_prompt_cancels_the_command_and_keeps_the_session() {
    let (tx, arrived) = mpsc::channel();
    let handler = Arc::new(Watched {
        inner: Loopback::new(),
        arrived: std::sync::Mutex::new(tx),
    });
    let lab = Instrument::start(handler, Transport::Hislip);
    let home = tempfile::tempdir().unwrap();
    let (mut term, mut child) = Terminal::spawn(
        Command::new(BIN)
            .args(["scpi", lab.resource(), "--timeout", "20"])
            .env("HOME", home.path())
            .env("TERM", "xterm"),
    );
    term.wait_for("> ", 1);
    term.type_text("SLOW? 60000\r");
    // (The identity probe that decides the default error check comes first.)
    let got = std::iter::from_fn(|| arrived.recv_timeout(LIMIT).ok())
        .find(|m| !m.starts_with("*IDN?"))
        .expect("the query reached the instrument");
    assert!(got.starts_with("SLOW? 60000"), "{got}");
    term.type_text("\x03");
    term.wait_for("cancelled; the device was cleared", 1);
    term.wait_for("> ", 2);
    term.type_text("*IDN?\r");
    term.wait_for(IDENTITY, 1);
    term.type_text("\\quit\r");
    let status = child.wait_within(LIMIT);
    assert!(
        status.success(),
        "{status:?}\n{}",
        term.seen.lock().unwrap()
    );
    let history = std::fs::read_to_string(home.path().join(".radbench_scpi_history")).unwrap();
    for line in ["SLOW? 60000", "*IDN?", "\\quit"] {
        assert!(history.contains(line), "{line}: {history}");
    }
}
