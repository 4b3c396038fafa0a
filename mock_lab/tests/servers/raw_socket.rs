//! Raw-socket server over real loopback sockets, with a minimal hand-written client.

use crate::common;

use std::time::Duration;

use common::{block_header, bounded, expected_block, instrument};
use mock_lab::server::{loopback_any, raw};
use tokio::io::{AsyncReadExt, AsyncWriteExt};
use tokio::net::TcpStream;

/// Reads one LF-terminated text reply.
async fn read_line(stream: &mut TcpStream) -> Vec<u8> {
    let mut out = Vec::new();
    let mut byte = [0u8; 1];
    loop {
        bounded(stream.read_exact(&mut byte)).await.expect("reply");
        if byte[0] == b'\n' {
            return out;
        }
        out.push(byte[0]);
    }
}

/// Reads a `#N` block reply followed by its LF.
async fn read_block(stream: &mut TcpStream) -> Vec<u8> {
    let mut head = [0u8; 2];
    bounded(stream.read_exact(&mut head)).await.unwrap();
    assert_eq!(head[0], b'#');
    let mut digits = vec![0u8; usize::from(head[1] - b'0')];
    bounded(stream.read_exact(&mut digits)).await.unwrap();
    let len: usize = std::str::from_utf8(&digits).unwrap().parse().unwrap();
    let mut data = vec![0u8; len + 1];
    bounded(stream.read_exact(&mut data)).await.unwrap();
    assert_eq!(data.pop(), Some(b'\n'));
    data
}

async fn connect() -> (
    mock_lab::server::ServerHandle,
    TcpStream,
    std::sync::Arc<mock_lab::faults::Faults>,
) {
    let (handler, options, faults) = instrument();
    let server = raw::serve(loopback_any(), handler, options).await.unwrap();
    let stream = bounded(TcpStream::connect(server.local_addr()))
        .await
        .unwrap();
    (server, stream, faults)
}

#[tokio::test]
async fn identity_with_lf_and_crlf() {
    let (_server, mut s, _) = connect().await;
    s.write_all(b"*IDN?\n").await.unwrap();
    assert_eq!(read_line(&mut s).await, b"MOCK_LAB,LOOPBACK,0,0.1");
    s.write_all(b"*IDN?\r\n*OPC?\r\n").await.unwrap();
    assert_eq!(read_line(&mut s).await, b"MOCK_LAB,LOOPBACK,0,0.1");
    assert_eq!(read_line(&mut s).await, b"1");
}

#[tokio::test]
async fn golden_bytes_one_byte_at_a_time() {
    let (_server, mut s, _) = connect().await;
    let stream = b"DATA #15a\nb\r\n\r\nDATA?\r\n";
    for &b in stream {
        s.write_all(&[b]).await.unwrap();
        s.flush().await.unwrap();
    }
    assert_eq!(read_block(&mut s).await, b"a\nb\r\n");
}

#[tokio::test]
async fn block_of_64_mb_each_way() {
    let (_server, mut s, _) = connect().await;
    let len = 64 << 20;
    s.write_all(format!("DATA:GEN {len},3\n").as_bytes())
        .await
        .unwrap();
    s.write_all(b"DATA?\n").await.unwrap();
    let data = read_block(&mut s).await;
    assert!(
        data == expected_block(len, 3),
        "64 MB block read back differs"
    );
    let mut upload = b"DATA ".to_vec();
    upload.extend_from_slice(&block_header(len));
    let payload: Vec<u8> = data.iter().map(|b| b ^ 0x5A).collect();
    upload.extend_from_slice(&payload);
    upload.extend_from_slice(b"\r\nDATA:LEN?\n");
    bounded(s.write_all(&upload)).await.unwrap();
    assert_eq!(read_line(&mut s).await, len.to_string().as_bytes());
    s.write_all(b"DATA?\n").await.unwrap();
    assert!(
        read_block(&mut s).await == payload,
        "uploaded block differs"
    );
}

#[tokio::test]
async fn several_clients_at_once_and_blocking_handler_stalls_only_its_client() {
    let (handler, options, _) = instrument();
    let server = raw::serve(loopback_any(), handler, options).await.unwrap();
    let mut slow = TcpStream::connect(server.local_addr()).await.unwrap();
    slow.write_all(b"SLOW? 3000\n").await.unwrap();
    let mut tasks = Vec::new();
    for i in 0..8 {
        let addr = server.local_addr();
        tasks.push(tokio::spawn(async move {
            let mut s = TcpStream::connect(addr).await.unwrap();
            for j in 0..20 {
                s.write_all(format!("ECHO c{i}m{j}\n").as_bytes())
                    .await
                    .unwrap();
                assert_eq!(read_line(&mut s).await, format!("c{i}m{j}").as_bytes());
            }
        }));
    }
    for task in tasks {
        bounded(task).await.unwrap();
    }
    assert_eq!(read_line(&mut slow).await, b"3000");
}

#[tokio::test]
async fn vanished_client_mid_block_does_not_take_the_server_down() {
    let (_server, mut s, _) = connect().await;
    let addr = s.peer_addr().unwrap();
    s.write_all(b"DATA #81000000abc").await.unwrap();
    drop(s);
    let mut s = bounded(TcpStream::connect(addr)).await.unwrap();
    s.write_all(b"*IDN?\n").await.unwrap();
    assert_eq!(read_line(&mut s).await, b"MOCK_LAB,LOOPBACK,0,0.1");
}

#[tokio::test]
async fn oversized_block_closes_only_that_connection() {
    let (handler, mut options, _) = instrument();
    options.max_message_size = 1000;
    let server = raw::serve(loopback_any(), handler, options).await.unwrap();
    let mut s = TcpStream::connect(server.local_addr()).await.unwrap();
    s.write_all(b"DATA #9100000000").await.unwrap();
    let mut buf = [0u8; 1];
    assert_eq!(bounded(s.read(&mut buf)).await.unwrap(), 0, "server closes");
    let mut s = TcpStream::connect(server.local_addr()).await.unwrap();
    s.write_all(b"*OPC?\n").await.unwrap();
    assert_eq!(read_line(&mut s).await, b"1");
}

#[tokio::test]
async fn fault_byte_segments_and_delay() {
    let (_server, mut s, faults) = connect().await;
    faults.set_byte_segments(true);
    faults.set_reply_delay(Duration::from_millis(20));
    s.write_all(b"DATA:GEN 300\nDATA?\n").await.unwrap();
    assert_eq!(read_block(&mut s).await, expected_block(300, 1));
    faults.clear();
    s.write_all(b"*OPC?\n").await.unwrap();
    assert_eq!(read_line(&mut s).await, b"1");
}

#[tokio::test]
async fn fault_drop_midway_closes_connection_after_half_a_block() {
    let (_server, mut s, faults) = connect().await;
    s.write_all(b"DATA:GEN 10000\n").await.unwrap();
    faults.drop_next_reply_midway();
    s.write_all(b"DATA?\n").await.unwrap();
    let mut got = Vec::new();
    bounded(s.read_to_end(&mut got)).await.unwrap();
    // Block header (7) + payload + LF, cut in half.
    assert_eq!(got.len(), 10008 / 2);
    let addr = s.peer_addr().unwrap();
    let mut s = TcpStream::connect(addr).await.unwrap();
    s.write_all(b"*OPC?\n").await.unwrap();
    assert_eq!(read_line(&mut s).await, b"1");
}

#[tokio::test]
async fn fault_swallowed_reply_then_next_answer_is_correct() {
    let (_server, mut s, faults) = connect().await;
    faults.swallow_next_reply();
    s.write_all(b"ECHO lost\n").await.unwrap();
    let mut buf = [0u8; 1];
    let waited = tokio::time::timeout(Duration::from_millis(200), s.read(&mut buf)).await;
    assert!(waited.is_err(), "the swallowed reply must never come");
    s.write_all(b"ECHO found\n").await.unwrap();
    assert_eq!(read_line(&mut s).await, b"found");
}

/// A handler that panics on one command, to check the server survives it.
struct Fragile;

impl mock_lab::server::Handler for Fragile {
    fn message(&self, data: &[u8]) -> Vec<Vec<u8>> {
        assert!(data != b"BOOM", "instrument firmware crashed");
        vec![data.to_vec()]
    }
}

#[tokio::test]
async fn panicking_handler_closes_only_that_connection() {
    let handler: std::sync::Arc<dyn mock_lab::server::Handler> = std::sync::Arc::new(Fragile);
    let server = raw::serve(loopback_any(), handler, Default::default())
        .await
        .unwrap();
    let mut s = TcpStream::connect(server.local_addr()).await.unwrap();
    s.write_all(b"BOOM\n").await.unwrap();
    let mut buf = [0u8; 1];
    assert_eq!(
        bounded(s.read(&mut buf)).await.unwrap(),
        0,
        "connection closed"
    );
    let mut s = TcpStream::connect(server.local_addr()).await.unwrap();
    s.write_all(b"still here\n").await.unwrap();
    assert_eq!(read_line(&mut s).await, b"still here");
}

#[tokio::test]
async fn blocks_ending_in_whitespace_reach_the_awg_byte_exact() {
    let (handler, options) = common::awg();
    let server = raw::serve(loopback_any(), handler, options).await.unwrap();
    let mut stream = bounded(TcpStream::connect(server.local_addr()))
        .await
        .unwrap();
    for exchange in common::whitespace_tail_uploads() {
        bounded(stream.write_all(&exchange.message)).await.unwrap();
        if let Some(reply) = exchange.reply {
            assert_eq!(
                String::from_utf8(read_line(&mut stream).await).unwrap(),
                reply
            );
        }
    }
}
