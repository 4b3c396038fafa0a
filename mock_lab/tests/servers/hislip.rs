//! HiSLIP server over real loopback sockets, with a minimal hand-written client.

use crate::common;

use std::net::SocketAddr;
use std::time::Duration;

use common::{block_header, bounded, expected_block, instrument};
use mock_lab::server::{hislip, loopback_any};
use tokio::io::{AsyncReadExt, AsyncWriteExt};
use tokio::net::TcpStream;

fn header(kind: u8, control: u8, param: u32, len: u64) -> Vec<u8> {
    let mut h = b"HS".to_vec();
    h.push(kind);
    h.push(control);
    h.extend_from_slice(&param.to_be_bytes());
    h.extend_from_slice(&len.to_be_bytes());
    h
}

async fn send(s: &mut TcpStream, kind: u8, control: u8, param: u32, payload: &[u8]) {
    let mut msg = header(kind, control, param, payload.len() as u64);
    msg.extend_from_slice(payload);
    bounded(s.write_all(&msg)).await.unwrap();
}

/// Reads one message: (type, control, parameter, payload).
async fn recv(s: &mut TcpStream) -> (u8, u8, u32, Vec<u8>) {
    let mut h = [0u8; 16];
    bounded(s.read_exact(&mut h)).await.unwrap();
    assert_eq!(&h[..2], b"HS");
    let len = u64::from_be_bytes(h[8..16].try_into().unwrap());
    let mut payload = vec![0u8; len as usize];
    bounded(s.read_exact(&mut payload)).await.unwrap();
    (
        h[2],
        h[3],
        u32::from_be_bytes(h[4..8].try_into().unwrap()),
        payload,
    )
}

struct Client {
    sync: TcpStream,
    async_: TcpStream,
    message_id: u32,
}

impl Client {
    async fn open(addr: SocketAddr) -> Client {
        let mut sync = bounded(TcpStream::connect(addr)).await.unwrap();
        // Golden Initialize, as pyvisa-py sends it.
        bounded(sync.write_all(b"HS\x00\x00\x01\x00xx\x00\x00\x00\x00\x00\x00\x00\x07hislip0"))
            .await
            .unwrap();
        let (kind, control, param, payload) = recv(&mut sync).await;
        assert_eq!(
            (kind, control, payload.len()),
            (1, 0, 0),
            "InitializeResponse"
        );
        assert_eq!(param >> 16, 0x0100, "protocol 1.0");
        let session = param & 0xFFFF;
        let mut async_ = bounded(TcpStream::connect(addr)).await.unwrap();
        send(&mut async_, 17, 0, session, &[]).await;
        let (kind, _, param, _) = recv(&mut async_).await;
        assert_eq!(kind, 18, "AsyncInitializeResponse");
        assert_eq!(param, u32::from_be_bytes([0, 0, b'M', b'L']));
        send(&mut async_, 15, 0, 0, &(1u64 << 20).to_be_bytes()).await;
        let (kind, _, _, payload) = recv(&mut async_).await;
        assert_eq!(
            (kind, payload.len()),
            (16, 8),
            "AsyncMaxMsgSizeResponse with u64 payload"
        );
        Client {
            sync,
            async_,
            message_id: 0xFFFF_FF00,
        }
    }

    async fn write(&mut self, data: &[u8]) -> u32 {
        let id = self.message_id;
        send(&mut self.sync, 7, 0, id, data).await;
        self.message_id = self.message_id.wrapping_add(2);
        id
    }

    /// Reads Data... DataEnd, checking every MessageID.
    async fn read(&mut self, id: u32) -> Vec<u8> {
        let mut out = Vec::new();
        loop {
            let (kind, _, param, payload) = recv(&mut self.sync).await;
            assert!(kind == 6 || kind == 7, "Data or DataEnd, got {kind}");
            assert_eq!(param, id, "MessageID echoed");
            out.extend_from_slice(&payload);
            if kind == 7 {
                return out;
            }
        }
    }

    async fn query(&mut self, text: &str) -> Vec<u8> {
        let id = self.write(format!("{text}\r\n").as_bytes()).await;
        self.read(id).await
    }

    async fn status(&mut self, rmt: u8) -> u8 {
        send(&mut self.async_, 21, rmt, self.message_id, &[]).await;
        let (kind, stb, _, _) = recv(&mut self.async_).await;
        assert_eq!(kind, 22);
        stb
    }

    async fn clear(&mut self) {
        send(&mut self.async_, 19, 0, 0, &[]).await;
        let (kind, features, _, _) = recv(&mut self.async_).await;
        assert_eq!(kind, 23, "AsyncDeviceClearAcknowledge");
        send(&mut self.sync, 8, features, 0, &[]).await;
        let (kind, _, _, _) = recv(&mut self.sync).await;
        assert_eq!(kind, 9, "DeviceClearAcknowledge");
        self.message_id = 0xFFFF_FF00;
    }
}

#[tokio::test]
async fn identity_status_and_device_clear() {
    let (handler, options, _) = instrument();
    let server = hislip::serve(loopback_any(), handler, options)
        .await
        .unwrap();
    let mut c = Client::open(server.local_addr()).await;
    assert_eq!(c.query("*IDN?").await, b"MOCK_LAB,LOOPBACK,0,0.1\n");
    assert_eq!(c.status(1).await, 0, "response read, nothing pending");
    let id = c.write(b"*OPC?\n").await;
    // Wait until the reply is on its way (not a sleep: the first byte has arrived).
    bounded(c.sync.peek(&mut [0u8; 1])).await.unwrap();
    assert_eq!(
        c.status(0).await & 0x10,
        0x10,
        "MAV while the reply is unread"
    );
    assert_eq!(c.read(id).await, b"1\n");
    assert_eq!(c.query("BOGUS;*OPC?").await, b"1\n");
    assert_eq!(c.status(1).await & 0x04, 0x04, "error queue not empty");
    // A slow query cut short by device clear: no stale reply afterwards.
    c.write(b"SLOW? 60000\n").await;
    c.clear().await;
    assert_eq!(c.query("ECHO after clear").await, b"after clear\n");
}

#[tokio::test]
async fn a_clear_that_lands_before_the_instrument_starts_a_slow_query_still_ends_it() {
    // The clear is sent once SLOW? has reached the instrument, which begins it 300 ms later.
    let (handler, entered) = common::LateStart::handler(Duration::from_millis(300));
    let server = hislip::serve(
        loopback_any(),
        handler,
        mock_lab::server::ServerOptions::default(),
    )
    .await
    .unwrap();
    let mut c = Client::open(server.local_addr()).await;
    c.write(b"SLOW? 60000\n").await;
    let _entered = common::reached(entered).await;
    c.clear().await;
    // Without the clear passed on again, SLOW? would hold the instrument for its full minute.
    let reply = tokio::time::timeout(Duration::from_secs(10), c.query("ECHO after clear"))
        .await
        .expect("the slow query was cut short");
    assert_eq!(reply, b"after clear\n");
}

#[tokio::test]
async fn block_of_64_mb_each_way_in_1_mb_messages() {
    let (handler, options, _) = instrument();
    let server = hislip::serve(loopback_any(), handler, options)
        .await
        .unwrap();
    let mut c = Client::open(server.local_addr()).await;
    let len = 64 << 20;
    c.write(format!("DATA:GEN {len},9\n").as_bytes()).await;
    let reply = c.query("DATA?").await;
    let header = block_header(len);
    assert_eq!(&reply[..header.len()], &header[..]);
    assert!(reply[header.len()..header.len() + len] == expected_block(len, 9)[..]);
    // Upload split in Data messages of at most 1 MiB, DataEnd last.
    let mut upload = b"DATA ".to_vec();
    upload.extend_from_slice(&header);
    upload.extend(expected_block(len, 10));
    let chunks: Vec<&[u8]> = upload.chunks(1 << 20).collect();
    for (i, chunk) in chunks.iter().enumerate() {
        let kind = if i + 1 == chunks.len() { 7 } else { 6 };
        send(&mut c.sync, kind, 0, c.message_id, chunk).await;
    }
    c.message_id = c.message_id.wrapping_add(2);
    assert_eq!(c.query("DATA:LEN?").await, format!("{len}\n").as_bytes());
    let reply = c.query("DATA?").await;
    assert!(reply[header.len()..header.len() + len] == expected_block(len, 10)[..]);
}

#[tokio::test]
async fn several_sessions_at_once() {
    let (handler, options, _) = instrument();
    let server = hislip::serve(loopback_any(), handler, options)
        .await
        .unwrap();
    let mut tasks = Vec::new();
    for i in 0..6 {
        let addr = server.local_addr();
        tasks.push(tokio::spawn(async move {
            let mut c = Client::open(addr).await;
            for j in 0..10 {
                let echo = format!("s{i}m{j}");
                assert_eq!(
                    c.query(&format!("ECHO {echo}")).await,
                    format!("{echo}\n").as_bytes()
                );
            }
        }));
    }
    for task in tasks {
        bounded(task).await.unwrap();
    }
}

#[tokio::test]
async fn bad_input_gets_errors_not_a_crash() {
    let (handler, options, _) = instrument();
    let server = hislip::serve(loopback_any(), handler, options)
        .await
        .unwrap();
    // AsyncInitialize for a session that does not exist: FatalError 3.
    let mut s = TcpStream::connect(server.local_addr()).await.unwrap();
    send(&mut s, 17, 0, 4242, &[]).await;
    assert_eq!(recv(&mut s).await.0, 2);
    // Garbage prologue: FatalError 1.
    let mut s = TcpStream::connect(server.local_addr()).await.unwrap();
    s.write_all(b"GARBAGE GARBAGE!").await.unwrap();
    let (kind, code, _, _) = recv(&mut s).await;
    assert_eq!((kind, code), (2, 1));
    // Unknown message type on a good session: Error 1, session keeps working.
    let mut c = Client::open(server.local_addr()).await;
    send(&mut c.sync, 99, 0, 0, b"xyz").await;
    let (kind, code, _, _) = recv(&mut c.sync).await;
    assert_eq!((kind, code), (3, 1));
    assert_eq!(c.query("*OPC?").await, b"1\n");
}

#[tokio::test]
async fn vanished_client_and_faults() {
    let (handler, options, faults) = instrument();
    let server = hislip::serve(loopback_any(), handler, options)
        .await
        .unwrap();
    let mut c = Client::open(server.local_addr()).await;
    // Half a Data message, then gone.
    c.sync.write_all(&header(7, 0, 1, 1000)).await.unwrap();
    c.sync.write_all(b"DATA #").await.unwrap();
    drop(c);
    let mut c = Client::open(server.local_addr()).await;
    faults.set_byte_segments(true);
    faults.set_reply_delay(Duration::from_millis(10));
    assert_eq!(c.query("ECHO slowly").await, b"slowly\n");
    faults.clear();
    faults.swallow_next_reply();
    c.write(b"ECHO lost\n").await;
    let mut byte = [0u8; 1];
    assert!(
        tokio::time::timeout(Duration::from_millis(200), c.sync.read(&mut byte))
            .await
            .is_err()
    );
    c.clear().await;
    assert_eq!(c.query("ECHO next").await, b"next\n");
    faults.drop_next_reply_midway();
    let id = c.write(b"DATA:GEN 5000;DATA?\n").await;
    let _ = id;
    let mut got = Vec::new();
    bounded(c.sync.read_to_end(&mut got)).await.unwrap();
    assert!(
        !got.is_empty() && got.len() < 5000,
        "half a reply, then the connection closed"
    );
    let mut c = Client::open(server.local_addr()).await;
    assert_eq!(c.query("*OPC?").await, b"1\n");
}

#[tokio::test]
async fn message_over_the_limit_gets_error_4_and_the_session_continues() {
    let (handler, mut options, _) = instrument();
    options.max_message_size = 1000;
    let server = hislip::serve(loopback_any(), handler, options)
        .await
        .unwrap();
    let mut c = Client::open(server.local_addr()).await;
    // The server's maximum is advertised in AsyncMaxMsgSizeResponse (payload + header).
    send(&mut c.async_, 15, 0, 0, &(1u64 << 20).to_be_bytes()).await;
    let (_, _, _, payload) = recv(&mut c.async_).await;
    assert_eq!(u64::from_be_bytes(payload.try_into().unwrap()), 1000 + 16);
    c.write(&[b'x'; 2000]).await;
    let (kind, code, _, _) = recv(&mut c.sync).await;
    assert_eq!((kind, code), (3, 4), "Error: message too large");
    assert_eq!(c.query("*OPC?").await, b"1\n");
}

#[tokio::test]
async fn blocks_ending_in_whitespace_reach_the_awg_byte_exact() {
    let (handler, options) = common::awg();
    let server = hislip::serve(loopback_any(), handler, options)
        .await
        .unwrap();
    let mut client = Client::open(server.local_addr()).await;
    for exchange in common::whitespace_tail_uploads() {
        let id = client.write(&exchange.message).await;
        if let Some(reply) = exchange.reply {
            assert_eq!(client.read(id).await, format!("{reply}\n").into_bytes());
        }
    }
}
