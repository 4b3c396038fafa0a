//! `radbench scpi` and `idn` bounded in total (issue 40): against a peer that sends half a block
//! and stalls, one that never answers and one that floods a reply that never ends, on each
//! network transport, the command exits 3 within its documented total
//! (`--connect-timeout + commands × --timeout + 2 s + bytes received / --min-rate`,
//! docs/io-timeouts.md), its memory bounded by the reply cap (64 MiB), measured as the child's
//! own peak resident set (`wait4`).
//!
//! The peers are the transport fault matrix's (tests/support/io_faults/peers.rs): each does its
//! protocol's handshake, takes one request and commits its fault (the cap itself, on a small
//! configured limit, is that matrix's `data_that_never_ends_the_message` on every transport).

#[allow(dead_code)]
#[path = "../support/io_faults/peers.rs"]
mod peers;

use peers::Fault;
use std::time::Instant;

/// The length the peers announce or pass (their matrix's largest message).
const LIMIT: usize = 1 << 20;

const BIN: &str = env!("CARGO_BIN_EXE_radbench");

/// The reply cap of `scpi` and `idn` (src/bin/radbench/cli/bounded.rs).
const CAP: u64 = 64 << 20;

#[derive(Debug, Clone, Copy)]
enum Proto {
    Socket,
    Vxi11,
    Hislip,
    Vicp,
}

/// Starts the peer; the resource string that reaches it.
async fn peer(proto: Proto, fault: Fault) -> String {
    let listener = tokio::net::TcpListener::bind("127.0.0.1:0").await.unwrap();
    let port = listener.local_addr().unwrap().port();
    match proto {
        Proto::Socket => {
            tokio::spawn(peers::socket(listener, fault));
            format!("TCPIP::127.0.0.1::{port}::SOCKET")
        }
        Proto::Vicp => {
            tokio::spawn(peers::vicp(listener, fault));
            format!("VICP::127.0.0.1,{port}")
        }
        Proto::Hislip => {
            tokio::spawn(peers::hislip(listener, fault));
            format!("TCPIP::127.0.0.1::hislip0,{port}::INSTR")
        }
        Proto::Vxi11 => {
            tokio::spawn(peers::vxi11(listener, fault));
            format!("TCPIP::127.0.0.1,{port}::inst0::INSTR")
        }
    }
}

/// Runs radbench with `args`; (exit code, stderr, seconds, peak resident set in bytes).
async fn measured(args: Vec<String>) -> (i32, String, f64, u64) {
    measured_with_input(args, "").await
}

/// [`measured`] with `input` on standard input (lines at the interactive prompt).
async fn measured_with_input(args: Vec<String>, input: &'static str) -> (i32, String, f64, u64) {
    tokio::task::spawn_blocking(move || {
        use std::os::unix::process::ExitStatusExt;
        let t = Instant::now();
        // Waited for below with wait4, which gives the child's own peak resident set.
        #[allow(clippy::zombie_processes)]
        let mut child = std::process::Command::new(BIN)
            .args(&args)
            .stdin(std::process::Stdio::piped())
            .stdout(std::process::Stdio::null())
            .stderr(std::process::Stdio::piped())
            .spawn()
            .unwrap();
        let pid = child.id() as libc::pid_t;
        let mut stdin = child.stdin.take().unwrap();
        std::io::Write::write_all(&mut stdin, input.as_bytes()).unwrap();
        drop(stdin);
        let mut stderr = child.stderr.unwrap();
        let reader = std::thread::spawn(move || {
            let mut text = String::new();
            let _ = std::io::Read::read_to_string(&mut stderr, &mut text);
            text
        });
        let mut status = 0;
        // SAFETY: rusage is plain data, filled by wait4 for this child only.
        let mut usage: libc::rusage = unsafe { std::mem::zeroed() };
        // SAFETY: waits for the child this function spawned; the pointers are valid.
        let rc = unsafe { libc::wait4(pid, &mut status, 0, &mut usage) };
        assert_eq!(rc, pid, "wait4");
        let seconds = t.elapsed().as_secs_f64();
        let code = std::process::ExitStatus::from_raw(status)
            .code()
            .unwrap_or(-1);
        let err = reader.join().unwrap();
        (code, err, seconds, usage.ru_maxrss as u64 * 1024)
    })
    .await
    .unwrap()
}

/// `radbench scpi RESOURCE DATA?` (the identity probe and the error checks as by default) with a
/// 1 s reply timeout.
async fn bounded(proto: Proto, fault: Fault) {
    let resource = peer(proto, fault).await;
    let what = format!("{proto:?} {fault:?}");
    let connect = 2.0;
    let read = 1.0;
    let rate = 10e6;
    let args: Vec<String> = [
        "scpi",
        "--connect-timeout",
        "2",
        "--timeout",
        "1",
        "--min-rate",
        "10",
        &resource,
        "DATA?",
    ]
    .iter()
    .map(|s| s.to_string())
    .collect();
    let (code, err, seconds, peak) = measured(args).await;
    assert_eq!(code, 3, "{what}: {err}");
    // The documented total: one command; a flood earns at most one capped reply.
    let earned = match fault {
        Fault::NeverEnds => CAP as f64 / rate,
        _ => (LIMIT as f64) / rate,
    };
    let total = connect + read + 2.0 + earned;
    eprintln!(
        "{what}: exit {code} after {seconds:.2} s (total {total:.1} s), peak {} MiB",
        peak >> 20
    );
    // Process start and exit on a loaded machine, on top of the total.
    assert!(
        seconds < total + 1.5,
        "{what}: {seconds:.1} s, total {total:.1} s: {err}"
    );
    // One reply at most twice the cap (the receive buffer and the reassembled message), plus
    // the program itself.
    assert!(
        peak < 2 * CAP + (96 << 20),
        "{what}: peak {} MiB",
        peak >> 20
    );
}

macro_rules! cases {
    ($($name:ident: $proto:ident $fault:ident;)*) => {$(
        #[tokio::test(flavor = "multi_thread", worker_threads = 2)]
        async fn $name() {
            bounded(Proto::$proto, Fault::$fault).await;
        }
    )*};
}

cases! {
    scpi_on_a_socket_half_block_then_stall: Socket AnnouncedNeverArrives;
    scpi_on_vxi11_half_block_then_stall: Vxi11 AnnouncedNeverArrives;
    scpi_on_hislip_half_block_then_stall: Hislip AnnouncedNeverArrives;
    scpi_on_vicp_half_block_then_stall: Vicp AnnouncedNeverArrives;
    scpi_on_a_socket_flood: Socket NeverEnds;
    scpi_on_vxi11_flood: Vxi11 NeverEnds;
    scpi_on_hislip_flood: Hislip NeverEnds;
    scpi_on_vicp_flood: Vicp NeverEnds;
    scpi_on_vxi11_no_reply: Vxi11 NoReply;
    scpi_on_hislip_no_reply: Hislip NoReply;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn idn_on_a_stalled_hislip_peer_gives_up_within_its_total() {
    let resource = peer(Proto::Hislip, Fault::AnnouncedNeverArrives).await;
    let args = ["idn", "--connect-timeout", "2", "--timeout", "1", &resource]
        .iter()
        .map(|s| s.to_string())
        .collect();
    let (code, err, seconds, _) = measured(args).await;
    assert_eq!(code, 3, "{err}");
    assert!(
        seconds < 2.0 + 1.0 + 2.0 + 0.2 + 1.5,
        "{seconds:.1} s: {err}"
    );
}

/// The case of issue 40: an instrument that identifies itself, then stalls. Over HiSLIP the
/// query's timeout, the device clear and the error check each waited their own time (14 s with
/// `--timeout 2` before the total); the total cuts it at `--connect-timeout + --timeout + 2 s`.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn scpi_on_a_stalled_hislip_instrument_gives_up_at_its_total() {
    let lab = super::support::start_lab().await;
    let resource = lab
        .endpoint("awg", mock_lab::server::launch::Transport::Hislip)
        .unwrap()
        .resource;
    lab.awg_faults
        .stall_for(std::time::Duration::from_secs(600));
    let args = [
        "scpi",
        "--connect-timeout",
        "1",
        "--timeout",
        "2",
        &resource,
        "*IDN?",
    ]
    .iter()
    .map(|s| s.to_string())
    .collect();
    let (code, err, seconds, _) = measured(args).await;
    lab.awg_faults.clear();
    assert_eq!(code, 3, "{err}");
    assert!(err.contains("gave up after 5.0 s in all"), "{err}");
    assert!(seconds < 5.0 + 1.5, "{seconds:.1} s: {err}");
}

fn strings(args: &[&str]) -> Vec<String> {
    args.iter().map(|s| s.to_string()).collect()
}

/// The interactive `scpi`'s connection (the identity probe and the error queue) has one
/// exchange's total: a peer that takes the first request (here the error queue's, with
/// `--check-errors`) and then sends half a block and stalls ends it with exit 3 within
/// `--connect-timeout + --timeout + 2 s`, before the prompt.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn interactive_scpi_connecting_to_a_stalled_peer_gives_up_within_its_total() {
    for proto in [Proto::Hislip, Proto::Vxi11] {
        let resource = peer(proto, Fault::AnnouncedNeverArrives).await;
        let args = strings(&[
            "scpi",
            "--connect-timeout",
            "2",
            "--timeout",
            "1",
            "--check-errors",
            &resource,
        ]);
        let (code, err, seconds, _) = measured_with_input(args, "*IDN?\n").await;
        // The probe's own timeout, the peer gone after it, or the total: exit 3 in time.
        assert_eq!(code, 3, "{proto:?}: {err}");
        let total = 2.0 + 1.0 + 2.0 + LIMIT as f64 / 10e6;
        assert!(seconds < total + 1.5, "{proto:?}: {seconds:.1} s: {err}");
    }
}

/// A line at the interactive prompt has one exchange's total: a stalled or flooding reply is
/// abandoned at `--connect-timeout + --timeout + 2 s` (plus the bytes at `--min-rate`), the
/// device cleared within `--timeout + 2 s`, and the prompt goes on to the next line (here the end
/// of input), memory under the reply cap.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_line_at_the_scpi_prompt_gives_up_within_its_total_and_the_prompt_goes_on() {
    for (proto, fault) in [
        (Proto::Hislip, Fault::AnnouncedNeverArrives),
        (Proto::Vxi11, Fault::NoReply),
        (Proto::Vxi11, Fault::NeverEnds),
        (Proto::Socket, Fault::NeverEnds),
    ] {
        let what = format!("{proto:?} {fault:?}");
        let resource = peer(proto, fault).await;
        let args = strings(&[
            "scpi",
            "--connect-timeout",
            "2",
            "--timeout",
            "1",
            "--min-rate",
            "10",
            "--no-check-errors",
            &resource,
        ]);
        let (code, err, seconds, peak) = measured_with_input(args, "DATA?\n").await;
        // The line's error is told (its read timeout, or the total that cut it), and the prompt
        // goes on to the end of input.
        assert_eq!(code, 0, "{what}: {err}");
        assert!(err.contains("error: "), "{what}: {err}");
        let earned = match fault {
            Fault::NeverEnds => CAP as f64 / 10e6,
            _ => LIMIT as f64 / 10e6,
        };
        let total = (2.0 + 1.0 + 2.0 + earned) + (1.0 + 2.0);
        eprintln!(
            "{what}: {seconds:.2} s (total {total:.1} s), peak {} MiB",
            peak >> 20
        );
        assert!(seconds < total + 1.5, "{what}: {seconds:.1} s: {err}");
        assert!(
            peak < 2 * CAP + (96 << 20),
            "{what}: peak {} MiB",
            peak >> 20
        );
    }
}

/// `doctor` has a total for its checks (40 s, src/measure/doctor/bounds.rs `CHECKS_TOTAL`): a bench
/// whose AWG floods a reply that never ends and whose scope sends half a block and stalls ends
/// with exit 3 within it, memory under the catalog's largest message.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn doctor_on_a_flooding_awg_and_a_stalled_scope_ends_within_its_total() {
    let awg = peer(Proto::Hislip, Fault::NeverEnds).await;
    let scope = peer(Proto::Vicp, Fault::AnnouncedNeverArrives).await;
    let dir = tempfile::tempdir().unwrap();
    let bench = dir.path().join("bench.toml");
    std::fs::write(
        &bench,
        format!(
            "[awg]\nmodel = \"keysight-m8195a\"\nresource = \"{awg}\"\n\
             [scope]\nmodel = \"lecroy-labmaster10zi-a\"\nresource = \"{scope}\"\n"
        ),
    )
    .unwrap();
    let args = strings(&["doctor", "--bench", bench.to_str().unwrap()]);
    let (code, err, seconds, peak) = measured(args).await;
    assert_eq!(code, 3, "{err}");
    assert!(
        err.contains("awg.reachable") || err.contains("awg.identity"),
        "{err}"
    );
    assert!(seconds < 40.0 + 1.5, "{seconds:.1} s: {err}");
    assert!(peak < 2 * CAP + (96 << 20), "peak {} MiB", peak >> 20);
}
