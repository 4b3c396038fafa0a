//! `radbench idn` and `radbench scpi` as a user runs them, against a mock_lab HiSLIP server.

use crate::io_support;
use crate::process_support;

use io_support::{bounded, start, start_serving, Proto};
use std::process::{Command, Output};

/// Runs the radbench binary off the async runtime; every run is bounded by the tool's own
/// timeouts (given on the command line) and by the test's limit.
async fn radbench(args: Vec<String>) -> Output {
    bounded(tokio::task::spawn_blocking(move || {
        process_support::output_within(
            Command::new(env!("CARGO_BIN_EXE_radbench")).args(&args),
            io_support::LIMIT,
        )
    }))
    .await
    .expect("the runner thread finished")
}

fn args(list: &[&str]) -> Vec<String> {
    list.iter().map(|s| s.to_string()).collect()
}

fn stdout(o: &Output) -> String {
    String::from_utf8_lossy(&o.stdout).into_owned()
}

fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn idn_prints_the_parsed_identity() {
    let bench = start(Proto::Hislip).await;
    let address = bench.resource.to_string();
    let out = radbench(args(&["idn", &address, "--timeout", "5"])).await;
    assert!(out.status.success(), "{}", stderr(&out));
    assert!(
        stdout(&out).contains("model:        LOOPBACK"),
        "{}",
        stdout(&out)
    );
    let out = radbench(args(&["idn", &address, "--json"])).await;
    let json: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(json["manufacturer"], "MOCK_LAB");
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn scpi_one_shot_saves_binary_and_journals() {
    let bench = start(Proto::Hislip).await;
    let address = bench.resource.to_string();
    let dir = tempfile::tempdir().unwrap();
    let journal = dir.path().join("io.jsonl");
    let saved = dir.path().join("block.bin");
    let out = radbench(args(&[
        "--trace-io",
        journal.to_str().unwrap(),
        "scpi",
        &address,
        "DATA:GEN 1000,5",
        "DATA?",
        "*OPC?",
        "--save-binary",
        saved.to_str().unwrap(),
        "--trace-io-keep-binary",
        "--check-errors",
    ]))
    .await;
    assert!(out.status.success(), "{}", stderr(&out));
    let text = stdout(&out);
    assert!(
        text.contains("binary block (definite): 1000 bytes"),
        "{text}"
    );
    assert!(text.lines().any(|l| l == "1"), "{text}");
    let expected = mock_lab::emulator::loopback::pseudo_random_bytes(1000, 5);
    assert_eq!(std::fs::read(&saved).unwrap(), expected);
    assert!(text.contains(&radbench::transport::sha256_hex(&expected)));

    let lines: Vec<serde_json::Value> = std::fs::read_to_string(&journal)
        .unwrap()
        .lines()
        .map(|l| serde_json::from_str(l).unwrap())
        .collect();
    assert_eq!(lines[0]["kind"], "connect");
    let writes: Vec<&str> = lines
        .iter()
        .filter(|l| l["direction"] == "write")
        .map(|l| l["text"].as_str().unwrap())
        .collect();
    // With --check-errors the queue is emptied before the first command.
    assert_eq!(writes[0], "SYST:ERR?\n");
    assert_eq!(writes[1], "DATA:GEN 1000,5\n");
    assert!(writes.contains(&"DATA?\n"));
    let binary = lines
        .iter()
        .find(|l| l["kind"] == "binary")
        .expect("a binary entry");
    assert_eq!(binary["direction"], "read");
    let kept = std::fs::read(binary["file"].as_str().unwrap()).unwrap();
    assert_eq!(&kept[..6], b"#41000");
    assert_eq!(
        binary["sha256"],
        radbench::transport::sha256_hex(&kept).as_str()
    );
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn refused_command_exits_3_with_the_device_error() {
    let bench = start(Proto::Hislip).await;
    let address = bench.resource.to_string();
    let out = radbench(args(&["scpi", &address, "BOGUS 1", "--check-errors"])).await;
    assert_eq!(out.status.code(), Some(3), "{}", stderr(&out));
    assert!(stderr(&out).contains("-113"), "{}", stderr(&out));
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn unanswered_query_shows_the_device_error_once_each() {
    for proto in [Proto::Hislip, Proto::Socket, Proto::Vxi11] {
        let bench = start(proto).await;
        let address = bench.resource.to_string();
        let out = radbench(args(&["scpi", &address, "BOGUS?", "--timeout", "0.3"])).await;
        let err = stderr(&out);
        assert_eq!(out.status.code(), Some(3), "{proto:?}: {err}");
        assert!(err.contains("no reply to `BOGUS?` within 300 ms"), "{err}");
        assert_eq!(err.matches("-113").count(), 1, "{err}");
    }
    // A link error names its cause once, not once per layer.
    let port = {
        let l = std::net::TcpListener::bind("127.0.0.1:0").unwrap();
        l.local_addr().unwrap().port()
    };
    let address = format!("TCPIP::127.0.0.1::{port}::SOCKET");
    let out = radbench(args(&["idn", &address, "--connect-timeout", "2"])).await;
    let err = stderr(&out);
    assert_eq!(err.matches("cannot connect").count(), 1, "{err}");
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn bad_address_exits_2_and_unreachable_exits_3() {
    let out = radbench(args(&["idn", "GPIB0::5::INSTR"])).await;
    assert_eq!(out.status.code(), Some(2));
    assert!(stderr(&out).contains("accepted forms"), "{}", stderr(&out));
    // A port nobody listens on.
    let port = {
        let l = std::net::TcpListener::bind("127.0.0.1:0").unwrap();
        l.local_addr().unwrap().port()
    };
    let address = format!("TCPIP::127.0.0.1::{port}::SOCKET");
    let out = radbench(args(&["idn", &address, "--connect-timeout", "2"])).await;
    assert_eq!(out.status.code(), Some(3), "{}", stderr(&out));
    assert!(stderr(&out).contains("cannot connect"), "{}", stderr(&out));
    let out = radbench(args(&["scpi", &address, "*IDN?", "--timeout", "0"])).await;
    assert_eq!(out.status.code(), Some(2), "{}", stderr(&out));
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn bench_io_moves_the_block_both_ways_and_reports_its_hash() {
    let socket = start(Proto::Socket).await;
    let vicp = start(Proto::Vicp).await;
    let (a, b) = (socket.resource.to_string(), vicp.resource.to_string());
    let out = radbench(args(&[
        "bench", "io", "--json", "--size", "300000", "--runs", "2", &a, &b,
    ]))
    .await;
    assert!(out.status.success(), "{}", stderr(&out));
    let json: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(json["bytes"], 300_000);
    // SHA-256 of 300 000 SplitMix64 bytes (seed 1), computed independently with numpy by
    // benches/compare_pyvisa.py's splitmix64_bytes.
    assert_eq!(
        json["payload_sha256"],
        "3ec3ac3878d0ee678cad2961c305fec0ce8ee56772049ce2ce92e283614f8a94"
    );
    let results = json["results"].as_array().unwrap();
    let seen: Vec<(&str, &str)> = results
        .iter()
        .map(|r| {
            (
                r["protocol"].as_str().unwrap(),
                r["direction"].as_str().unwrap(),
            )
        })
        .collect();
    assert_eq!(
        seen,
        [
            ("socket", "read"),
            ("socket", "write"),
            ("vicp", "read"),
            ("vicp", "write")
        ]
    );
    for r in results {
        assert_eq!(r["seconds"].as_array().unwrap().len(), 2);
        assert!(r["median_mb_s"].as_f64().unwrap() > 0.0);
    }
    // No timed run is bad input (exit 2).
    let out = radbench(args(&["bench", "io", "--runs", "0", &a])).await;
    assert_eq!(out.status.code(), Some(2), "{}", stderr(&out));
}

/// The LeCroy scope (the only VICP instrument) has no SCPI error queue: a query it refuses is
/// reported from its command error register `CMR?`, not as a timeout to raise.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_query_the_scope_refuses_is_read_from_its_command_register() {
    let scope = mock_lab::emulator::lecroy::Lecroy::embedded().expect("scope model");
    let bench = start_serving(Proto::Vicp, std::sync::Arc::new(scope)).await;
    let address = bench.resource.to_string();
    let out = radbench(args(&["scpi", &address, "SARA?", "--timeout", "0.5"])).await;
    let err = stderr(&out);
    assert_eq!(out.status.code(), Some(3), "{err}");
    assert!(err.contains("no reply to `SARA?` within 500 ms"), "{err}");
    assert!(
        err.contains("unrecognized command/query header"),
        "the CMR? code is not explained: {err}"
    );
    assert!(!err.contains("timed out"), "{err}");
    // A query it knows still answers on the same kind of session.
    let out = radbench(args(&["scpi", &address, "CHDR OFF", "INR?"])).await;
    assert!(out.status.success(), "{}", stderr(&out));
}

/// `bench io` on an instrument without the loopback commands (the AWG, one of the catalog's) is
/// refused at once, saying what `bench io` needs and how to start it, not after a timeout.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn bench_io_on_the_awg_reports_its_refusal() {
    let awg = mock_lab::emulator::m8195a::M8195a::embedded().expect("AWG model");
    let bench = start_serving(Proto::Hislip, std::sync::Arc::new(awg)).await;
    let address = bench.resource.to_string();
    let out = radbench(args(&[
        "bench",
        "io",
        "--size",
        "1000",
        "--runs",
        "1",
        "--timeout",
        "0.5",
        &address,
    ]))
    .await;
    let err = stderr(&out);
    assert_eq!(out.status.code(), Some(2), "{err}");
    assert!(err.contains("M8195A") || err.contains("m8195a"), "{err}");
    assert!(err.contains("DATA?"), "{err}");
    assert!(err.contains("mock-lab serve --with-loopback"), "{err}");
    assert!(
        !err.contains("timed out") && !err.contains("no reply"),
        "{err}"
    );
}

/// The Gotmic modules from `radbench idn` and `radbench scpi` on their serial resource: register
/// reads (no `?`) are read and printed, CRC is added once the module has it on, and a refused
/// request exits 3 with the module's error.
#[cfg(unix)]
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn gotmic_modules_from_idn_and_scpi() {
    use mock_lab::server::{serial, ServerOptions};
    let module = mock_lab::emulator::gotmic::Gotmic::rx_embedded().unwrap();
    let endpoint = serial::serve(
        std::sync::Arc::new(module),
        ServerOptions::with_faults(mock_lab::faults::Faults::new()),
    )
    .expect("pty endpoint starts");
    let address = format!("ASRL{}::INSTR", endpoint.device_path());
    let out = radbench(args(&["idn", &address, "--timeout", "10"])).await;
    assert!(out.status.success(), "{}", stderr(&out));
    assert!(
        stdout(&out).contains("GOTMIC-EBAND-RX-EMU"),
        "{}",
        stdout(&out)
    );

    let out = radbench(args(&[
        "scpi",
        &address,
        "R 03",
        "CRC ON",
        "W 03 0011",
        "R 03",
    ]))
    .await;
    assert!(out.status.success(), "{}", stderr(&out));
    let lines: Vec<String> = stdout(&out).lines().map(str::to_string).collect();
    assert_eq!(
        lines,
        ["OK 003F", "OK", "OK", "OK 0011"],
        "{}",
        stderr(&out)
    );

    // The module kept CRC on: a new process finds out and frames its requests.
    let out = radbench(args(&["idn", &address, "--timeout", "10"])).await;
    assert!(out.status.success(), "{}", stderr(&out));
    let out = radbench(args(&["scpi", &address, "R 03", "R 7F", "--timeout", "10"])).await;
    assert_eq!(out.status.code(), Some(3), "{}", stderr(&out));
    assert_eq!(stdout(&out).trim(), "OK 0011");
    assert!(
        stderr(&out).contains("unknown register"),
        "{}",
        stderr(&out)
    );
}

/// `radbench -v capture 2>log`: the log is plain text (colour only on a terminal).
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_log_written_to_a_file_has_no_colour_codes() {
    let dir = tempfile::tempdir().unwrap();
    let (code, _, err) = crate::support::radbench_in(
        Some(dir.path()),
        &["-vv", "capture", "--allow-rf", "--out", "c", "--force"],
    )
    .await;
    assert_eq!(code, 0, "{err}");
    assert!(
        err.contains("INFO") || err.contains("DEBUG"),
        "a log: {err}"
    );
    assert!(!err.contains('\u{1b}'), "no ANSI escape codes: {err:?}");
}

/// `radbench scpi AWG ":FREQ:RASTX 16e9"` (a typo): the AWG is one of the catalog's, so its error
/// queue is read by default, and the refusal fails the command (it used to exit 0 in silence).
/// An error an earlier session left in the queue is cleared first and named as such, not blamed
/// on the next command.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn scpi_reads_a_catalog_instruments_error_queue_by_default() {
    let lab = mock_lab_started().await;
    let awg = lab
        .endpoint("awg", mock_lab::server::launch::Transport::Hislip)
        .unwrap()
        .resource;
    let scpi = |args: &[&str]| {
        let mut all = vec!["scpi", awg.as_str()];
        all.extend_from_slice(args);
        let all: Vec<String> = all.iter().map(|s| s.to_string()).collect();
        async move {
            let refs: Vec<&str> = all.iter().map(String::as_str).collect();
            crate::support::radbench_in(None, &refs).await
        }
    };
    let (code, _, err) = scpi(&[":FREQ:RASTX 16e9"]).await;
    assert_eq!(
        code, 3,
        "the instrument refused (the exit code table): {err}"
    );
    assert!(
        err.contains(":FREQ:RASTX 16e9") && err.contains("-113"),
        "{err}"
    );

    // Left in the queue on purpose, then a good command: it succeeds, the old error is named.
    let (code, _, err) = scpi(&["--no-check-errors", ":FREQ:RASTX 16e9"]).await;
    assert_eq!(code, 0, "{err}");
    let (code, out, err) = scpi(&[":FREQ:RAST 60e9", ":FREQ:RAST?"]).await;
    assert_eq!(code, 0, "the good command is not blamed: {err}");
    assert!(out.contains("6"), "{out}");
    assert!(
        err.contains("from before these commands") && err.contains("-113"),
        "{err}"
    );
}

/// `radbench idn` on a LeCroy at its power-on settings (`COMM_HEADER SHORT`, replies
/// `*IDN MOCK_LAB,...`): the manufacturer is MOCK_LAB, not `*IDN MOCK_LAB`.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn idn_on_a_scope_with_response_headers_on() {
    let lab = mock_lab_started().await;
    let scope = lab
        .endpoint("scope", mock_lab::server::launch::Transport::Vicp)
        .unwrap()
        .resource;
    let (code, out, err) = crate::support::radbench_in(None, &["idn", &scope]).await;
    assert_eq!(code, 0, "{err}");
    let line = out
        .lines()
        .find(|l| l.starts_with("manufacturer:"))
        .unwrap_or_else(|| panic!("{out}"));
    assert!(!line.contains("*IDN"), "{line}");
    assert!(out.contains("model:"), "{out}");
}

/// The whole simulated bench on loopback (its AWG and scope with their catalog identities).
async fn mock_lab_started() -> mock_lab::lab::Lab {
    tokio::time::timeout(
        std::time::Duration::from_secs(10),
        mock_lab::lab::start(mock_lab::lab::LabOptions::default()),
    )
    .await
    .expect("the lab starts")
    .unwrap()
}
