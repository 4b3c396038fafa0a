//! A seeded fault injector between radbench and the mock_lab loopback instrument, on every TCP
//! transport (raw socket, VXI-11, HiSLIP, VICP): a proxy that cuts what passes into random
//! pieces, holds some of them back a little, and now and then drops the connection at a random
//! byte. Whatever it does, every operation ends within its bound, and every answer radbench
//! returns is the right one: a fault shows as a link error, never as a wrong or stale reply. Once
//! the faults stop, the same session works again.

use crate::io_support;

use io_support::{bounded, payload, start, Proto};
use mock_lab::emulator::loopback::IDENTITY;
use radbench::rng::SplitMix64;
use radbench::session::{BlockForm, Session, SessionError};
use radbench::transport::LinkError;
use std::net::SocketAddr;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::Arc;
use std::time::Duration;
use tokio::io::{AsyncReadExt, AsyncWriteExt};
use tokio::net::{TcpListener, TcpStream};

/// What the injector may do; switched off to check the session recovers.
struct Faults {
    hostile: AtomicBool,
    drops: AtomicU64,
}

const SEEDS: u64 = 6;
const ROUNDS: usize = 25;

/// Probability, per chunk passed on, that the connection is dropped there (in 1/1000).
const DROP_PER_MILLE: u64 = 15;

/// A proxy on 127.0.0.1 forwarding every connection to `upstream` through the injector.
async fn proxy(upstream: SocketAddr, seed: u64, faults: Arc<Faults>) -> SocketAddr {
    let listener = TcpListener::bind("127.0.0.1:0").await.unwrap();
    let addr = listener.local_addr().unwrap();
    tokio::spawn(async move {
        let mut connection = 0u64;
        while let Ok((client, _)) = listener.accept().await {
            connection += 1;
            let Ok(server) = TcpStream::connect(upstream).await else {
                continue;
            };
            let _ = client.set_nodelay(true);
            let _ = server.set_nodelay(true);
            let (cr, cw) = client.into_split();
            let (sr, sw) = server.into_split();
            let seed = seed ^ connection.wrapping_mul(0x9E37_79B9_7F4A_7C15);
            // A drop on either side ends the whole connection: the other direction's pump sees
            // its peer gone.
            tokio::spawn(pump(cr, sw, SplitMix64::new(seed), faults.clone()));
            tokio::spawn(pump(sr, cw, SplitMix64::new(!seed), faults.clone()));
        }
    });
    addr
}

/// Copies one direction, in random pieces with random short holds, dropping now and then.
async fn pump(
    mut from: tokio::net::tcp::OwnedReadHalf,
    mut to: tokio::net::tcp::OwnedWriteHalf,
    mut rng: SplitMix64,
    faults: Arc<Faults>,
) {
    let mut buf = vec![0u8; 64 << 10];
    loop {
        let n = match from.read(&mut buf).await {
            Ok(0) | Err(_) => return,
            Ok(n) => n,
        };
        let hostile = faults.hostile.load(Ordering::SeqCst);
        let mut rest = &buf[..n];
        if hostile && rng.next_u64() % 1000 < DROP_PER_MILLE {
            // Pass on a random part of this chunk, then drop the connection (both halves).
            let keep = (rng.next_u64() % (n as u64 + 1)) as usize;
            let _ = to.write_all(&rest[..keep]).await;
            faults.drops.fetch_add(1, Ordering::SeqCst);
            return;
        }
        while !rest.is_empty() {
            let piece = if hostile {
                1 + (rng.next_u64() % rest.len() as u64) as usize
            } else {
                rest.len()
            };
            if to.write_all(&rest[..piece]).await.is_err() {
                return;
            }
            rest = &rest[piece..];
            if hostile && rng.next_u64() % 8 == 0 {
                tokio::time::sleep(Duration::from_micros(rng.next_u64() % 2000)).await;
            }
        }
    }
}

/// A fault may only show as a link failure (closed, reset, timed out, reconnect refused).
fn is_link_failure(e: &SessionError) -> bool {
    matches!(
        e.link_error(),
        Some(
            LinkError::Closed { .. }
                | LinkError::Timeout { .. }
                | LinkError::Io { .. }
                | LinkError::Connect { .. }
        )
    )
}

fn check<T>(what: &str, result: Result<T, SessionError>, right: impl Fn(&T) -> bool) -> bool {
    match result {
        Ok(value) => {
            assert!(
                right(&value),
                "{what}: a wrong answer came back as a success"
            );
            true
        }
        Err(e) => {
            assert!(
                is_link_failure(&e),
                "{what}: a fault showed as something else than a link failure: {e}"
            );
            false
        }
    }
}

/// Runs seeded operations through the injector; every success must be exactly right.
async fn exercise(session: &mut Session, seed: u64, rounds: usize) -> usize {
    let mut rng = SplitMix64::new(seed);
    let mut good = 0;
    // Blocks whose write failed: their fate is unknown. Bytes of an abandoned connection may
    // still reach the instrument (whose store all connections share) after a later block was
    // stored on the new connection, so reading one of these back is the instrument's state, not
    // a stale reply. A block the instrument confirmed earlier never is.
    let mut unconfirmed: Vec<Vec<u8>> = Vec::new();
    for round in 0..rounds {
        match rng.next_u64() % 3 {
            0 => {
                let token = format!("token-{seed}-{round}");
                let result = bounded(session.query(&format!("ECHO {token}"))).await;
                good += usize::from(check("ECHO", result, |reply| *reply == token));
            }
            1 => {
                let len = 1024 + (rng.next_u64() % (64 << 10)) as usize;
                let data = payload(len, rng.next_u64());
                // Only a block the instrument confirmed holding (*OPC? after it) must come back.
                let stored = check(
                    "DATA",
                    bounded(session.write_block("DATA ", &data, BlockForm::Definite)).await,
                    |_| true,
                ) && check("*OPC?", bounded(session.opc()).await, |_| true);
                if stored {
                    let result = bounded(session.query_block("DATA?")).await;
                    good += usize::from(check("DATA?", result, |b| {
                        b.payload() == &data[..]
                            || unconfirmed.iter().any(|u| b.payload() == &u[..])
                    }));
                } else {
                    unconfirmed.push(data);
                }
            }
            _ => {
                let result = bounded(session.idn()).await;
                good += usize::from(check("*IDN?", result, |id| id.to_string() == IDENTITY));
            }
        }
    }
    good
}

async fn run(proto: Proto) {
    let bench = start(proto).await;
    let faults = Arc::new(Faults {
        hostile: AtomicBool::new(true),
        drops: AtomicU64::new(0),
    });
    let upstream: SocketAddr = bench.server.local_addr();
    let through = proxy(upstream, 0x5EED ^ proto as u64, faults.clone()).await;
    // The same resource, through the proxy.
    let via: radbench::address::Resource = match proto {
        Proto::Socket => format!("TCPIP::127.0.0.1::{}::SOCKET", through.port()),
        Proto::Hislip => format!("TCPIP::127.0.0.1::hislip0,{}::INSTR", through.port()),
        Proto::Vxi11 => format!("TCPIP::127.0.0.1,{}::inst0::INSTR", through.port()),
        Proto::Vicp => format!("VICP::127.0.0.1,{}", through.port()),
        Proto::Vxi11Portmapper => unreachable!("not run through the proxy"),
    }
    .parse()
    .unwrap();
    let options = io_support::options(&bench, Duration::from_secs(2));
    let mut good = 0;
    let mut session = None;
    for seed in 0..SEEDS {
        // Opening may itself meet a drop; try again, as a user would.
        let s = match session.take() {
            Some(s) => s,
            None => {
                match bounded(Session::open(via.clone(), options.clone(), None, "proxied")).await {
                    Ok(s) => s,
                    Err(e) => {
                        assert!(is_link_failure(&e), "{proto:?}: opening failed oddly: {e}");
                        continue;
                    }
                }
            }
        };
        let mut s = s;
        good += exercise(&mut s, seed, ROUNDS).await;
        session = Some(s);
    }
    // Most operations get through: a dropped connection costs the operation it hit, and the
    // next one reopens the link.
    assert!(
        good * 2 >= SEEDS as usize * ROUNDS,
        "{proto:?}: only {good} of {} operations got an answer through the injector",
        SEEDS as usize * ROUNDS
    );
    // Faults off: the session (reopened if it was lost) answers correctly again.
    faults.hostile.store(false, Ordering::SeqCst);
    let mut s = match session {
        Some(mut s) => {
            // Whatever the last fault left (a dirty or dropped link), start afresh.
            bounded(s.reconnect()).await.unwrap();
            s
        }
        None => bounded(Session::open(via, options, None, "proxied"))
            .await
            .unwrap(),
    };
    assert_eq!(bounded(s.idn()).await.unwrap().to_string(), IDENTITY);
    assert_eq!(bounded(s.query("ECHO calm")).await.unwrap(), "calm");
    eprintln!(
        "{proto:?}: {good} exact answers, {} connections dropped",
        faults.drops.load(Ordering::SeqCst)
    );
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn socket_through_the_injector() {
    run(Proto::Socket).await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn hislip_through_the_injector() {
    run(Proto::Hislip).await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn vxi11_through_the_injector() {
    run(Proto::Vxi11).await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn vicp_through_the_injector() {
    run(Proto::Vicp).await;
}
