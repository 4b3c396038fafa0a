//! Line-based serial endpoint on a pseudo-terminal (the Gotmic modules' link).
//!
//! The server owns the pty master (and keeps the slave open, so a client closing its end does
//! not hang the master up); clients open [`SerialHandle::device_path`] like any serial port.
//! One request per line (LF, CR LF accepted), each response sent with a LF; a handler with its own
//! [`Handler::line_terminator`] (a module whose firmware ends lines with CR, say) gets plain lines
//! ending at that terminator's last byte, and its replies end with it. Blocking I/O on a
//! dedicated thread: the handler is called on that thread directly.
//!
//! Faults: delay, 1-byte segments and swallowed replies behave as on TCP; "dropped midway"
//! sends half the reply and nothing more (a serial line cannot be disconnected).

use std::io::{self, Read, Write};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::thread::JoinHandle;
use std::time::Duration;

use serialport::{SerialPort, TTYPort};

use super::conn::terminated;
use super::framing::{Frame, FramingError, Splitter};
use super::{Handler, ServerError, ServerOptions};
use crate::faults::ReplyFate;

/// How often the serving thread checks whether it should stop.
const POLL: Duration = Duration::from_millis(50);

/// A running serial endpoint. Dropping it stops the thread and closes the pty.
#[derive(Debug)]
pub struct SerialHandle {
    path: String,
    stop: Arc<AtomicBool>,
    thread: Option<JoinHandle<()>>,
}

impl SerialHandle {
    /// The pty slave device clients open (for example `/dev/pts/7`).
    pub fn device_path(&self) -> &str {
        &self.path
    }

    /// Stops serving and waits for the thread to end (at most one poll interval).
    pub fn shutdown(&mut self) {
        self.stop.store(true, Ordering::SeqCst);
        if let Some(thread) = self.thread.take() {
            let _ = thread.join();
        }
    }
}

impl Drop for SerialHandle {
    fn drop(&mut self) {
        self.shutdown();
    }
}

/// Creates a pty pair and serves `handler` on it from a new thread.
pub fn serve(
    handler: Arc<dyn Handler>,
    options: ServerOptions,
) -> Result<SerialHandle, ServerError> {
    let (mut master, slave) = TTYPort::pair()?;
    let path = slave.name().ok_or_else(|| ServerError::Start {
        protocol: "serial",
        source: io::Error::other("the pty slave has no device name"),
    })?;
    master.set_timeout(POLL)?;
    let stop = Arc::new(AtomicBool::new(false));
    let thread_stop = Arc::clone(&stop);
    let thread = std::thread::Builder::new()
        .name("mock-lab-serial".into())
        .spawn(move || {
            // The slave stays open while we serve, so the master never sees a hang-up.
            let _slave = slave;
            if let Err(err) = serve_lines(&mut master, handler.as_ref(), &options, &thread_stop) {
                tracing::warn!("serial endpoint stopped: {err}");
            }
        })
        .map_err(|source| ServerError::Start {
            protocol: "serial",
            source,
        })?;
    Ok(SerialHandle {
        path,
        stop,
        thread: Some(thread),
    })
}

fn serve_lines(
    port: &mut TTYPort,
    handler: &dyn Handler,
    options: &ServerOptions,
    stop: &AtomicBool,
) -> io::Result<()> {
    let line_end = handler.line_terminator().map(<[u8]>::to_vec);
    let mut splitter = Splitter::new(options.max_message_size);
    let mut buf: Vec<u8> = Vec::new();
    let mut chunk = vec![0u8; 64 << 10];
    while !stop.load(Ordering::SeqCst) {
        let n = match port.read(&mut chunk) {
            Ok(0) => continue,
            Ok(n) => n,
            Err(e)
                if matches!(
                    e.kind(),
                    io::ErrorKind::TimedOut
                        | io::ErrorKind::WouldBlock
                        | io::ErrorKind::Interrupted
                ) =>
            {
                continue
            }
            Err(e) => return Err(e),
        };
        buf.extend_from_slice(&chunk[..n]);
        loop {
            let next = match &line_end {
                Some(end) => plain_line(&buf, end, options.max_message_size),
                None => splitter.next_frame(&buf),
            };
            let frame = match next {
                Ok(Some(frame)) => frame,
                Ok(None) => break,
                Err(err) => {
                    // A serial line cannot be closed: drop what arrived and resynchronise.
                    tracing::warn!("serial input discarded: {err}");
                    buf.clear();
                    splitter = Splitter::new(options.max_message_size);
                    break;
                }
            };
            let line = buf[..frame.message_len].to_vec();
            buf.drain(..frame.consumed);
            if line.is_empty() {
                continue;
            }
            for response in handler.message(&line) {
                let response = match &line_end {
                    Some(end) => [response, end.clone()].concat(),
                    None => terminated(response),
                };
                match write_response(port, &response, options) {
                    Ok(()) => {}
                    // Nobody reads the other end: drop the reply, keep serving.
                    Err(e) if e.kind() == io::ErrorKind::TimedOut => {
                        tracing::debug!("serial reply dropped: nobody is reading the port");
                    }
                    Err(e) => return Err(e),
                }
            }
        }
    }
    Ok(())
}

/// The first line of `buf` for a device that is not IEEE 488.2: it ends at the terminator's last
/// byte (the bytes of the terminator before it are stripped), with no `#` blocks.
fn plain_line(buf: &[u8], end: &[u8], max: usize) -> Result<Option<Frame>, FramingError> {
    // Never empty (the catalog checks it); LF if it were.
    let last = end.last().copied().unwrap_or(b'\n');
    match buf.iter().position(|&b| b == last) {
        Some(at) => {
            let mut len = at;
            let before_last = &end[..end.len().saturating_sub(1)];
            while len > 0 && before_last.contains(&buf[len - 1]) {
                len -= 1;
            }
            Ok(Some(Frame {
                message_len: len,
                consumed: at + 1,
            }))
        }
        None if buf.len() > max => Err(FramingError::MessageTooLarge { max }),
        None => Ok(None),
    }
}

fn write_response(port: &mut TTYPort, response: &[u8], options: &ServerOptions) -> io::Result<()> {
    let plan = options.faults.plan_reply();
    if !plan.delay.is_zero() {
        std::thread::sleep(plan.delay);
    }
    let bytes = match plan.fate {
        ReplyFate::Swallow => return Ok(()),
        ReplyFate::DropMidway => &response[..response.len() / 2],
        ReplyFate::Deliver => response,
    };
    if plan.byte_segments {
        for byte in bytes {
            port.write_all(std::slice::from_ref(byte))?;
            port.flush()?;
        }
    } else {
        port.write_all(bytes)?;
        port.flush()?;
    }
    Ok(())
}
