//! VXI-11 server over real loopback sockets, with a minimal hand-written RPC client.

use crate::common;

use std::net::SocketAddr;
use std::time::Duration;

use common::{block_header, bounded, expected_block, instrument};
use mock_lab::server::loopback_any;
use mock_lab::server::vxi11::{self, Vxi11Addresses};
use tokio::io::{AsyncReadExt, AsyncWriteExt};
use tokio::net::TcpStream;

const CORE: u32 = 0x0607AF;
const END: i32 = 0x08;

fn be(words: &[u32]) -> Vec<u8> {
    words.iter().flat_map(|w| w.to_be_bytes()).collect()
}

fn opaque(data: &[u8]) -> Vec<u8> {
    let mut out = be(&[data.len() as u32]);
    out.extend_from_slice(data);
    out.resize(out.len() + (4 - data.len() % 4) % 4, 0);
    out
}

struct Rpc {
    stream: TcpStream,
    xid: u32,
}

impl Rpc {
    async fn connect(addr: SocketAddr) -> Rpc {
        Rpc {
            stream: bounded(TcpStream::connect(addr)).await.unwrap(),
            xid: 1,
        }
    }

    /// Sends a call (in two fragments, to exercise reassembly) and returns the result words
    /// after the accepted-reply header, checking accept_stat SUCCESS.
    async fn call(&mut self, prog: u32, vers: u32, proc_: u32, args: &[u8]) -> Vec<u8> {
        self.xid += 1;
        let mut body = be(&[self.xid, 0, 2, prog, vers, proc_, 0, 0, 0, 0]);
        body.extend_from_slice(args);
        let split = body.len() / 2;
        let mut msg = be(&[split as u32]);
        msg.extend_from_slice(&body[..split]);
        msg.extend_from_slice(&be(&[0x8000_0000 | (body.len() - split) as u32]));
        msg.extend_from_slice(&body[split..]);
        bounded(self.stream.write_all(&msg)).await.unwrap();
        let reply = self.record().await;
        assert_eq!(&reply[..4], &self.xid.to_be_bytes(), "xid echoed");
        assert_eq!(
            &reply[4..24],
            &be(&[1, 0, 0, 0, 0])[..],
            "accepted, SUCCESS"
        );
        reply[24..].to_vec()
    }

    async fn record(&mut self) -> Vec<u8> {
        let mut out = Vec::new();
        loop {
            let mut mark = [0u8; 4];
            bounded(self.stream.read_exact(&mut mark)).await.unwrap();
            let mark = u32::from_be_bytes(mark);
            let start = out.len();
            out.resize(start + (mark & 0x7FFF_FFFF) as usize, 0);
            bounded(self.stream.read_exact(&mut out[start..]))
                .await
                .unwrap();
            if mark & 0x8000_0000 != 0 {
                return out;
            }
        }
    }
}

fn word(b: &[u8], i: usize) -> u32 {
    u32::from_be_bytes(b[i * 4..i * 4 + 4].try_into().unwrap())
}

struct Link {
    rpc: Rpc,
    lid: u32,
    abort_port: u16,
    max_recv: u32,
}

impl Link {
    async fn open(addr: SocketAddr) -> Link {
        let mut rpc = Rpc::connect(addr).await;
        let mut args = be(&[1234, 0, 10000]);
        args.extend(opaque(b"inst0"));
        let r = rpc.call(CORE, 1, 10, &args).await;
        assert_eq!(word(&r, 0), 0, "create_link error");
        Link {
            rpc,
            lid: word(&r, 1),
            abort_port: word(&r, 2) as u16,
            max_recv: word(&r, 3),
        }
    }

    async fn write(&mut self, data: &[u8]) {
        let chunks: Vec<&[u8]> = data.chunks(self.max_recv as usize).collect();
        for (i, chunk) in chunks.iter().enumerate() {
            let flags = if i + 1 == chunks.len() { END } else { 0 };
            let mut args = be(&[self.lid, 1000, 1000, flags as u32]);
            args.extend(opaque(chunk));
            let r = self.rpc.call(CORE, 1, 11, &args).await;
            assert_eq!((word(&r, 0), word(&r, 1)), (0, chunk.len() as u32));
        }
    }

    /// One device_read: (error, reason, data).
    async fn read_once(
        &mut self,
        size: u32,
        timeout_ms: u32,
        term: Option<u8>,
    ) -> (u32, u32, Vec<u8>) {
        let flags = if term.is_some() { 0x80 } else { 0 };
        let args = be(&[
            self.lid,
            size,
            timeout_ms,
            1000,
            flags,
            u32::from(term.unwrap_or(0)),
        ]);
        let r = self.rpc.call(CORE, 1, 12, &args).await;
        let len = word(&r, 2) as usize;
        (word(&r, 0), word(&r, 1), r[12..12 + len].to_vec())
    }

    async fn read(&mut self) -> Vec<u8> {
        let mut out = Vec::new();
        loop {
            let (error, reason, data) = self.read_once(1 << 20, 5000, None).await;
            assert_eq!(error, 0, "device_read error");
            out.extend(data);
            if reason & 4 != 0 {
                return out;
            }
        }
    }

    async fn generic(&mut self, proc_: u32) -> Vec<u8> {
        self.rpc
            .call(CORE, 1, proc_, &be(&[self.lid, 0, 1000, 1000]))
            .await
    }
}

async fn server() -> (
    mock_lab::server::ServerHandle,
    std::sync::Arc<mock_lab::faults::Faults>,
) {
    let (handler, options, faults) = instrument();
    let addrs = Vxi11Addresses {
        portmapper: Some(loopback_any()),
        ..Vxi11Addresses::loopback()
    };
    (vxi11::serve(addrs, handler, options).await.unwrap(), faults)
}

#[tokio::test]
async fn portmapper_reports_the_core_port() {
    let (server, _) = server().await;
    let mut pm = Rpc::connect(server.listener("portmapper").unwrap()).await;
    let r = pm.call(100_000, 2, 3, &be(&[CORE, 1, 6, 0])).await;
    assert_eq!(word(&r, 0), u32::from(server.local_addr().port()));
    let r = pm.call(100_000, 2, 3, &be(&[0x1234, 1, 6, 0])).await;
    assert_eq!(word(&r, 0), 0, "unknown program: port 0");
}

#[tokio::test]
async fn identity_readstb_clear_trigger_lock() {
    let (server, _) = server().await;
    let mut link = Link::open(server.local_addr()).await;
    assert_eq!(link.abort_port, server.listener("abort").unwrap().port());
    link.write(b"*IDN?\r\n").await;
    assert_eq!(link.read().await, b"MOCK_LAB,LOOPBACK,0,0.1\n");
    // termChar and requestSize reasons.
    link.write(b"ECHO abcd").await;
    let (_, reason, data) = link.read_once(1000, 1000, Some(b'b')).await;
    assert_eq!((reason, data.as_slice()), (2, &b"ab"[..]), "CHR");
    let (_, reason, data) = link.read_once(1, 1000, None).await;
    assert_eq!((reason, data.as_slice()), (1, &b"c"[..]), "REQCNT");
    let (_, reason, data) = link.read_once(100, 1000, None).await;
    assert_eq!((reason, data.as_slice()), (4, &b"d\n"[..]), "END");
    // Status byte with MAV while a response waits.
    link.write(b"BOGUS;*OPC?").await;
    let stb = loop {
        let r = link.generic(13).await;
        let stb = word(&r, 1);
        if stb & 0x10 != 0 {
            break stb;
        }
    };
    assert_eq!(stb & 0x14, 0x14, "MAV and error queue bit");
    assert_eq!(link.read().await, b"1\n");
    // Device clear drops a pending slow answer.
    link.write(b"SLOW? 60000").await;
    assert_eq!(word(&link.generic(15).await, 0), 0);
    let (error, _, _) = link.read_once(100, 100, None).await;
    assert_eq!(error, 15, "nothing to read after clear: I/O timeout");
    assert_eq!(word(&link.generic(14).await, 0), 0, "trigger");
    assert_eq!(word(&link.generic(16).await, 0), 0, "remote");
    // Lock: a second link is refused while the first holds it.
    assert_eq!(
        word(&link.rpc.call(CORE, 1, 18, &be(&[link.lid, 0, 0])).await, 0),
        0
    );
    let mut other = Link::open(server.local_addr()).await;
    let mut args = be(&[other.lid, 1000, 1000, END as u32]);
    args.extend(opaque(b"*IDN?"));
    assert_eq!(
        word(&other.rpc.call(CORE, 1, 11, &args).await, 0),
        11,
        "locked"
    );
    assert_eq!(
        word(&link.rpc.call(CORE, 1, 19, &be(&[link.lid])).await, 0),
        0
    );
    other.write(b"*OPC?").await;
    assert_eq!(other.read().await, b"1\n");
    assert_eq!(
        word(&link.rpc.call(CORE, 1, 23, &be(&[link.lid])).await, 0),
        0,
        "destroy_link"
    );
    assert_eq!(word(&link.generic(13).await, 0), 4, "link gone");
}

#[tokio::test]
async fn abort_channel_ends_a_waiting_read() {
    let (server, _) = server().await;
    let mut link = Link::open(server.local_addr()).await;
    link.write(b"SLOW? 60000").await;
    let abort_addr = server.listener("abort").unwrap();
    let lid = link.lid;
    let aborter = tokio::spawn(async move {
        let mut abort = Rpc::connect(abort_addr).await;
        // Abort until the read is waiting (the flag is consumed by the read).
        abort.call(0x0607B0, 1, 1, &be(&[lid])).await
    });
    let (error, _, _) = link.read_once(100, 20_000, None).await;
    assert_eq!(error, 23, "aborted");
    assert_eq!(word(&bounded(aborter).await.unwrap(), 0), 0);
    // The instrument is still busy; a device clear ends that too.
    assert_eq!(word(&link.generic(15).await, 0), 0);
    link.write(b"*OPC?").await;
    assert_eq!(link.read().await, b"1\n");
}

#[tokio::test]
async fn block_of_64_mb_each_way() {
    let (server, _) = server().await;
    let mut link = Link::open(server.local_addr()).await;
    let len = 64 << 20;
    link.write(format!("DATA:GEN {len},5").as_bytes()).await;
    link.write(b"DATA?").await;
    let reply = link.read().await;
    let header = block_header(len);
    assert!(reply[header.len()..header.len() + len] == expected_block(len, 5)[..]);
    let mut upload = b"DATA ".to_vec();
    upload.extend_from_slice(&header);
    upload.extend(expected_block(len, 6));
    upload.extend_from_slice(b"\n");
    link.max_recv = 4 << 20; // several device_write chunks, END on the last
    link.write(&upload).await;
    link.write(b"DATA?").await;
    let reply = link.read().await;
    assert!(reply[header.len()..header.len() + len] == expected_block(len, 6)[..]);
}

#[tokio::test]
async fn several_clients_and_a_vanished_one() {
    let (server, _) = server().await;
    let mut half = TcpStream::connect(server.local_addr()).await.unwrap();
    half.write_all(&be(&[0x8000_1000, 1, 0])).await.unwrap();
    drop(half);
    let mut tasks = Vec::new();
    for i in 0..6 {
        let addr = server.local_addr();
        tasks.push(tokio::spawn(async move {
            let mut link = Link::open(addr).await;
            for j in 0..10 {
                link.write(format!("ECHO l{i}m{j}").as_bytes()).await;
                assert_eq!(link.read().await, format!("l{i}m{j}\n").as_bytes());
            }
        }));
    }
    for task in tasks {
        bounded(task).await.unwrap();
    }
}

#[tokio::test]
async fn faults_apply_to_device_read() {
    let (server, faults) = server().await;
    let mut link = Link::open(server.local_addr()).await;
    faults.set_byte_segments(true);
    link.write(b"ECHO bytewise").await;
    assert_eq!(link.read().await, b"bytewise\n");
    faults.clear();
    faults.swallow_next_reply();
    link.write(b"ECHO lost").await;
    assert_eq!(
        link.read_once(100, 100, None).await.0,
        15,
        "never comes: I/O timeout"
    );
    link.write(b"ECHO next").await;
    assert_eq!(link.read().await, b"next\n");
    faults.set_reply_delay(Duration::from_millis(300));
    link.write(b"ECHO late").await;
    assert_eq!(
        link.read_once(100, 50, None).await.0,
        15,
        "delayed past the io_timeout"
    );
    assert_eq!(link.read().await, b"late\n");
    faults.clear();
    faults.drop_next_reply_midway();
    link.write(b"DATA:GEN 1000;DATA?").await;
    let args = be(&[link.lid, 1 << 20, 1000, 1000, 0, 0]);
    let mut call = be(&[
        0x8000_0000 | (40 + args.len() as u32),
        99,
        0,
        2,
        CORE,
        1,
        12,
        0,
        0,
        0,
        0,
    ]);
    call.extend(args);
    link.rpc.stream.write_all(&call).await.unwrap();
    let mut got = Vec::new();
    bounded(link.rpc.stream.read_to_end(&mut got))
        .await
        .unwrap();
    assert!(
        !got.is_empty() && got.len() < 1000,
        "half a reply, then closed"
    );
}

#[tokio::test]
async fn device_lock_with_waitlock_waits_for_the_release() {
    let (server, _) = server().await;
    let mut holder = Link::open(server.local_addr()).await;
    assert_eq!(
        word(
            &holder.rpc.call(CORE, 1, 18, &be(&[holder.lid, 0, 0])).await,
            0
        ),
        0
    );
    let mut waiter = Link::open(server.local_addr()).await;
    // Without waitlock: refused at once.
    assert_eq!(
        word(
            &waiter.rpc.call(CORE, 1, 18, &be(&[waiter.lid, 0, 0])).await,
            0
        ),
        11
    );
    // With waitlock and a long lock_timeout: granted once the holder lets go.
    let lid = waiter.lid;
    let pending = tokio::spawn(async move {
        let r = waiter.rpc.call(CORE, 1, 18, &be(&[lid, 1, 20_000])).await;
        // Keep the link (and its lock) alive: closing the connection would release it.
        (word(&r, 0), waiter)
    });
    assert_eq!(
        word(&holder.rpc.call(CORE, 1, 19, &be(&[holder.lid])).await, 0),
        0
    );
    let (granted, _waiter) = bounded(pending).await.unwrap();
    assert_eq!(granted, 0, "lock granted after release");
    // Now the first link waits briefly and gives up.
    let r = holder
        .rpc
        .call(CORE, 1, 18, &be(&[holder.lid, 1, 50]))
        .await;
    assert_eq!(word(&r, 0), 11, "lock_timeout expired");
}

#[tokio::test]
async fn blocks_ending_in_whitespace_reach_the_awg_byte_exact() {
    let (handler, options) = common::awg();
    let server = vxi11::serve(Vxi11Addresses::loopback(), handler, options)
        .await
        .unwrap();
    let mut link = Link::open(server.local_addr()).await;
    for exchange in common::whitespace_tail_uploads() {
        link.write(&exchange.message).await;
        if let Some(reply) = exchange.reply {
            assert_eq!(link.read().await, format!("{reply}\n").into_bytes());
        }
    }
}
