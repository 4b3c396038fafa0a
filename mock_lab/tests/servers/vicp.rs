//! VICP server over real loopback sockets, with a minimal hand-written client.

use crate::common;

use std::os::fd::AsRawFd;
use std::time::Duration;

use common::{block_header, bounded, expected_block, instrument};
use mock_lab::server::{loopback_any, vicp};
use tokio::io::{AsyncReadExt, AsyncWriteExt};
use tokio::net::TcpStream;

struct Client {
    s: TcpStream,
    seq: u8,
}

impl Client {
    async fn connect(addr: std::net::SocketAddr) -> Client {
        Client {
            s: bounded(TcpStream::connect(addr)).await.unwrap(),
            seq: 1,
        }
    }

    async fn send_block(&mut self, op: u8, payload: &[u8]) {
        let mut msg = vec![op, 1, self.seq, 0];
        msg.extend_from_slice(&(payload.len() as u32).to_be_bytes());
        msg.extend_from_slice(payload);
        bounded(self.s.write_all(&msg)).await.unwrap();
    }

    async fn send(&mut self, text: &[u8]) -> u8 {
        self.send_block(0x81, text).await;
        let seq = self.seq;
        self.seq = if self.seq == 255 { 1 } else { self.seq + 1 };
        seq
    }

    /// Reads blocks until EOI, checking each carries `seq`.
    async fn read(&mut self, seq: u8) -> Vec<u8> {
        let mut out = Vec::new();
        loop {
            let mut h = [0u8; 8];
            bounded(self.s.read_exact(&mut h)).await.unwrap();
            assert_eq!(h[0] & 0x80, 0x80, "DATA bit");
            assert_eq!(h[1], 1, "version");
            assert_eq!(h[2], seq, "sequence number echoed");
            let len = u32::from_be_bytes(h[4..8].try_into().unwrap()) as usize;
            let start = out.len();
            out.resize(start + len, 0);
            bounded(self.s.read_exact(&mut out[start..])).await.unwrap();
            if h[0] & 0x01 != 0 {
                return out;
            }
        }
    }

    async fn query(&mut self, text: &str) -> Vec<u8> {
        let seq = self.send(text.as_bytes()).await;
        self.read(seq).await
    }
}

async fn server() -> (
    mock_lab::server::ServerHandle,
    std::sync::Arc<mock_lab::faults::Faults>,
) {
    let (handler, options, faults) = instrument();
    (
        vicp::serve(loopback_any(), handler, options).await.unwrap(),
        faults,
    )
}

#[tokio::test]
async fn golden_identity_and_nonzero_sequence_for_old_clients() {
    let (server, _) = server().await;
    let mut c = Client::connect(server.local_addr()).await;
    c.s.write_all(b"\x81\x01\x01\x00\x00\x00\x00\x05*IDN?")
        .await
        .unwrap();
    let mut reply = [0u8; 8 + 24];
    bounded(c.s.read_exact(&mut reply)).await.unwrap();
    assert_eq!(&reply[..8], b"\x81\x01\x01\x00\x00\x00\x00\x18");
    assert_eq!(&reply[8..], b"MOCK_LAB,LOOPBACK,0,0.1\n");
    // A VICP 1 client numbering everything 0 still gets non-zero numbers back.
    c.s.write_all(b"\x81\x01\x00\x00\x00\x00\x00\x05*OPC?")
        .await
        .unwrap();
    let mut reply = [0u8; 10];
    bounded(c.s.read_exact(&mut reply)).await.unwrap();
    assert_ne!(reply[2], 0);
    assert_eq!(&reply[8..], b"1\n");
}

#[tokio::test]
async fn message_in_several_blocks_and_64_mb_each_way() {
    let (server, _) = server().await;
    let mut c = Client::connect(server.local_addr()).await;
    let len = 64 << 20;
    let mut upload = b"DATA ".to_vec();
    upload.extend_from_slice(&block_header(len));
    upload.extend(expected_block(len, 11));
    let chunks: Vec<&[u8]> = upload.chunks(3 << 20).collect();
    for (i, chunk) in chunks.iter().enumerate() {
        let op = if i + 1 == chunks.len() { 0x81 } else { 0x80 };
        c.send_block(op, chunk).await;
    }
    c.seq += 1;
    let reply = c.query("DATA?").await;
    let header = block_header(len);
    assert!(reply[header.len()..header.len() + len] == expected_block(len, 11)[..]);
    c.send(format!("DATA:GEN {len},12").as_bytes()).await;
    let reply = c.query("DATA?").await;
    assert!(reply[header.len()..header.len() + len] == expected_block(len, 12)[..]);
}

#[tokio::test]
async fn a_clear_that_lands_before_the_instrument_starts_a_slow_query_still_ends_it() {
    // The clear is sent once SLOW? has reached the instrument, which begins it 300 ms later.
    let (handler, entered) = common::LateStart::handler(Duration::from_millis(300));
    let server = vicp::serve(
        loopback_any(),
        handler,
        mock_lab::server::ServerOptions::default(),
    )
    .await
    .unwrap();
    let mut c = Client::connect(server.local_addr()).await;
    c.send(b"SLOW? 60000").await;
    let _entered = common::reached(entered).await;
    c.send_block(0x90, b"").await;
    // Without the clear passed on again, SLOW? would hold the instrument for its full minute.
    let reply = tokio::time::timeout(Duration::from_secs(10), c.query("ECHO fresh"))
        .await
        .expect("the slow query was cut short");
    assert_eq!(reply, b"fresh\n");
}

#[tokio::test]
async fn device_clear_and_both_serial_polls() {
    let (server, _) = server().await;
    let mut c = Client::connect(server.local_addr()).await;
    // Clear cuts a slow query short; nothing stale arrives afterwards.
    c.send(b"SLOW? 60000").await;
    c.send_block(0x90, b"").await;
    assert_eq!(c.query("ECHO fresh").await, b"fresh\n");
    // In-band serial poll.
    assert_eq!(c.query("BOGUS;*OPC?").await, b"1\n");
    c.send_block(0x84, b"").await;
    let seq = c.seq;
    assert_eq!(
        c.read(seq).await,
        [0x04],
        "error queue bit in the status byte"
    );
    // Out-of-band serial poll (VICP 1a): urgent 'S' in, urgent status byte out.
    let fd = c.s.as_raw_fd();
    // SAFETY: sends one byte from a valid buffer on a live socket.
    let sent = unsafe { libc::send(fd, b"S".as_ptr().cast(), 1, libc::MSG_OOB) };
    assert_eq!(sent, 1);
    let stb = bounded(async {
        loop {
            c.s.readable().await.unwrap();
            let mut byte = 0u8;
            // SAFETY: reads one byte into a valid local.
            let n = unsafe {
                libc::recv(
                    fd,
                    (&mut byte as *mut u8).cast(),
                    1,
                    libc::MSG_OOB | libc::MSG_DONTWAIT,
                )
            };
            if n == 1 {
                return byte;
            }
            tokio::task::yield_now().await;
        }
    })
    .await;
    assert_eq!(stb, 0x04);
    // The in-band nudge: an empty non-EOI block with an older sequence number.
    let mut nudge = [0u8; 8];
    bounded(c.s.read_exact(&mut nudge)).await.unwrap();
    assert_eq!(nudge, [0x80, 1, seq - 1, 0, 0, 0, 0, 0]);
    assert_eq!(c.query("SYST:ERR?").await, b"-113,\"Undefined header\"\n");
}

#[tokio::test]
async fn several_clients_vanished_client_and_faults() {
    let (server, faults) = server().await;
    let mut gone = Client::connect(server.local_addr()).await;
    gone.s
        .write_all(b"\x81\x01\x01\x00\x00\x10\x00\x00DATA #")
        .await
        .unwrap();
    drop(gone);
    let mut tasks = Vec::new();
    for i in 0..6 {
        let addr = server.local_addr();
        tasks.push(tokio::spawn(async move {
            let mut c = Client::connect(addr).await;
            for j in 0..10 {
                let text = format!("v{i}m{j}");
                assert_eq!(
                    c.query(&format!("ECHO {text}")).await,
                    format!("{text}\n").as_bytes()
                );
            }
        }));
    }
    for task in tasks {
        bounded(task).await.unwrap();
    }
    let mut c = Client::connect(server.local_addr()).await;
    faults.set_byte_segments(true);
    faults.set_reply_delay(Duration::from_millis(10));
    assert_eq!(c.query("ECHO trickle").await, b"trickle\n");
    faults.clear();
    faults.swallow_next_reply();
    c.send(b"ECHO lost").await;
    let mut byte = [0u8; 1];
    assert!(
        tokio::time::timeout(Duration::from_millis(200), c.s.read(&mut byte))
            .await
            .is_err()
    );
    assert_eq!(c.query("ECHO next").await, b"next\n");
    faults.drop_next_reply_midway();
    c.send(b"DATA:GEN 3000;DATA?").await;
    let mut got = Vec::new();
    bounded(c.s.read_to_end(&mut got)).await.unwrap();
    assert!(!got.is_empty() && got.len() < 3000);
}

/// A client that closes (FIN, then RST) must not leave the server's out-of-band serial poll
/// task spinning: tokio keeps "read closed" readiness set for good, and a task that loops on it
/// holds a worker thread forever. With one worker, the first spinning task would stall every
/// later connection; each round here gives that race another chance (without the fix, the
/// pyvicp interop suite hung on this about one run in three).
#[test]
fn closed_clients_leave_the_server_responsive() {
    use std::io::{Read, Write};
    use std::net::Shutdown;

    let runtime = tokio::runtime::Builder::new_multi_thread()
        .worker_threads(2)
        .enable_all()
        .build()
        .unwrap();
    let (server, _faults) = runtime.block_on(server());
    let addr = server.local_addr();
    let rounds = || -> Result<(), String> {
        for round in 0..200 {
            let mut s = std::net::TcpStream::connect(addr).map_err(|e| e.to_string())?;
            s.set_read_timeout(Some(Duration::from_secs(10))).unwrap();
            s.write_all(b"\x81\x01\x01\x00\x00\x00\x00\x05*OPC?")
                .map_err(|e| e.to_string())?;
            let mut reply = [0u8; 10];
            s.read_exact(&mut reply)
                .map_err(|e| format!("round {round}: no reply within 10 s ({e})"))?;
            if &reply != b"\x81\x01\x01\x00\x00\x00\x00\x021\n" {
                return Err(format!("round {round}: reply {reply:02x?}"));
            }
            // Closed as pyvicp closes: shutdown both ways, then close with zero linger (RST).
            s.shutdown(Shutdown::Both).map_err(|e| e.to_string())?;
            set_zero_linger(&s);
        }
        Ok(())
    };
    let outcome = rounds();
    drop(server);
    // A stuck worker would make an ordinary drop of the runtime wait for it forever.
    runtime.shutdown_background();
    outcome.unwrap();
}

/// SO_LINGER with a zero timeout: `close` then resets the connection instead of a FIN handshake.
fn set_zero_linger(s: &std::net::TcpStream) {
    let linger = libc::linger {
        l_onoff: 1,
        l_linger: 0,
    };
    // SAFETY: setsockopt on a live socket with a pointer to a correctly sized local.
    let rc = unsafe {
        libc::setsockopt(
            s.as_raw_fd(),
            libc::SOL_SOCKET,
            libc::SO_LINGER,
            (&linger as *const libc::linger).cast(),
            std::mem::size_of::<libc::linger>() as libc::socklen_t,
        )
    };
    assert_eq!(rc, 0, "setsockopt(SO_LINGER)");
}

#[tokio::test]
async fn blocks_ending_in_whitespace_reach_the_awg_byte_exact() {
    let (handler, options) = common::awg();
    let server = vicp::serve(loopback_any(), handler, options).await.unwrap();
    let mut client = Client::connect(server.local_addr()).await;
    for exchange in common::whitespace_tail_uploads() {
        let seq = client.send(&exchange.message).await;
        if let Some(reply) = exchange.reply {
            assert_eq!(client.read(seq).await, format!("{reply}\n").into_bytes());
        }
    }
}
