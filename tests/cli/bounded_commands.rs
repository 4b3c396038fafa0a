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

/// The reply cap of `scpi` and `idn` (src/cli/bounded.rs).
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
    tokio::task::spawn_blocking(move || {
        use std::os::unix::process::ExitStatusExt;
        let t = Instant::now();
        // Waited for below with wait4, which gives the child's own peak resident set.
        #[allow(clippy::zombie_processes)]
        let child = std::process::Command::new(BIN)
            .args(&args)
            .stdin(std::process::Stdio::null())
            .stdout(std::process::Stdio::null())
            .stderr(std::process::Stdio::piped())
            .spawn()
            .unwrap();
        let pid = child.id() as libc::pid_t;
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
