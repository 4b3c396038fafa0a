//! Serial client (`serialport` on its own thread) against the mock_lab serial endpoint on a
//! pseudo-terminal.
#![cfg(unix)]

mod io_support;

use io_support::bounded;
use mock_lab::emulator::loopback::{Loopback, IDENTITY};
use mock_lab::faults::Faults;
use mock_lab::server::{serial, Handler, ServerOptions};
use radbench::session::{BlockForm, Session, SessionOptions};
use radbench::transport::LinkError;
use std::sync::Arc;
use std::time::Duration;

fn endpoint() -> (serial::SerialHandle, Arc<Faults>) {
    let faults = Faults::new();
    let handler: Arc<dyn Handler> = Arc::new(Loopback::new());
    let handle = serial::serve(handler, ServerOptions::with_faults(faults.clone()))
        .expect("pty endpoint starts");
    (handle, faults)
}

async fn open(path: &str, read: Duration) -> Session {
    let mut options = SessionOptions::default();
    options.link.timeouts.read = read;
    let resource = format!("ASRL{path}::INSTR").parse().unwrap();
    bounded(Session::open(resource, options, None, "gotmic"))
        .await
        .expect("serial session opens")
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn identity_blocks_and_errors_over_a_pty() {
    let (endpoint, _faults) = endpoint();
    let mut s = open(endpoint.device_path(), Duration::from_secs(5)).await;
    assert_eq!(bounded(s.idn()).await.unwrap().to_string(), IDENTITY);
    let data = b"line one\nline two\n#3 not a header".repeat(20);
    bounded(s.write_block("DATA ", &data, BlockForm::Definite))
        .await
        .unwrap();
    let block = bounded(s.query_block("DATA?")).await.unwrap();
    assert_eq!(block.payload(), &data[..]);
    assert_eq!(bounded(s.read_stb()).await.unwrap() & 0x04, 0);
    bounded(s.write("NOT:A:COMMAND")).await.unwrap();
    let errors = bounded(s.errors()).await.unwrap();
    assert_eq!(errors.len(), 1);
    assert_eq!(errors[0].code, -113);
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn missing_and_half_replies_time_out_then_the_next_answer_is_fresh() {
    let (endpoint, faults) = endpoint();
    let mut s = open(endpoint.device_path(), Duration::from_millis(300)).await;
    faults.swallow_next_reply();
    let err = bounded(s.query("ECHO lost")).await.unwrap_err();
    assert!(
        matches!(err.link_error(), Some(LinkError::Timeout { .. })),
        "{err}"
    );
    assert_eq!(bounded(s.query("ECHO next")).await.unwrap(), "next");
    // Half a reply and nothing more: the fragment is discarded by the clear after the timeout.
    faults.drop_next_reply_midway();
    let err = bounded(s.query("ECHO 0123456789abcdef")).await.unwrap_err();
    assert!(
        matches!(err.link_error(), Some(LinkError::Timeout { .. })),
        "{err}"
    );
    assert_eq!(bounded(s.query("ECHO whole")).await.unwrap(), "whole");
    // Replies trickling in one byte at a time.
    faults.set_byte_segments(true);
    assert_eq!(bounded(s.idn()).await.unwrap().to_string(), IDENTITY);
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_missing_device_is_a_clear_error() {
    let resource = "ASRL/dev/radbench-no-such-port::INSTR".parse().unwrap();
    let err = bounded(Session::open(resource, SessionOptions::default(), None, ""))
        .await
        .err()
        .expect("opening a missing port fails");
    assert!(err.to_string().contains("radbench-no-such-port"), "{err}");
    assert!(matches!(err.link_error(), Some(LinkError::Serial { .. })));
}
