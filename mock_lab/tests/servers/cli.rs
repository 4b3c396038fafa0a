//! The `mock-lab` binary: one JSON line naming every endpoint, and a clean stop on stdin EOF.

use crate::common;
use crate::process_support;

use std::io::{BufRead, BufReader, Write};
use std::process::{Command, Stdio};

use process_support::{output_within, Spawned};

#[test]
fn serve_json_lists_every_endpoint_and_stops_on_stdin_eof() {
    let mut child = Spawned::new(
        Command::new(env!("CARGO_BIN_EXE_mock-lab"))
            .args(["serve", "--json"])
            .stdin(Stdio::piped())
            .stdout(Stdio::piped()),
    );
    let line = child.first_line_within(common::LIMIT);
    let listing: serde_json::Value = serde_json::from_str(&line).expect("one JSON line");
    let endpoints = listing["endpoints"].as_array().unwrap();
    let served: Vec<(&str, &str)> = endpoints
        .iter()
        .map(|e| {
            (
                e["instrument"].as_str().unwrap(),
                e["transport"].as_str().unwrap(),
            )
        })
        .collect();
    for expected in [
        ("awg", "raw"),
        ("awg", "hislip"),
        ("awg", "vxi11"),
        ("scope", "vicp"),
        ("scope", "vxi11"),
        ("tx", "serial"),
        ("rx", "serial"),
    ] {
        assert!(
            served.contains(&expected),
            "{expected:?} missing: {served:?}"
        );
    }
    assert!(listing["control"]
        .as_str()
        .unwrap()
        .starts_with("127.0.0.1:"));
    let loopback: Vec<&serde_json::Value> = endpoints
        .iter()
        .filter(|e| e["instrument"] == "loopback")
        .collect();
    let transports: Vec<&str> = loopback
        .iter()
        .map(|e| e["transport"].as_str().unwrap())
        .collect();
    assert_eq!(transports, ["raw", "vxi11", "hislip", "vicp", "serial"]);
    for e in &loopback {
        assert!(e["resource"].as_str().unwrap().ends_with("INSTR") || e["transport"] == "raw");
    }
    // The raw endpoint answers.
    let raw = loopback[0]["address"].as_str().unwrap();
    let mut s = std::net::TcpStream::connect(raw).unwrap();
    s.set_read_timeout(Some(common::LIMIT)).unwrap();
    s.write_all(b"*IDN?\n").unwrap();
    let mut reply = String::new();
    BufReader::new(&s).read_line(&mut reply).unwrap();
    assert_eq!(reply, "MOCK_LAB,LOOPBACK,0,0.1\n");
    // End of stdin stops the server.
    drop(child.stdin.take());
    let status = child.wait_within(common::LIMIT);
    assert!(status.success());
}

#[test]
fn bad_options_fail_with_a_message() {
    let out = output_within(
        Command::new(env!("CARGO_BIN_EXE_mock-lab")).args(["serve", "--max-message-size", "10"]),
        common::LIMIT,
    );
    assert!(!out.status.success());
    assert!(String::from_utf8_lossy(&out.stderr).contains("--max-message-size"));
}

#[test]
fn ignore_stdin_keeps_serving_after_stdin_closes() {
    let mut child = Spawned::new(
        Command::new(env!("CARGO_BIN_EXE_mock-lab"))
            .args(["serve", "--json", "--ignore-stdin"])
            .stdin(Stdio::null())
            .stdout(Stdio::piped()),
    );
    let line = child.first_line_within(common::LIMIT);
    let listing: serde_json::Value = serde_json::from_str(&line).unwrap();
    let raw = listing["endpoints"][0]["address"]
        .as_str()
        .unwrap()
        .to_string();
    // stdin was closed from the start; the server must still answer.
    let mut s = std::net::TcpStream::connect(&raw).unwrap();
    s.set_read_timeout(Some(common::LIMIT)).unwrap();
    s.write_all(b"*OPC?\n").unwrap();
    let mut reply = String::new();
    BufReader::new(&s).read_line(&mut reply).unwrap();
    assert_eq!(reply, "1\n");
    assert!(child.try_wait().unwrap().is_none(), "still running");
}

/// A spawned `mock-lab serve --json`, killed if the test ends early.
struct Served {
    child: Spawned,
    listing: serde_json::Value,
}

impl Served {
    fn start(args: &[&str]) -> Served {
        let mut child = Spawned::new(
            Command::new(env!("CARGO_BIN_EXE_mock-lab"))
                .arg("serve")
                .arg("--json")
                .args(args)
                .stdin(Stdio::piped())
                .stdout(Stdio::piped())
                .stderr(Stdio::null()),
        );
        let line = child.first_line_within(common::LIMIT);
        let listing = serde_json::from_str(&line).expect("one JSON line");
        Served { child, listing }
    }

    fn endpoint(&self, instrument: &str, transport: &str) -> serde_json::Value {
        self.listing["endpoints"]
            .as_array()
            .unwrap()
            .iter()
            .find(|e| e["instrument"] == instrument && e["transport"] == transport)
            .cloned()
            .unwrap()
    }

    fn signal(&self, signal: i32) {
        let pid = libc::pid_t::try_from(self.child.id()).unwrap();
        // SAFETY: sends a signal to our own child; no memory is involved.
        assert_eq!(unsafe { libc::kill(pid, signal) }, 0);
    }

    /// Waits (bounded) for the process to end; its exit status.
    fn wait(mut self) -> std::process::ExitStatus {
        self.child.wait_within(common::LIMIT)
    }
}

#[test]
fn serve_stops_on_sigint_and_sigterm_while_stdin_stays_open() {
    for (signal, flags) in [
        (libc::SIGTERM, &["--until-stdin-closes"][..]),
        (libc::SIGINT, &[][..]),
        (libc::SIGTERM, &["--ignore-stdin"][..]),
    ] {
        let served = Served::start(flags);
        let raw = served.endpoint("loopback", "raw")["address"]
            .as_str()
            .unwrap()
            .to_string();
        std::net::TcpStream::connect(&raw).expect("serving");
        served.signal(signal);
        // stdin is still open (the pipe is held by `served`): only the signal can stop it.
        let status = served.wait();
        assert!(status.success(), "signal {signal} {flags:?}: {status:?}");
        let err = std::net::TcpStream::connect(&raw).expect_err("stopped");
        assert_eq!(err.kind(), std::io::ErrorKind::ConnectionRefused);
    }
}

#[test]
fn the_scopes_other_endpoint_is_marked_inactive_and_refuses_at_once() {
    let served = Served::start(&[]);
    let vxi11 = served.endpoint("scope", "vxi11");
    assert_eq!(vxi11["active"], false);
    let reason = vxi11["reason"].as_str().unwrap();
    assert!(reason.contains("TCPIP (VICP)"), "{reason}");
    let vicp = served.endpoint("scope", "vicp");
    assert_eq!(vicp["active"], true);
    assert!(vicp.get("reason").is_none());
    let err = std::net::TcpStream::connect_timeout(
        &vxi11["address"].as_str().unwrap().parse().unwrap(),
        common::LIMIT,
    )
    .expect_err("a closed port refuses");
    assert_eq!(err.kind(), std::io::ErrorKind::ConnectionRefused);
    let served = Served::start(&["--scope-remote", "vxi11"]);
    assert_eq!(served.endpoint("scope", "vxi11")["active"], true);
    assert_eq!(served.endpoint("scope", "vicp")["active"], false);
}

/// Runs `mock-lab serve ARGS` expecting it to refuse at once; (exit code, stderr).
fn refused(args: &[&str]) -> (Option<i32>, String) {
    let out = output_within(
        Command::new(env!("CARGO_BIN_EXE_mock-lab"))
            .arg("serve")
            .args(args),
        common::LIMIT,
    );
    (
        out.status.code(),
        String::from_utf8_lossy(&out.stderr).into_owned(),
    )
}

#[test]
fn out_of_range_port_base_and_bad_scenes_are_bad_input() {
    for base in ["65535", "0", "65512"] {
        let (code, err) = refused(&["--port-base", base]);
        assert_eq!(code, Some(2), "{base}: {err}");
        assert!(
            err.contains("--port-base") && err.contains("1 ..= 65511"),
            "{err}"
        );
    }
    let dir = std::env::temp_dir().join(format!("mock-lab-cli-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    for (name, text, expected) in [
        (
            "three.toml",
            "[impairments]\ndc_offset_v = [0.0, 0.0, 0.1]\n",
            &["three.toml", "line 2", "dc_offset_v", "exactly 2 values"][..],
        ),
        (
            "huge.toml",
            "snr_db = 20\n\n[[targets]]\nrange_m = 1.0\namplitude = 1e300\n",
            &["huge.toml", "line 5", "targets[0].amplitude", "1e300"][..],
        ),
        (
            "escape.toml",
            "[[targets]]\nrange_m = \"\x1b]0;pwned\x07\"\n",
            &["escape.toml", "line 2", "\\x1b]0;pwned\\x07"][..],
        ),
    ] {
        let path = dir.join(name);
        std::fs::write(&path, text).unwrap();
        let (code, err) = refused(&["--scene", path.to_str().unwrap()]);
        assert_eq!(code, Some(2), "{err}");
        for part in expected {
            assert!(err.contains(part), "{part}: {err}");
        }
        assert!(
            !err.contains('\x1b'),
            "no raw escape reaches the terminal: {err:?}"
        );
    }
    let _ = std::fs::remove_dir_all(&dir);
}

fn protocol_fixture(name: &str) -> String {
    std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../tests/data/protocols")
        .join(name)
        .to_string_lossy()
        .into_owned()
}

/// Sends `request` on a serial device and reads its reply up to and including `end`, bounded.
fn serial_exchange(path: &str, request: &[u8], end: u8) -> Vec<u8> {
    use std::io::Read;
    let mut port = serialport::new(path, 115_200)
        .timeout(std::time::Duration::from_millis(200))
        .open()
        .expect("the module's pty opens");
    port.write_all(request).unwrap();
    let deadline = std::time::Instant::now() + common::LIMIT;
    let mut reply = Vec::new();
    let mut byte = [0u8; 1];
    while reply.last() != Some(&end) {
        assert!(
            std::time::Instant::now() < deadline,
            "no reply ending in {end:#04x}: {reply:?}"
        );
        if let Ok(1) = port.read(&mut byte) {
            reply.push(byte[0]);
        }
    }
    reply
}

#[test]
fn tx_model_serves_a_modules_own_protocol_and_line_terminator() {
    let served = Served::start(&["--tx-model", &protocol_fixture("acme_eband_tx.toml")]);
    let tx = served.endpoint("tx", "serial")["address"]
        .as_str()
        .unwrap()
        .to_string();
    // The fixture's words, ended by CR alone (no LF ever comes back).
    let reply = serial_exchange(&tx, b"#1 ID?\r", b'\r');
    let text = String::from_utf8_lossy(&reply);
    assert!(text.contains("GOTMIC-EBAND-TX-EMU"), "{text:?}");
    assert!(!text.contains('\n'), "{text:?}");
    // The receiver kept the built-in model: its LF-ended `*IDN?`.
    let rx = served.endpoint("rx", "serial")["address"]
        .as_str()
        .unwrap()
        .to_string();
    let reply = serial_exchange(&rx, b"*IDN?\n", b'\n');
    assert!(
        String::from_utf8_lossy(&reply).contains("GOTMIC-EBAND-RX-EMU"),
        "{reply:?}"
    );
    drop(served);

    let (code, err) = refused(&["--rx-model", "no-such-model.toml"]);
    assert_eq!(code, Some(2), "{err}");
    assert!(err.contains("no-such-model.toml"), "{err}");
}
