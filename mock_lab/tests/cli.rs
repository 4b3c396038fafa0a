//! The `mock-lab` binary: one JSON line naming every endpoint, and a clean stop on stdin EOF.

mod common;

use std::io::{BufRead, BufReader, Write};
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

#[test]
fn serve_json_lists_every_endpoint_and_stops_on_stdin_eof() {
    let mut child = Command::new(env!("CARGO_BIN_EXE_mock-lab"))
        .args(["serve", "--json"])
        .stdin(Stdio::piped())
        .stdout(Stdio::piped())
        .spawn()
        .expect("mock-lab starts");
    let mut line = String::new();
    BufReader::new(child.stdout.take().unwrap())
        .read_line(&mut line)
        .unwrap();
    let listing: serde_json::Value = serde_json::from_str(&line).expect("one JSON line");
    let endpoints = listing["endpoints"].as_array().unwrap();
    let transports: Vec<&str> = endpoints
        .iter()
        .map(|e| e["transport"].as_str().unwrap())
        .collect();
    assert_eq!(transports, ["raw", "vxi11", "hislip", "vicp", "serial"]);
    for e in endpoints {
        assert_eq!(e["instrument"], "loopback");
        assert!(e["resource"].as_str().unwrap().ends_with("INSTR") || e["transport"] == "raw");
    }
    // The raw endpoint answers.
    let raw = endpoints[0]["address"].as_str().unwrap();
    let mut s = std::net::TcpStream::connect(raw).unwrap();
    s.set_read_timeout(Some(common::LIMIT)).unwrap();
    s.write_all(b"*IDN?\n").unwrap();
    let mut reply = String::new();
    BufReader::new(&s).read_line(&mut reply).unwrap();
    assert_eq!(reply, "MOCK_LAB,LOOPBACK,0,0.1\n");
    // End of stdin stops the server.
    drop(child.stdin.take());
    let deadline = Instant::now() + common::LIMIT;
    let status = loop {
        if let Some(status) = child.try_wait().unwrap() {
            break status;
        }
        assert!(
            Instant::now() < deadline,
            "mock-lab did not stop on stdin EOF"
        );
        std::thread::sleep(Duration::from_millis(20));
    };
    assert!(status.success());
}

#[test]
fn bad_options_fail_with_a_message() {
    let out = Command::new(env!("CARGO_BIN_EXE_mock-lab"))
        .args(["serve", "--max-message-size", "10"])
        .stdin(Stdio::null())
        .output()
        .unwrap();
    assert!(!out.status.success());
    assert!(String::from_utf8_lossy(&out.stderr).contains("--max-message-size"));
}

#[test]
fn ignore_stdin_keeps_serving_after_stdin_closes() {
    let mut child = Command::new(env!("CARGO_BIN_EXE_mock-lab"))
        .args(["serve", "--json", "--ignore-stdin"])
        .stdin(Stdio::null())
        .stdout(Stdio::piped())
        .spawn()
        .expect("mock-lab starts");
    let mut line = String::new();
    BufReader::new(child.stdout.take().unwrap())
        .read_line(&mut line)
        .unwrap();
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
    child.kill().unwrap();
    child.wait().unwrap();
}
