//! Misbehaving peers, one per transport, written here (not in mock_lab): each does the protocol's
//! opening handshake properly, takes one request, and then commits one [`Fault`].

use radbench::rng::SplitMix64;
use radbench::transport::hislip::{self as hislip, msg};
use radbench::transport::vicp;
use radbench::transport::vxi11::{record_mark, XdrWriter};
use std::io::{Read, Write};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::time::Duration;
use tokio::io::{AsyncReadExt, AsyncWriteExt};
use tokio::net::{TcpListener, TcpStream};

/// What the peer does once it has the request.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Fault {
    /// Never answers (keeps the connection open).
    NoReply,
    /// Starts a 1000-byte reply, sends half of it, closes the connection.
    CloseMidBlock,
    /// A header announces a reply just under the limit; ten bytes follow, then nothing.
    AnnouncedNeverArrives,
    /// A length field far beyond any limit (4 GB where the format can say it).
    HugeLength,
    /// Seeded random bytes, then nothing.
    Garbage,
    /// A reply that never ends, one byte per 50 ms.
    Trickle,
    /// Replies to other (older) requests, as fast as it can, forever.
    StaleForever,
    /// The right reply's data, as fast as it can, never marked as the end of the message.
    NeverEnds,
}

pub const ALL_FAULTS: [Fault; 8] = [
    Fault::NoReply,
    Fault::CloseMidBlock,
    Fault::AnnouncedNeverArrives,
    Fault::HugeLength,
    Fault::Garbage,
    Fault::Trickle,
    Fault::StaleForever,
    Fault::NeverEnds,
];

/// Bytes of garbage a [`Fault::Garbage`] peer sends.
pub const GARBAGE_LEN: usize = 4096;
const TRICKLE_PERIOD: Duration = Duration::from_millis(50);
const CHUNK: usize = 64 << 10;

pub fn garbage() -> Vec<u8> {
    let mut rng = SplitMix64::new(0x6A7BA6E);
    let mut out = Vec::with_capacity(GARBAGE_LEN);
    while out.len() < GARBAGE_LEN {
        out.extend_from_slice(&rng.next_u64().to_le_bytes());
    }
    // Framed transports: make the first header's fixed fields wrong, as garbage would have them
    // (no "HS" prologue, VICP version not 1).
    out[0] = 0x7E;
    out[1] = 0x55;
    out
}

/// Reads from the peer's side until the client goes away (keeps a connection open).
async fn hold(stream: &mut TcpStream) {
    let mut sink = [0u8; 4096];
    while matches!(stream.read(&mut sink).await, Ok(n) if n > 0) {}
}

/// Sends `unit()` over and over until the client goes away.
async fn flood(stream: &mut TcpStream, mut unit: impl FnMut() -> Vec<u8>) {
    loop {
        if stream.write_all(&unit()).await.is_err() {
            return;
        }
    }
}

async fn trickle(stream: &mut TcpStream, head: &[u8]) {
    if stream.write_all(head).await.is_err() {
        return;
    }
    loop {
        tokio::time::sleep(TRICKLE_PERIOD).await;
        if stream.write_all(b"x").await.is_err() {
            return;
        }
    }
}

// ---------------------------------------------------------------- raw socket

pub async fn socket(listener: TcpListener, fault: Fault) {
    let Ok((mut s, _)) = listener.accept().await else {
        return;
    };
    let mut byte = [0u8; 1];
    while s.read(&mut byte).await.is_ok_and(|n| n == 1) && byte[0] != b'\n' {}
    let limit = super::LIMIT;
    match fault {
        Fault::NoReply | Fault::StaleForever => hold(&mut s).await,
        Fault::CloseMidBlock => {
            let _ = s.write_all(b"#41000").await;
            let _ = s.write_all(&[b'x'; 500]).await;
        }
        Fault::AnnouncedNeverArrives => {
            let head = format!("#7{:07}0123456789", limit - 100);
            let _ = s.write_all(head.as_bytes()).await;
            hold(&mut s).await;
        }
        Fault::HugeLength => {
            let _ = s.write_all(b"#9999999999").await;
            hold(&mut s).await;
        }
        Fault::Garbage => {
            let _ = s.write_all(&garbage()).await;
            hold(&mut s).await;
        }
        Fault::Trickle => trickle(&mut s, b"reply ").await,
        Fault::NeverEnds => flood(&mut s, || vec![b'a'; CHUNK]).await,
    }
}

// ---------------------------------------------------------------- VICP

async fn vicp_request(s: &mut TcpStream) -> Option<u8> {
    let mut head = [0u8; vicp::HEADER_LEN];
    s.read_exact(&mut head).await.ok()?;
    let h = vicp::Header::parse(&head).ok()?;
    let mut body = vec![0u8; h.len as usize];
    s.read_exact(&mut body).await.ok()?;
    Some(h.seq)
}

fn vicp_block(op: u8, seq: u8, payload: &[u8]) -> Vec<u8> {
    let mut out = vicp::Header::new(op, seq, payload.len() as u32)
        .encode()
        .to_vec();
    out.extend_from_slice(payload);
    out
}

pub async fn vicp(listener: TcpListener, fault: Fault) {
    let Ok((mut s, _)) = listener.accept().await else {
        return;
    };
    let Some(seq) = vicp_request(&mut s).await else {
        return;
    };
    let data_end = vicp::op::DATA | vicp::op::EOI;
    match fault {
        Fault::NoReply => hold(&mut s).await,
        Fault::CloseMidBlock => {
            let head = vicp::Header::new(data_end, seq, 1000).encode();
            let _ = s.write_all(&head).await;
            let _ = s.write_all(&[b'x'; 500]).await;
        }
        Fault::AnnouncedNeverArrives => {
            let head = vicp::Header::new(data_end, seq, (super::LIMIT - 100) as u32).encode();
            let _ = s.write_all(&head).await;
            let _ = s.write_all(b"0123456789").await;
            hold(&mut s).await;
        }
        Fault::HugeLength => {
            let head = vicp::Header::new(data_end, seq, u32::MAX).encode();
            let _ = s.write_all(&head).await;
            hold(&mut s).await;
        }
        Fault::Garbage => {
            let _ = s.write_all(&garbage()).await;
            hold(&mut s).await;
        }
        Fault::Trickle => {
            let head = vicp::Header::new(data_end, seq, 1_000_000).encode();
            trickle(&mut s, &head).await;
        }
        Fault::StaleForever => {
            let stale = seq.wrapping_add(100).max(1);
            flood(&mut s, || vicp_block(data_end, stale, b"old reply\n")).await;
        }
        Fault::NeverEnds => {
            let block = vicp_block(vicp::op::DATA, seq, &[b'a'; CHUNK]);
            flood(&mut s, || block.clone()).await;
        }
    }
}

// ---------------------------------------------------------------- HiSLIP

async fn hislip_frame(s: &mut TcpStream) -> Option<hislip::Frame> {
    let mut head = [0u8; hislip::HEADER_LEN];
    s.read_exact(&mut head).await.ok()?;
    let header = hislip::Header::parse(&head).ok()?;
    let mut payload = vec![0u8; header.len as usize];
    s.read_exact(&mut payload).await.ok()?;
    Some(hislip::Frame {
        header,
        payload: payload.into(),
    })
}

fn hislip_header(msg_type: u8, id: u32, len: u64) -> Vec<u8> {
    hislip::Header::new(msg_type, 0, id, len).encode().to_vec()
}

pub async fn hislip(listener: TcpListener, fault: Fault) {
    // Sync channel: Initialize.
    let Ok((mut sync, _)) = listener.accept().await else {
        return;
    };
    if hislip_frame(&mut sync).await.is_none() {
        return;
    }
    let session = 7u32;
    let init = hislip::encode_frame(msg::INITIALIZE_RESPONSE, 0, (0x0100 << 16) | session, &[]);
    if sync.write_all(&init).await.is_err() {
        return;
    }
    // Async channel: AsyncInitialize and AsyncMaxMsgSize.
    let Ok((mut async_, _)) = listener.accept().await else {
        return;
    };
    if hislip_frame(&mut async_).await.is_none() {
        return;
    }
    let reply = hislip::encode_frame(msg::ASYNC_INITIALIZE_RESPONSE, 0, 0x5242, &[]);
    if async_.write_all(&reply).await.is_err() || hislip_frame(&mut async_).await.is_none() {
        return;
    }
    let size = (super::LIMIT as u64).to_be_bytes();
    let reply = hislip::encode_frame(msg::ASYNC_MAX_MSG_SIZE_RESPONSE, 0, 0, &size);
    if async_.write_all(&reply).await.is_err() {
        return;
    }
    // The request: its MessageID is the one the reply must carry.
    let Some(request) = hislip_frame(&mut sync).await else {
        return;
    };
    let id = request.header.param;
    let s = &mut sync;
    match fault {
        Fault::NoReply => hold(s).await,
        Fault::CloseMidBlock => {
            let _ = s.write_all(&hislip_header(msg::DATA_END, id, 1000)).await;
            let _ = s.write_all(&[b'x'; 500]).await;
        }
        Fault::AnnouncedNeverArrives => {
            let head = hislip_header(msg::DATA_END, id, super::LIMIT as u64 - 100);
            let _ = s.write_all(&head).await;
            let _ = s.write_all(b"0123456789").await;
            hold(s).await;
        }
        Fault::HugeLength => {
            let _ = s
                .write_all(&hislip_header(msg::DATA_END, id, 4 << 30))
                .await;
            hold(s).await;
        }
        Fault::Garbage => {
            let _ = s.write_all(&garbage()).await;
            hold(s).await;
        }
        Fault::Trickle => trickle(s, &hislip_header(msg::DATA_END, id, 1_000_000)).await,
        Fault::StaleForever => {
            let stale = id.wrapping_sub(2);
            flood(s, || {
                hislip::encode_frame(msg::DATA_END, 0, stale, b"old reply\n")
            })
            .await;
        }
        Fault::NeverEnds => {
            let frame = hislip::encode_frame(msg::DATA, 0, id, &[b'a'; CHUNK]);
            flood(s, || frame.clone()).await;
        }
    }
}

// ---------------------------------------------------------------- VXI-11

/// One RPC call: (xid, procedure).
async fn rpc_call(s: &mut TcpStream) -> Option<(u32, u32)> {
    let mut mark = [0u8; 4];
    s.read_exact(&mut mark).await.ok()?;
    let len = (u32::from_be_bytes(mark) & 0x7FFF_FFFF) as usize;
    let mut body = vec![0u8; len];
    s.read_exact(&mut body).await.ok()?;
    let word = |i: usize| u32::from_be_bytes(body[4 * i..4 * i + 4].try_into().unwrap());
    (len >= 24).then(|| (word(0), word(5)))
}

/// A successful RPC reply record carrying `results`.
fn rpc_reply(xid: u32, results: &[u8]) -> Vec<u8> {
    let mut w = XdrWriter::default();
    w.u32(xid).u32(1).u32(0).u32(0).u32(0).u32(0);
    w.buf.extend_from_slice(results);
    let mut out = record_mark(w.buf.len() as u32, true).to_vec();
    out.extend_from_slice(&w.buf);
    out
}

fn read_results(reason: u32, data: &[u8]) -> Vec<u8> {
    let mut w = XdrWriter::default();
    w.u32(0).u32(reason).opaque(data);
    w.buf
}

pub async fn vxi11(listener: TcpListener, fault: Fault) {
    let Ok((mut s, _)) = listener.accept().await else {
        return;
    };
    // create_link, then device_write: answered properly.
    let Some((xid, _)) = rpc_call(&mut s).await else {
        return;
    };
    let mut link = XdrWriter::default();
    link.u32(0).u32(1).u32(1).u32(1 << 20);
    if s.write_all(&rpc_reply(xid, &link.buf)).await.is_err() {
        return;
    }
    let Some((xid, _)) = rpc_call(&mut s).await else {
        return;
    };
    let mut written = XdrWriter::default();
    written.u32(0).u32(u32::MAX);
    if s.write_all(&rpc_reply(xid, &written.buf)).await.is_err() {
        return;
    }
    // The device_read whose reply misbehaves.
    let Some((xid, _)) = rpc_call(&mut s).await else {
        return;
    };
    match fault {
        Fault::NoReply => hold(&mut s).await,
        Fault::CloseMidBlock => {
            let _ = s.write_all(&record_mark(1000, true)).await;
            let _ = s.write_all(&[0u8; 500]).await;
        }
        Fault::AnnouncedNeverArrives => {
            let _ = s
                .write_all(&record_mark(super::LIMIT as u32 - 100, true))
                .await;
            let _ = s.write_all(&xid.to_be_bytes()).await;
            let _ = s.write_all(b"012345").await;
            hold(&mut s).await;
        }
        Fault::HugeLength => {
            // A Device_ReadResp whose opaque data claims 4 GB (the record is 40 bytes).
            let mut results = XdrWriter::default();
            results.u32(0).u32(4).u32(u32::MAX);
            let _ = s.write_all(&rpc_reply(xid, &results.buf)).await;
            hold(&mut s).await;
        }
        Fault::Garbage => {
            let _ = s.write_all(&garbage()).await;
            hold(&mut s).await;
        }
        Fault::Trickle => {
            let mut head = record_mark(1_000_000, true).to_vec();
            head.extend_from_slice(&xid.to_be_bytes());
            trickle(&mut s, &head).await;
        }
        Fault::StaleForever => {
            let stale = xid.wrapping_sub(1);
            let reply = rpc_reply(stale, &read_results(4, b"old reply\n"));
            flood(&mut s, || reply.clone()).await;
        }
        Fault::NeverEnds => {
            // Every device_read answered at once with data and no END: the client asks again.
            let data = vec![b'a'; CHUNK];
            let mut xid = xid;
            loop {
                if s.write_all(&rpc_reply(xid, &read_results(0, &data)))
                    .await
                    .is_err()
                {
                    return;
                }
                match rpc_call(&mut s).await {
                    Some((next, _)) => xid = next,
                    None => return,
                }
            }
        }
    }
}

// ---------------------------------------------------------------- serial (pty)

/// Writes all of `data` to the pty master, giving up when `stop` is set or the line is gone.
fn pty_write(master: &mut serialport::TTYPort, mut data: &[u8], stop: &AtomicBool) -> bool {
    while !data.is_empty() {
        if stop.load(Ordering::SeqCst) {
            return false;
        }
        match master.write(data) {
            Ok(n) => data = &data[n..],
            Err(e) if nothing_yet(&e) => {}
            Err(_) => return false,
        }
    }
    true
}

/// A read that found no byte yet (the pty's timeout, or a non-blocking descriptor).
fn nothing_yet(e: &std::io::Error) -> bool {
    matches!(
        e.kind(),
        std::io::ErrorKind::TimedOut | std::io::ErrorKind::WouldBlock
    )
}

/// Reads and drops bytes until `stop` is set.
fn pty_hold(master: &mut serialport::TTYPort, stop: &AtomicBool) {
    let mut sink = [0u8; 4096];
    while !stop.load(Ordering::SeqCst) {
        match master.read(&mut sink) {
            Ok(_) => {}
            Err(e) if nothing_yet(&e) => {}
            Err(_) => return,
        }
    }
}

/// Serves one fault on the master side of a pty, on the calling (blocking) thread.
pub fn serial(mut master: serialport::TTYPort, fault: Fault, stop: Arc<AtomicBool>) {
    use serialport::SerialPort;
    use std::os::fd::AsRawFd;
    let _ = master.set_timeout(TRICKLE_PERIOD);
    // Non-blocking, so a write into a full line returns instead of waiting for a reader that is
    // gone (a tty write on a blocking descriptor waits until every byte is taken).
    // SAFETY: fcntl on a descriptor this TTYPort owns, changing only its O_NONBLOCK flag.
    unsafe {
        let fd = master.as_raw_fd();
        let flags = libc::fcntl(fd, libc::F_GETFL);
        libc::fcntl(fd, libc::F_SETFL, flags | libc::O_NONBLOCK);
    }
    let mut byte = [0u8; 1];
    loop {
        if stop.load(Ordering::SeqCst) {
            return;
        }
        match master.read(&mut byte) {
            Ok(1) if byte[0] == b'\n' => break,
            Ok(_) => {}
            Err(e) if nothing_yet(&e) => {}
            Err(_) => return,
        }
    }
    let limit = super::LIMIT;
    match fault {
        Fault::NoReply | Fault::StaleForever => pty_hold(&mut master, &stop),
        Fault::CloseMidBlock => {
            pty_write(&mut master, b"#41000", &stop);
            pty_write(&mut master, &[b'x'; 500], &stop);
            let _ = master.flush();
            // Dropping the master hangs the line up.
        }
        Fault::AnnouncedNeverArrives => {
            let head = format!("#7{:07}0123456789", limit - 100);
            pty_write(&mut master, head.as_bytes(), &stop);
            pty_hold(&mut master, &stop);
        }
        Fault::HugeLength => {
            pty_write(&mut master, b"#9999999999", &stop);
            pty_hold(&mut master, &stop);
        }
        Fault::Garbage => {
            pty_write(&mut master, &garbage(), &stop);
            pty_hold(&mut master, &stop);
        }
        Fault::Trickle => {
            if !pty_write(&mut master, b"reply ", &stop) {
                return;
            }
            while !stop.load(Ordering::SeqCst) {
                std::thread::sleep(TRICKLE_PERIOD);
                if !pty_write(&mut master, b"x", &stop) {
                    return;
                }
            }
        }
        Fault::NeverEnds => {
            let chunk = vec![b'a'; CHUNK];
            while pty_write(&mut master, &chunk, &stop) {}
        }
    }
}
