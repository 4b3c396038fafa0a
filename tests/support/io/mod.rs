//! Shared loopback checks: radbench's clients against the mock_lab servers serving the generic
//! loopback instrument (`mock_lab::emulator::loopback`). Each `tests/io_<protocol>.rs` runs every
//! check for its protocol.
#![allow(dead_code)]

use mock_lab::emulator::loopback::{Loopback, IDENTITY};
use mock_lab::faults::Faults;
use mock_lab::server::{self, Handler, ServerHandle, ServerOptions};
use radbench::address::Resource;
use radbench::rng::SplitMix64;
use radbench::session::{BlockForm, Session, SessionError, SessionOptions};
use radbench::transport::{sha256_hex, Direction, LinkError, Progress, Timeouts};
use std::future::Future;
use std::sync::Arc;
use std::time::Duration;

/// Every wait in these tests is bounded by this.
pub const LIMIT: Duration = Duration::from_secs(60);

pub async fn bounded<T>(fut: impl Future<Output = T>) -> T {
    tokio::time::timeout(LIMIT, fut)
        .await
        .expect("operation did not finish within the test's time limit")
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Proto {
    Socket,
    Hislip,
    Vxi11,
    /// VXI-11 with the core port found through the portmapper.
    Vxi11Portmapper,
    Vicp,
}

/// A running mock server with its faults and the resource string that reaches it.
pub struct Bench {
    pub faults: Arc<Faults>,
    /// The portmapper's port when the test uses one instead of 111.
    pub portmapper_port: Option<u16>,
    pub resource: Resource,
    pub server: ServerHandle,
}

pub async fn start(proto: Proto) -> Bench {
    start_serving(proto, Arc::new(Loopback::new())).await
}

/// A mock server of `proto` serving `handler` (an emulated instrument).
pub async fn start_serving(proto: Proto, handler: Arc<dyn Handler>) -> Bench {
    let faults = Faults::new();
    let options = ServerOptions::with_faults(faults.clone());
    let any = server::loopback_any();
    let server = match proto {
        Proto::Socket => server::raw::serve(any, handler, options).await,
        Proto::Hislip => server::hislip::serve(any, handler, options).await,
        Proto::Vxi11 => {
            server::vxi11::serve(server::vxi11::Vxi11Addresses::loopback(), handler, options).await
        }
        Proto::Vxi11Portmapper => {
            let addrs = server::vxi11::Vxi11Addresses {
                portmapper: Some(any),
                ..server::vxi11::Vxi11Addresses::loopback()
            };
            server::vxi11::serve(addrs, handler, options).await
        }
        Proto::Vicp => server::vicp::serve(any, handler, options).await,
    }
    .expect("mock server starts");
    let port = server.local_addr().port();
    let text = match proto {
        Proto::Socket => format!("TCPIP::127.0.0.1::{port}::SOCKET"),
        Proto::Hislip => format!("TCPIP::127.0.0.1::hislip0,{port}::INSTR"),
        Proto::Vxi11 => format!("TCPIP::127.0.0.1,{port}::inst0::INSTR"),
        Proto::Vxi11Portmapper => "TCPIP::127.0.0.1::inst0::INSTR".to_string(),
        Proto::Vicp => format!("VICP::127.0.0.1,{port}"),
    };
    Bench {
        faults,
        portmapper_port: server.listener("portmapper").map(|a| a.port()),
        resource: text.parse().expect("valid resource"),
        server,
    }
}

pub fn options(bench: &Bench, read: Duration) -> SessionOptions {
    let mut o = SessionOptions {
        // The loopback instrument keeps a SCPI error queue on every transport, VICP included
        // (where the session would otherwise read a LeCroy scope's CMR? register).
        error_query: radbench::session::SCPI_ERROR_QUERY.into(),
        ..SessionOptions::default()
    };
    if let Some(port) = bench.portmapper_port {
        o.link.portmapper_port = port;
    }
    o.link.timeouts = Timeouts {
        connect: Duration::from_secs(5),
        read,
        write: Duration::from_secs(10),
        min_rate_bytes_per_s: 20_000_000,
    };
    o
}

pub async fn open(bench: &Bench, read: Duration) -> Session {
    bounded(Session::open(
        bench.resource.clone(),
        options(bench, read),
        None,
        "loopback",
    ))
    .await
    .expect("session opens")
}

/// Seeded pseudo-random payload (8 bytes per step, no per-byte work).
pub fn payload(len: usize, seed: u64) -> Vec<u8> {
    let mut rng = SplitMix64::new(seed);
    let mut out = Vec::with_capacity(len + 8);
    while out.len() < len {
        out.extend_from_slice(&rng.next_u64().to_le_bytes());
    }
    out.truncate(len);
    out
}

pub async fn check_idn(proto: Proto) {
    let bench = start(proto).await;
    let mut s = open(&bench, Duration::from_secs(5)).await;
    let id = bounded(s.idn()).await.unwrap();
    assert_eq!(id.to_string(), IDENTITY);
    assert_eq!(id.model, "LOOPBACK");
    bounded(s.opc()).await.unwrap();
    bounded(s.rst()).await.unwrap();
    bounded(s.cls()).await.unwrap();
    assert_eq!(bounded(s.query_i64("DATA:LEN?")).await.unwrap(), 0);
    assert_eq!(
        bounded(s.query_string("ECHO \"quoted\"")).await.unwrap(),
        "quoted"
    );
    bounded(s.close()).await.unwrap();
}

/// 64 MiB up as a definite block, back down, identical SHA-256.
pub async fn check_block_64mb(proto: Proto) {
    let bench = start(proto).await;
    let mut s = open(&bench, Duration::from_secs(10)).await;
    let len = 64 << 20;
    let data = payload(len, 0x5EED);
    let sent_hash = sha256_hex(&data);
    bounded(s.write_block("DATA ", &data, BlockForm::Definite))
        .await
        .unwrap();
    assert_eq!(bounded(s.query_i64("DATA:LEN?")).await.unwrap(), len as i64);
    // Progress is reported while the long block comes in.
    let reports = Arc::new(std::sync::Mutex::new(Vec::new()));
    let sink = Arc::clone(&reports);
    s.link_options_mut().progress = Some(Arc::new(move |p: Progress| {
        sink.lock().unwrap().push(p);
    }));
    let block = bounded(s.query_block("DATA?")).await.unwrap();
    assert_eq!(block.len(), len);
    assert_eq!(sha256_hex(block.payload()), sent_hash);
    let reports = std::mem::take(&mut *reports.lock().unwrap());
    assert!(
        !reports.is_empty(),
        "no progress reported for a 64 MiB read"
    );
    assert!(reports.iter().all(|p| p.direction == Direction::Read));
    assert!(reports.windows(2).all(|w| w[0].done < w[1].done));
    assert!(reports.last().unwrap().done <= len as u64 + 4096);
    assert!(bounded(s.errors()).await.unwrap().is_empty());
}

/// A block whose payload contains newlines and `#` survives both directions; an indefinite block
/// too where the transport has a message end (refused, not mangled, on a raw socket).
pub async fn check_small_blocks(proto: Proto) {
    let bench = start(proto).await;
    let mut s = open(&bench, Duration::from_secs(5)).await;
    let tricky = b"\n#9\n\r\n\"#0 \n".repeat(100);
    bounded(s.write_block(":DATA ", &tricky, BlockForm::Definite))
        .await
        .unwrap();
    let block = bounded(s.query_block("DATA?")).await.unwrap();
    assert_eq!(block.payload(), &tricky[..]);
    let result = bounded(s.write_block("DATA ", &tricky, BlockForm::Indefinite)).await;
    if proto == Proto::Socket {
        let err = result.unwrap_err();
        assert!(matches!(
            err.link_error(),
            Some(LinkError::IndefiniteBlockWithNewline { .. })
        ));
        bounded(s.write_block("DATA ", b"no newline here", BlockForm::Indefinite))
            .await
            .unwrap();
        let block = bounded(s.query_block("DATA?")).await.unwrap();
        assert_eq!(block.payload(), b"no newline here");
    } else {
        result.unwrap();
        let block = bounded(s.query_block("DATA?")).await.unwrap();
        assert_eq!(block.payload(), &tricky[..]);
    }
    // Replies trickling in one byte per segment are still whole messages.
    bench.faults.set_byte_segments(true);
    bounded(s.write_block("DATA ", b"a\nb", BlockForm::Definite))
        .await
        .unwrap();
    let block = bounded(s.query_block("DATA?")).await.unwrap();
    assert_eq!(block.payload(), b"a\nb");
    assert_eq!(bounded(s.idn()).await.unwrap().to_string(), IDENTITY);
}

/// A slow query whose reply is abandoned, an explicit device clear, then a fresh correct answer.
///
/// The query is abandoned by a short read timeout rather than cleared right after the write: on
/// HiSLIP the clear travels on the other channel and may overtake the query, and the mock server
/// (unlike the HiSLIP spec) still runs a query that arrives between AsyncDeviceClear and
/// DeviceClearComplete, whose late reply then carries the reset MessageID.
pub async fn check_device_clear(proto: Proto) {
    let bench = start(proto).await;
    let mut s = open(&bench, Duration::from_millis(200)).await;
    let err = bounded(s.query("SLOW? 2000")).await.unwrap_err();
    assert!(matches!(err.link_error(), Some(LinkError::Timeout { .. })));
    bounded(s.device_clear()).await.unwrap();
    s.link_options_mut().timeouts.read = Duration::from_secs(5);
    assert_eq!(bounded(s.idn()).await.unwrap().to_string(), IDENTITY);
    assert_eq!(bounded(s.query("ECHO after")).await.unwrap(), "after");
}

/// The status byte reports the error queue (bit 2) until it is drained; errors are typed.
pub async fn check_status_byte(proto: Proto) {
    let bench = start(proto).await;
    let mut s = open(&bench, Duration::from_secs(5)).await;
    assert_eq!(bounded(s.read_stb()).await.unwrap() & 0x04, 0);
    bounded(s.write("BOGUS:COMMAND 1")).await.unwrap();
    // A query round trip makes sure the command was processed before polling.
    bounded(s.opc()).await.unwrap();
    assert_eq!(bounded(s.read_stb()).await.unwrap() & 0x04, 0x04);
    let err = bounded(s.check_errors(Some("BOGUS:COMMAND 1")))
        .await
        .unwrap_err();
    let SessionError::Device { errors, .. } = &err else {
        panic!("expected a device error, got {err}");
    };
    assert_eq!(errors[0].code, -113);
    assert!(err.link_error().is_none());
    assert_eq!(bounded(s.read_stb()).await.unwrap() & 0x04, 0);
}

/// A read that times out is followed by a device clear, so the next query gets its own answer,
/// not the late one.
pub async fn check_timeout_then_fresh_answer(proto: Proto) {
    let bench = start(proto).await;
    let mut s = open(&bench, Duration::from_millis(300)).await;
    let err = bounded(s.query("SLOW? 1500")).await.unwrap_err();
    assert!(
        matches!(err.link_error(), Some(LinkError::Timeout { .. })),
        "{err}"
    );
    assert_eq!(bounded(s.query("ECHO fresh")).await.unwrap(), "fresh");
    // A reply that never comes.
    bench.faults.swallow_next_reply();
    let err = bounded(s.query("ECHO lost")).await.unwrap_err();
    assert!(
        matches!(err.link_error(), Some(LinkError::Timeout { .. })),
        "{err}"
    );
    assert_eq!(bounded(s.query("ECHO next")).await.unwrap(), "next");
    // A future dropped mid-operation leaves the link usable.
    let dropped = tokio::time::timeout(Duration::from_millis(50), s.query("SLOW? 1000")).await;
    assert!(dropped.is_err());
    assert_eq!(bounded(s.query("ECHO again")).await.unwrap(), "again");
}

/// A query the instrument refuses gets no reply (488.2): after the read timeout the session reads
/// the error queue and reports the refusal, not a bare timeout; the link stays usable.
pub async fn check_unanswered_query_is_a_refusal(proto: Proto) {
    let bench = start(proto).await;
    let mut s = open(&bench, Duration::from_millis(300)).await;
    let err = bounded(s.query("BOGUS:QUERY?")).await.unwrap_err();
    let SessionError::Unanswered { errors, query, .. } = &err else {
        panic!("expected the instrument's errors, got {err}");
    };
    assert_eq!(errors[0].code, -113, "{err}");
    assert_eq!(query, "BOGUS:QUERY?");
    assert!(
        err.to_string().contains("no reply to `BOGUS:QUERY?`"),
        "{err}"
    );
    assert_eq!(err.device_errors().map(|e| e.len()), Some(1));
    assert_eq!(err.kind(), radbench::transport::ErrorKind::FixInput);
    assert_eq!(bounded(s.query("ECHO next")).await.unwrap(), "next");
}

/// The server drops the connection in the middle of a block: a clear link error (not a hang, not
/// a timeout), then reconnect and carry on.
pub async fn check_dropped_connection(proto: Proto) {
    let bench = start(proto).await;
    let mut s = open(&bench, Duration::from_secs(5)).await;
    let data = payload(1 << 20, 3);
    bounded(s.write_block("DATA ", &data, BlockForm::Definite))
        .await
        .unwrap();
    bench.faults.drop_next_reply_midway();
    let err = bounded(s.query_block("DATA?")).await.unwrap_err();
    assert!(
        matches!(err.link_error(), Some(LinkError::Closed { .. })),
        "{err}"
    );
    assert_eq!(err.kind(), radbench::transport::ErrorKind::Retry);
    bounded(s.reconnect()).await.unwrap();
    let block = bounded(s.query_block("DATA?")).await.unwrap();
    assert_eq!(block.payload(), &data[..]);
}

/// A server that goes away entirely: connecting again fails with a clear error.
pub async fn check_server_gone(proto: Proto) {
    let mut bench = start(proto).await;
    let mut s = open(&bench, Duration::from_secs(1)).await;
    bench.server.shutdown();
    // Established connections may outlive the listener task; either way the next exchanges end
    // in a link error or still work, but never hang.
    let _ = bounded(s.idn()).await;
    let err = bounded(s.reconnect()).await.unwrap_err();
    assert!(matches!(
        err.link_error(),
        Some(LinkError::Connect { .. } | LinkError::Closed { .. })
    ));
}

/// Defines one `#[tokio::test]` per check for a protocol.
#[macro_export]
macro_rules! loopback_suite {
    ($proto:expr) => {
        #[tokio::test(flavor = "multi_thread", worker_threads = 2)]
        async fn idn_opc_rst_cls() {
            io_support::check_idn($proto).await;
        }
        #[tokio::test(flavor = "multi_thread", worker_threads = 2)]
        async fn block_of_64_mib_each_way() {
            io_support::check_block_64mb($proto).await;
        }
        #[tokio::test(flavor = "multi_thread", worker_threads = 2)]
        async fn small_blocks_with_newlines_and_byte_segments() {
            io_support::check_small_blocks($proto).await;
        }
        #[tokio::test(flavor = "multi_thread", worker_threads = 2)]
        async fn device_clear() {
            io_support::check_device_clear($proto).await;
        }
        #[tokio::test(flavor = "multi_thread", worker_threads = 2)]
        async fn status_byte_and_error_queue() {
            io_support::check_status_byte($proto).await;
        }
        #[tokio::test(flavor = "multi_thread", worker_threads = 2)]
        async fn timeout_then_fresh_answer() {
            io_support::check_timeout_then_fresh_answer($proto).await;
        }
        #[tokio::test(flavor = "multi_thread", worker_threads = 2)]
        async fn unanswered_query_is_a_refusal() {
            io_support::check_unanswered_query_is_a_refusal($proto).await;
        }
        #[tokio::test(flavor = "multi_thread", worker_threads = 2)]
        async fn dropped_connection_is_a_clear_error() {
            io_support::check_dropped_connection($proto).await;
        }
        #[tokio::test(flavor = "multi_thread", worker_threads = 2)]
        async fn server_gone() {
            io_support::check_server_gone($proto).await;
        }
    };
}
