//! A driver's long wait (a scope's `WAIT`, an AWG's `*OPC?` after a download) is passed with the
//! query: it is honoured, and the session's own read timeout is never touched, not even by a
//! query that is dropped half-way.

use std::time::Duration;

use radbench::driver::InstrumentIo;
use radbench::session::{Session, SessionOptions};
use tokio::io::{AsyncBufReadExt, AsyncWriteExt, BufReader};
use tokio::net::TcpListener;

async fn bounded<T>(f: impl std::future::Future<Output = T>) -> T {
    tokio::time::timeout(Duration::from_secs(30), f)
        .await
        .expect("operation did not finish within 30 s")
}

/// A raw-socket peer that answers each line with `late` after `delay`, or never when `None`.
async fn peer(delay: Option<Duration>) -> (u16, tokio::task::JoinHandle<()>) {
    let listener = TcpListener::bind("127.0.0.1:0").await.unwrap();
    let port = listener.local_addr().unwrap().port();
    let task = tokio::spawn(async move {
        let Ok((stream, _)) = listener.accept().await else {
            return;
        };
        let (read, mut write) = stream.into_split();
        let mut lines = BufReader::new(read).lines();
        while let Ok(Some(_)) = lines.next_line().await {
            match delay {
                Some(d) => {
                    tokio::time::sleep(d).await;
                    if write.write_all(b"late\n").await.is_err() {
                        return;
                    }
                }
                None => std::future::pending::<()>().await,
            }
        }
    });
    (port, task)
}

async fn session(port: u16, read: Duration) -> Session {
    let mut options = SessionOptions::default();
    options.link.timeouts.read = read;
    let resource = format!("TCPIP::127.0.0.1::{port}::SOCKET").parse().unwrap();
    bounded(Session::open(resource, options, None, "test"))
        .await
        .unwrap()
}

#[tokio::test]
async fn a_dropped_long_query_leaves_the_session_timeout_as_it_was() {
    let (port, task) = peer(None).await;
    let mut session = session(port, Duration::from_secs(1)).await;
    let cut_short = tokio::time::timeout(
        Duration::from_millis(50),
        session.query_with_timeout("*OPC?", Duration::from_secs(30)),
    )
    .await;
    assert!(cut_short.is_err(), "the peer never answers");
    assert_eq!(
        session.link_options_mut().timeouts.read,
        Duration::from_secs(1)
    );
    task.abort();
}

#[tokio::test]
async fn a_long_query_waits_past_the_session_timeout() {
    let (port, task) = peer(Some(Duration::from_millis(400))).await;
    let mut session = session(port, Duration::from_millis(100)).await;
    let reply = bounded(session.query_with_timeout("*OPC?", Duration::from_secs(20)))
        .await
        .unwrap();
    assert_eq!(reply, "late");
    assert_eq!(
        session.link_options_mut().timeouts.read,
        Duration::from_millis(100)
    );
    task.abort();
}
