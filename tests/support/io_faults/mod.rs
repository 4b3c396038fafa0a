//! The fault matrix: each transport against each [`Fault`] of a peer written here, over real
//! loopback sockets (a pseudo-terminal for serial). Every fault must end in its documented error
//! (docs/io-timeouts.md) within the documented bound, with the memory radbench allocates bounded
//! by the largest message, and no panic. Time is checked only as "within bound plus a generous
//! margin": the numbers are never asserted as speed.
#![allow(dead_code)]

pub mod peers;

pub use peers::Fault;
use radbench::transport::{CodecError, Link, LinkError, LinkOptions, Timeouts};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::time::Duration;

/// The largest message in these tests (also serial's own limit).
pub const LIMIT: usize = 1 << 20;
/// The read timeout.
pub const READ: Duration = Duration::from_millis(300);
/// The slowest healthy rate: low, so that any deadline still stretched by an announced length
/// (1 MiB = 10.5 s) or by stale replies would overrun the margin below.
pub const RATE: u64 = 100_000;
/// Added to every documented bound before a test gives up waiting.
pub const MARGIN: Duration = Duration::from_secs(5);
/// VXI-11 keeps this on top of the read timeout for the server's own reply.
const VXI11_GRACE: Duration = Duration::from_millis(500);

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Proto {
    Socket,
    Vxi11,
    Hislip,
    Vicp,
    Serial,
}

/// The error a fault must end in.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Expect {
    Timeout,
    Closed,
    /// A length over the limit, announced or reached ([`CodecError::TooLarge`]).
    TooLarge,
    /// Bytes that are not the protocol ([`LinkError::Codec`] of any kind).
    Undecodable,
    /// Raw socket and serial have no framing to break: garbage may be a reply, a timeout or an
    /// over-long message; only "no panic, bounded" is required.
    AnyOutcome,
}

/// The documented outcome; `None` where the fault cannot happen (raw socket and serial number no
/// replies, so there is no "older request" to answer).
pub fn expected(proto: Proto, fault: Fault) -> Option<Expect> {
    let unframed = matches!(proto, Proto::Socket | Proto::Serial);
    Some(match fault {
        Fault::NoReply | Fault::AnnouncedNeverArrives | Fault::Trickle => Expect::Timeout,
        Fault::CloseMidBlock => Expect::Closed,
        Fault::HugeLength if proto == Proto::Vxi11 => Expect::Undecodable,
        Fault::HugeLength => Expect::TooLarge,
        Fault::Garbage if unframed => Expect::AnyOutcome,
        Fault::Garbage => Expect::Undecodable,
        Fault::StaleForever if unframed => return None,
        Fault::StaleForever => Expect::Timeout,
        Fault::NeverEnds => Expect::TooLarge,
    })
}

/// The documented bound: read timeout + (bytes of the message received, at most the largest
/// message) / min rate, plus VXI-11's grace. Bytes a fault sends that earn time are at most
/// [`LIMIT`] (a message that never ends) or the garbage; everything else sends a few bytes.
pub fn bound(proto: Proto, fault: Fault) -> Duration {
    let grace = if proto == Proto::Vxi11 {
        VXI11_GRACE
    } else {
        Duration::ZERO
    };
    let counted = match fault {
        Fault::NeverEnds => LIMIT,
        Fault::Garbage => peers::GARBAGE_LEN,
        _ => 4096,
    };
    READ + grace + Duration::from_secs_f64(counted as f64 / RATE as f64)
}

/// What radbench may allocate while it reads: one receive buffer of at most the largest message
/// plus slack, and for transports that assemble a message from frames, the message as well.
pub fn memory_bound(proto: Proto) -> usize {
    match proto {
        Proto::Socket | Proto::Serial => LIMIT + (1 << 20),
        _ => 2 * LIMIT + (1 << 20),
    }
}

pub fn options() -> LinkOptions {
    LinkOptions {
        timeouts: Timeouts {
            connect: Duration::from_secs(5),
            read: READ,
            write: Duration::from_secs(5),
            min_rate_bytes_per_s: RATE,
        },
        max_message_bytes: LIMIT,
        ..LinkOptions::default()
    }
}

/// Measurements are process-wide: one fault at a time.
static ONE_AT_A_TIME: tokio::sync::Mutex<()> = tokio::sync::Mutex::const_new(());

/// A peer committing `fault`, and a link to it that has sent one request.
struct Setup {
    link: Link,
    stop: Arc<AtomicBool>,
    /// Fires when the serial peer's thread is done (it is never joined: a test that fails
    /// must not hang on it).
    serial_peer: Option<tokio::sync::oneshot::Receiver<()>>,
}

async fn setup(proto: Proto, fault: Fault) -> Setup {
    let stop = Arc::new(AtomicBool::new(false));
    if proto == Proto::Serial {
        let (master, slave) = serialport::TTYPort::pair().expect("pty pair");
        let peer_stop = stop.clone();
        let (done, finished) = tokio::sync::oneshot::channel();
        std::thread::spawn(move || {
            peers::serial(master, fault, peer_stop);
            let _ = done.send(());
        });
        let name = serialport::SerialPort::name(&slave).unwrap_or_default();
        let serial =
            radbench::transport::SerialLink::from_port(Box::new(slave), name.clone(), LIMIT)
                .expect("serial link");
        let resource = format!("ASRL{name}::INSTR").parse().expect("resource");
        return Setup {
            link: Link::from_serial(resource, serial, options()),
            stop,
            serial_peer: Some(finished),
        };
    }
    let listener = tokio::net::TcpListener::bind("127.0.0.1:0")
        .await
        .expect("listener");
    let port = listener.local_addr().unwrap().port();
    let text = match proto {
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
        Proto::Serial => unreachable!("handled above"),
    };
    let link = tokio::time::timeout(MARGIN, Link::open(text.parse().unwrap(), options()))
        .await
        .expect("connect within the margin")
        .unwrap_or_else(|e| panic!("{proto:?}: the handshake failed: {e}"));
    Setup {
        link,
        stop,
        serial_peer: None,
    }
}

fn as_expected(expect: Expect, result: &Result<bytes::Bytes, LinkError>) -> bool {
    matches!(
        (expect, result),
        (Expect::AnyOutcome, _)
            | (Expect::Timeout, Err(LinkError::Timeout { .. }))
            | (Expect::Closed, Err(LinkError::Closed { .. }))
            | (
                Expect::TooLarge,
                Err(LinkError::Codec {
                    source: CodecError::TooLarge { .. },
                    ..
                })
            )
            | (Expect::Undecodable, Err(LinkError::Codec { .. }))
    )
}

/// Runs one cell of the matrix.
pub async fn run(proto: Proto, fault: Fault) {
    let Some(expect) = expected(proto, fault) else {
        return;
    };
    let _one = ONE_AT_A_TIME.lock().await;
    let mut setup = setup(proto, fault).await;
    let sent = tokio::time::timeout(MARGIN, setup.link.write_message(&[b"QUERY?\n"]))
        .await
        .expect("the request is sent within the margin");
    let base = super::io_alloc_count::start();
    let limit = bound(proto, fault) + MARGIN;
    let result = match sent {
        Ok(()) => tokio::time::timeout(limit, setup.link.read_message())
            .await
            .unwrap_or_else(|_| {
                panic!(
                    "{proto:?} {fault:?}: no error within the documented bound {:?} (+ margin)",
                    bound(proto, fault)
                )
            }),
        // A peer that hangs up as soon as it has the request may be seen doing so while the
        // request is still draining (a serial line): the same outcome, noticed earlier.
        Err(e @ LinkError::Closed { .. }) if expect == Expect::Closed => Err(e),
        Err(e) => panic!("{proto:?} {fault:?}: the request failed: {e}"),
    };
    let grew = super::io_alloc_count::peak_above(base);
    let shown = match &result {
        Ok(m) => format!("a reply of {} bytes", m.len()),
        Err(e) => e.to_string(),
    };
    assert!(
        as_expected(expect, &result),
        "{proto:?} {fault:?}: expected {expect:?}, got {shown}"
    );
    assert!(
        grew <= memory_bound(proto),
        "{proto:?} {fault:?}: {grew} bytes allocated while reading (bound {}); {shown}",
        memory_bound(proto)
    );
    setup.stop.store(true, Ordering::SeqCst);
    drop(setup.link);
    if let Some(finished) = setup.serial_peer.take() {
        tokio::time::timeout(MARGIN, finished)
            .await
            .expect("the serial peer stops")
            .expect("the serial peer did not panic");
    }
}
