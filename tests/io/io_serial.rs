//! Serial client (`serialport` on its own thread) against the mock_lab serial endpoint on a
//! pseudo-terminal.

use crate::io_support;

use io_support::bounded;
use mock_lab::emulator::loopback::{Loopback, IDENTITY};
use mock_lab::faults::Faults;
use mock_lab::server::{serial, Handler, ServerOptions};
use radbench::session::{BlockForm, Crc8, LineProtocol, Session, SessionError, SessionOptions};
use radbench::transport::LinkError;
use serialport::SerialPort;
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

/// The Gotmic modules' line protocol (project-defined, instruments/gotmic_*.toml): CRC-8/SMBUS.
fn gotmic_line() -> SessionOptions {
    SessionOptions {
        line: Some(LineProtocol {
            crc: Some(Crc8 {
                poly: 0x07,
                init: 0x00,
            }),
        }),
        ..SessionOptions::default()
    }
}

async fn open_with(path: &str, options: SessionOptions) -> Session {
    let resource = format!("ASRL{path}::INSTR").parse().unwrap();
    bounded(Session::open(resource, options, None, "gotmic"))
        .await
        .expect("serial session opens")
}

/// A line-protocol session reads the reply to every request (register reads do not end in `?`),
/// adds the CRC once the module has it on, and reports an `ERR` line as a refusal.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_gotmic_module_answers_every_line_with_or_without_crc() {
    let module = mock_lab::emulator::gotmic::Gotmic::tx_embedded().unwrap();
    let endpoint = serial::serve(Arc::new(module), ServerOptions::with_faults(Faults::new()))
        .expect("pty endpoint starts");
    let mut s = open_with(endpoint.device_path(), gotmic_line()).await;
    assert!(s.answers_every_request());
    let id = bounded(s.idn()).await.unwrap();
    assert_eq!(id.model, "GOTMIC-EBAND-TX-EMU");
    assert_eq!(bounded(s.query("R 03")).await.unwrap(), "OK 003F");
    bounded(s.write("W 03 0010")).await.unwrap();
    assert_eq!(bounded(s.query("R 03")).await.unwrap(), "OK 0010");
    bounded(s.write("CRC ON")).await.unwrap();
    assert_eq!(bounded(s.query("R 03")).await.unwrap(), "OK 0010");
    let err = bounded(s.query("R 7F")).await.unwrap_err();
    let SessionError::Device { errors, after, .. } = &err else {
        panic!("expected the module's refusal, got {err}");
    };
    assert_eq!(errors[0].code, 2, "{err}");
    assert_eq!(after.as_deref(), Some("R 7F"));
    assert!(bounded(s.errors()).await.unwrap().is_empty());
    drop(s);

    // A new session does not know the module has CRC on: its plain request is refused for the
    // missing CRC, and sent again framed.
    let mut s = open_with(endpoint.device_path(), gotmic_line()).await;
    assert_eq!(bounded(s.query("R 03")).await.unwrap(), "OK 0010");
    assert_eq!(bounded(s.idn()).await.unwrap().model, "GOTMIC-EBAND-TX-EMU");
    bounded(s.write("CRC OFF")).await.unwrap();
    assert_eq!(bounded(s.query("R 03")).await.unwrap(), "OK 0010");
    // Without a line protocol the same module is an ordinary serial device again.
    drop(s);
    let mut s = open_with(endpoint.device_path(), SessionOptions::default()).await;
    assert_eq!(bounded(s.query("R 03")).await.unwrap(), "OK 0010");
}

/// A reply the previous user of the port left unread (sitting in the line's input queue when
/// the session opens) is drained, not returned to the first query.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_reply_left_unread_is_drained_not_taken_by_the_next_session() {
    use std::io::{Read, Write};
    let (mut peer, client) = serialport::TTYPort::pair().expect("pty pair");
    // The previous session's unread reply.
    peer.write_all(b"OK 003F\n").unwrap();
    peer.flush().unwrap();
    let answerer = std::thread::spawn(move || {
        peer.set_timeout(Duration::from_secs(20)).unwrap();
        let mut line = Vec::new();
        let mut byte = [0u8; 1];
        while !line.ends_with(b"\n") {
            if peer.read(&mut byte).unwrap_or(0) == 0 {
                return None;
            }
            line.push(byte[0]);
        }
        peer.write_all(b"fresh answer\n").unwrap();
        peer.flush().unwrap();
        Some((line, peer))
    });
    let device = client.name().unwrap_or_default();
    let link =
        radbench::transport::SerialLink::from_port(Box::new(client), device.clone(), 1 << 20)
            .unwrap();
    let resource: radbench::address::Resource = format!("ASRL{device}::INSTR").parse().unwrap();
    let link = radbench::transport::Link::from_serial(
        resource,
        link,
        radbench::transport::LinkOptions::default(),
    );
    let mut s = Session::from_link(link, SessionOptions::default());
    assert_eq!(bounded(s.query("R 03")).await.unwrap(), "fresh answer");
    let (request, _peer) = bounded(tokio::task::spawn_blocking(move || answerer.join()))
        .await
        .unwrap()
        .unwrap()
        .expect("the request arrived");
    assert_eq!(request, b"R 03\n");
}

/// A closed session has let go of the port when `close` returns: the device (opened
/// exclusively) can be opened again at once, as `radbench scpi` does after probing a module.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_closed_port_can_be_opened_again_at_once() {
    let (endpoint, _faults) = endpoint();
    for _ in 0..20 {
        let mut s = open(endpoint.device_path(), Duration::from_secs(5)).await;
        assert_eq!(bounded(s.idn()).await.unwrap().to_string(), IDENTITY);
        bounded(s.close()).await.unwrap();
    }
}
