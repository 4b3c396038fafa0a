//! Serial links (`ASRL<device>::INSTR`): a blocking `serialport` owned by one thread, bridged to
//! async with channels. Messages end at a newline outside binary blocks (as on a raw socket), or at
//! the last byte of the bench's `line_terminator` for modules whose firmware ends lines otherwise.
//!
//! Cancelling a request does not interrupt the thread mid-read: it finishes (or times out) and its
//! result is dropped, so a reply nobody waits for is never handed to the next reader.

use super::error::LinkError;
use super::framing::TerminatedDecoder;
use super::io::{buffer_ceiling, reserve_within, Decode, LinkOptions};
use bytes::{Bytes, BytesMut};
use std::sync::mpsc;
use std::time::{Duration, Instant};
use tokio::sync::oneshot;

/// Serial line settings, taken from the bench file.
#[derive(Debug, Clone, PartialEq, Eq, serde::Deserialize, serde::Serialize)]
#[serde(deny_unknown_fields, default)]
pub struct SerialSettings {
    pub baud: u32,
    /// 5, 6, 7 or 8.
    pub data_bits: u8,
    /// "none", "odd" or "even".
    pub parity: String,
    /// 1 or 2.
    pub stop_bits: u8,
    /// "none", "software" or "hardware".
    pub flow_control: String,
    /// What ends every request; a reply ends at its last byte (as VISA's termination character),
    /// and the bytes before it that belong to the terminator are stripped with the blanks.
    /// "\n" by default; "\r" or "\r\n" for modules whose firmware wants them.
    pub line_terminator: String,
}

impl Default for SerialSettings {
    fn default() -> Self {
        Self {
            baud: 115_200,
            data_bits: 8,
            parity: "none".into(),
            stop_bits: 1,
            flow_control: "none".into(),
            line_terminator: "\n".into(),
        }
    }
}

impl SerialSettings {
    /// The byte a reply ends at: the terminator's last.
    fn reply_end(&self) -> u8 {
        self.line_terminator.bytes().last().unwrap_or(b'\n')
    }

    fn builder(&self, path: &str) -> Result<serialport::SerialPortBuilder, LinkError> {
        let bad = |detail: String| LinkError::Serial {
            device: path.to_string(),
            detail,
        };
        let data_bits = match self.data_bits {
            5 => serialport::DataBits::Five,
            6 => serialport::DataBits::Six,
            7 => serialport::DataBits::Seven,
            8 => serialport::DataBits::Eight,
            n => return Err(bad(format!("data_bits = {n}: allowed are 5, 6, 7, 8"))),
        };
        let parity = match self.parity.to_ascii_lowercase().as_str() {
            "none" => serialport::Parity::None,
            "odd" => serialport::Parity::Odd,
            "even" => serialport::Parity::Even,
            p => return Err(bad(format!("parity = {p:?}: allowed are none, odd, even"))),
        };
        let stop_bits = match self.stop_bits {
            1 => serialport::StopBits::One,
            2 => serialport::StopBits::Two,
            n => return Err(bad(format!("stop_bits = {n}: allowed are 1, 2"))),
        };
        let flow = match self.flow_control.to_ascii_lowercase().as_str() {
            "none" => serialport::FlowControl::None,
            "software" => serialport::FlowControl::Software,
            "hardware" => serialport::FlowControl::Hardware,
            f => {
                return Err(bad(format!(
                    "flow_control = {f:?}: allowed are none, software, hardware"
                )))
            }
        };
        if self.baud == 0 {
            return Err(bad("baud = 0: give the line speed, e.g. 115200".into()));
        }
        if self.line_terminator.is_empty() || self.line_terminator.len() > 4 {
            return Err(bad(format!(
                "line_terminator = {:?}: allowed are 1 to 4 characters, e.g. \"\\n\", \"\\r\" or \"\\r\\n\"",
                self.line_terminator
            )));
        }
        Ok(serialport::new(path, self.baud)
            .data_bits(data_bits)
            .parity(parity)
            .stop_bits(stop_bits)
            .flow_control(flow)
            .timeout(POLL))
    }
}

/// What a serial link does with the line before its first request.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum OnOpen {
    /// Throws away what the line holds, then waits until it has been quiet for `SETTLE` (50 ms),
    /// throwing away whatever arrives meanwhile: a reply the previous user of the port left in
    /// flight is not taken for the answer to the first request. Costs `SETTLE` (50 ms) before
    /// the first request.
    #[default]
    Drain,
    /// Throws away what the line holds and sends the first request at once. For a driver whose
    /// first exchanges detect a reply out of step (each request's input is flushed before it is
    /// written, so a stale reply can only shift the replies of the first exchanges, and those
    /// are checked), e.g. the Gotmic driver's `CRC ON`, `*IDN?`, ID register.
    Flush,
}

/// The operating-system path of an `ASRL` device: `ASRL3` is the third port, otherwise the text
/// after `ASRL` is the path itself (`ASRL/dev/ttyUSB0`).
pub fn device_path(device: &str) -> String {
    match device.parse::<u32>() {
        Ok(n) if cfg!(windows) => format!("COM{n}"),
        Ok(n) => format!("/dev/ttyS{}", n.saturating_sub(1)),
        Err(_) => device.to_string(),
    }
}

/// The largest message a serial link takes, whatever `max_message_bytes` says: 1 MiB is 91 s at
/// 115200 baud. It bounds how long a device that streams without ever ending a line keeps a read
/// alive (its bytes arrive at a healthy rate, so only their number can stop it).
pub(crate) const MAX_MESSAGE: usize = 1 << 20;

/// How long one blocking read waits before the thread checks its deadline again.
const POLL: Duration = Duration::from_millis(20);
/// A line silent this long has no reply left in flight: how a drain knows it is done.
pub(crate) const SETTLE: Duration = Duration::from_millis(50);
/// A drain gives up when the device keeps talking this long (it is then not a reply left over).
pub(crate) const DRAIN_LIMIT: Duration = Duration::from_secs(1);

/// The deadline rule of [`Timeouts`](super::Timeouts), carried to the serial thread.
#[derive(Debug, Clone, Copy)]
struct ReadBudget {
    base: Duration,
    timeouts: super::io::Timeouts,
    max_counted: u64,
}

impl ReadBudget {
    fn allowed(&self, counted: u64) -> Duration {
        self.base + self.timeouts.allowance_for(counted.min(self.max_counted))
    }
}

enum Request {
    Write(Vec<u8>, Duration, oneshot::Sender<Result<(), LinkError>>),
    Read(ReadBudget, oneshot::Sender<Result<Bytes, LinkError>>),
    Clear(oneshot::Sender<Result<(), LinkError>>),
    /// Close the port, then answer: whoever opens the device next finds it free (the port is
    /// opened exclusively).
    Close(oneshot::Sender<Result<(), LinkError>>),
}

pub struct SerialLink {
    device: String,
    requests: mpsc::Sender<Request>,
    /// Disconnects once the serial thread has let go of the port (in a mutex only so the link
    /// is `Sync`; drop reaches it without locking).
    released: std::sync::Mutex<mpsc::Receiver<()>>,
}

/// How long dropping a link waits for its thread to let go of the port (only a request still
/// under way makes it wait at all).
const RELEASE_WAIT: Duration = Duration::from_secs(1);

impl Drop for SerialLink {
    /// Lets the serial thread go and waits (bounded) until it has closed the port, so dropping
    /// a session and opening the same device again does not meet the exclusive lock.
    fn drop(&mut self) {
        let (idle, _) = mpsc::channel();
        drop(std::mem::replace(&mut self.requests, idle));
        let released = self.released.get_mut().unwrap_or_else(|p| p.into_inner());
        let _ = released.recv_timeout(RELEASE_WAIT);
    }
}

impl SerialLink {
    pub async fn open(device: &str, options: &LinkOptions) -> Result<Self, LinkError> {
        let path = device_path(device);
        let builder = options.serial.builder(&path)?;
        let limit = options.max_message_bytes;
        let open_path = path.clone();
        let on_open = options.serial_on_open;
        let port = tokio::task::spawn_blocking(move || builder.open())
            .await
            .map_err(|e| LinkError::Serial {
                device: open_path.clone(),
                detail: format!("the opening thread failed: {e}"),
            })?
            .map_err(|e| LinkError::Serial {
                device: open_path,
                detail: format!("cannot open: {e}; check the device path and permissions"),
            })?;
        Self::from_port_ending(port, path, limit, on_open, options.serial.reply_end())
    }

    /// Runs a link over an already open port (tests use a pseudo-terminal pair), drained before
    /// its first request ([`OnOpen::Drain`]). Messages are at most `limit` bytes, and never more
    /// than `MAX_MESSAGE`.
    pub fn from_port(
        port: Box<dyn serialport::SerialPort>,
        device: String,
        limit: usize,
    ) -> Result<Self, LinkError> {
        Self::from_port_with(port, device, limit, OnOpen::Drain)
    }

    /// [`from_port`](Self::from_port) with the line handled as `on_open` says before the first
    /// request.
    pub fn from_port_with(
        port: Box<dyn serialport::SerialPort>,
        device: String,
        limit: usize,
        on_open: OnOpen,
    ) -> Result<Self, LinkError> {
        Self::from_port_ending(port, device, limit, on_open, b'\n')
    }

    /// [`from_port_with`](Self::from_port_with) for a device whose replies end at `reply_end`.
    pub(crate) fn from_port_ending(
        port: Box<dyn serialport::SerialPort>,
        device: String,
        limit: usize,
        on_open: OnOpen,
        reply_end: u8,
    ) -> Result<Self, LinkError> {
        let limit = limit.min(MAX_MESSAGE);
        let (tx, rx) = mpsc::channel();
        let (released_tx, released) = mpsc::channel::<()>();
        let name = device.clone();
        std::thread::Builder::new()
            .name(format!("serial {device}"))
            .spawn(move || {
                serve(port, rx, name, limit, on_open, reply_end);
                // The port is closed once serve returns: the link's drop may go on.
                drop(released_tx);
            })
            .map_err(|e| LinkError::Serial {
                device: device.clone(),
                detail: format!("cannot start the serial thread: {e}"),
            })?;
        Ok(Self {
            device,
            requests: tx,
            released: std::sync::Mutex::new(released),
        })
    }

    /// Closes the port and returns once it is closed, so the device can be opened again at
    /// once (by this process or another).
    pub async fn close(self) -> Result<(), LinkError> {
        self.ask(Request::Close).await
    }

    fn gone(&self) -> LinkError {
        LinkError::Serial {
            device: self.device.clone(),
            detail: "the serial thread has stopped; reopen the link".into(),
        }
    }

    async fn ask<T>(
        &self,
        make: impl FnOnce(oneshot::Sender<Result<T, LinkError>>) -> Request,
    ) -> Result<T, LinkError> {
        let (tx, rx) = oneshot::channel();
        self.requests.send(make(tx)).map_err(|_| self.gone())?;
        rx.await.map_err(|_| self.gone())?
    }

    pub async fn write_message(
        &mut self,
        parts: &[&[u8]],
        options: &LinkOptions,
    ) -> Result<(), LinkError> {
        let data = parts.concat();
        let allowed = options.timeouts.write + options.timeouts.allowance_for(data.len() as u64);
        self.ask(|tx| Request::Write(data, allowed, tx)).await
    }

    pub async fn read_message(&mut self, options: &LinkOptions) -> Result<Bytes, LinkError> {
        let budget = ReadBudget {
            base: options.timeouts.read,
            timeouts: options.timeouts,
            max_counted: options.max_message_bytes.min(MAX_MESSAGE) as u64,
        };
        self.ask(|tx| Request::Read(budget, tx)).await
    }

    /// Discards everything buffered in both directions, then drains: bytes are read and thrown
    /// away until the line has been quiet for `SETTLE`, so a late reply to an abandoned request
    /// is not taken for the next answer.
    pub async fn device_clear(&mut self) -> Result<(), LinkError> {
        self.ask(Request::Clear).await
    }
}

fn serve(
    mut port: Box<dyn serialport::SerialPort>,
    requests: mpsc::Receiver<Request>,
    device: String,
    limit: usize,
    on_open: OnOpen,
    reply_end: u8,
) {
    let mut inbox = Inbox {
        decoder: TerminatedDecoder::new(reply_end, limit),
        ceiling: buffer_ceiling(limit),
        buf: BytesMut::with_capacity(4096),
    };
    // A reply a previous user of the port left unread is not the answer to our first request.
    let mut opened = Some(match on_open {
        OnOpen::Drain => drain(port.as_mut(), &device),
        OnOpen::Flush => {
            port.clear(serialport::ClearBuffer::Input)
                .map_err(|e| LinkError::Serial {
                    device: device.clone(),
                    detail: format!("cannot clear the input buffer: {e}"),
                })
        }
    });
    while let Ok(request) = requests.recv() {
        if let Some(Err(e)) = opened.take() {
            // Reported once, with the first request.
            tracing::warn!("{e}");
        }
        match request {
            Request::Write(data, allowed, reply) => {
                // Whatever arrived before this request cannot be its reply: a reply nobody read
                // (a command that answers, an abandoned query) is dropped here.
                inbox.reset();
                let _ = port.clear(serialport::ClearBuffer::Input);
                let _ = reply.send(write_all(port.as_mut(), &data, allowed, &device));
            }
            Request::Read(budget, reply) => {
                let _ = reply.send(inbox.read_message(port.as_mut(), budget));
            }
            Request::Clear(reply) => {
                inbox.reset();
                let result = port
                    .clear(serialport::ClearBuffer::All)
                    .map_err(|e| LinkError::Serial {
                        device: device.clone(),
                        detail: format!("cannot clear buffers: {e}"),
                    })
                    .and_then(|()| drain(port.as_mut(), &device));
                let _ = reply.send(result);
            }
            Request::Close(reply) => {
                drop(port);
                let _ = reply.send(Ok(()));
                return;
            }
        }
    }
}

/// Writes every byte within `allowed`, then waits for the line to send them.
fn write_all(
    port: &mut dyn serialport::SerialPort,
    data: &[u8],
    allowed: Duration,
    device: &str,
) -> Result<(), LinkError> {
    let started = Instant::now();
    let mut rest = data;
    while !rest.is_empty() {
        if started.elapsed() > allowed {
            return Err(LinkError::Timeout {
                op: "serial write",
                after: allowed,
            });
        }
        match port.write(rest) {
            Ok(n) => rest = &rest[n..],
            Err(e) if e.kind() == std::io::ErrorKind::TimedOut => continue,
            Err(e) => return Err(serial_io_error("serial write", e)),
        }
    }
    // Every byte is with the driver; waiting for the line to send them fails only when it hung
    // up (an unplugged adapter, a closed pty: `serialport` keeps no errno here), so that is
    // reported as the instrument going away.
    port.flush().map_err(|e| {
        tracing::debug!(%device, "serial drain failed: {e}");
        LinkError::Closed {
            op: "serial write (drain)",
        }
    })
}

/// Bytes received and not yet taken as a message.
struct Inbox {
    decoder: TerminatedDecoder,
    ceiling: usize,
    buf: BytesMut,
}

impl Inbox {
    fn reset(&mut self) {
        self.decoder.reset();
        self.buf.clear();
    }

    /// Reads until one whole message is buffered, within the budget of the bytes counted.
    fn read_message(
        &mut self,
        port: &mut dyn serialport::SerialPort,
        budget: ReadBudget,
    ) -> Result<Bytes, LinkError> {
        let started = Instant::now();
        let mut chunk = [0u8; 4096];
        let mut counted = 0u64;
        loop {
            match self.decoder.decode(&mut self.buf) {
                Ok(Some(frame)) => return Ok(frame),
                Ok(None) => {}
                Err(e) => {
                    self.reset();
                    return Err(LinkError::codec("serial")(e));
                }
            }
            let allowed = budget.allowed(counted);
            if started.elapsed() > allowed {
                return Err(LinkError::Timeout {
                    op: "serial read",
                    after: allowed,
                });
            }
            match port.read(&mut chunk) {
                Ok(0) => return Err(LinkError::Closed { op: "serial read" }),
                Ok(n) => {
                    counted += n as u64;
                    reserve_within(&mut self.buf, n, self.ceiling);
                    self.buf.extend_from_slice(&chunk[..n]);
                }
                Err(e) if e.kind() == std::io::ErrorKind::TimedOut => {}
                Err(e) => return Err(serial_io_error("serial read", e)),
            }
        }
    }
}

/// Reads and throws away bytes until the line has been quiet for [`SETTLE`]; an error when it
/// never goes quiet within [`DRAIN_LIMIT`]. Each read waits at most until the quiet window would
/// end, so the drain takes `SETTLE` on a quiet line, not the next multiple of [`POLL`].
fn drain(port: &mut dyn serialport::SerialPort, device: &str) -> Result<(), LinkError> {
    let result = drain_reads(port, device);
    // The port's usual read timeout is back whatever happened.
    let _ = port.set_timeout(POLL);
    result
}

fn drain_reads(port: &mut dyn serialport::SerialPort, device: &str) -> Result<(), LinkError> {
    let started = Instant::now();
    let mut quiet_since = Instant::now();
    let mut chunk = [0u8; 4096];
    let mut thrown = 0usize;
    loop {
        let quiet = quiet_since.elapsed();
        if quiet >= SETTLE {
            if thrown > 0 {
                tracing::debug!(device, thrown, "serial: drained bytes nobody asked for");
            }
            return Ok(());
        }
        let _ = port.set_timeout((SETTLE - quiet).clamp(Duration::from_millis(1), POLL));
        if started.elapsed() >= DRAIN_LIMIT {
            return Err(LinkError::Serial {
                device: device.to_string(),
                detail: format!(
                    "the device kept sending for {} without being asked ({thrown} bytes thrown \
                     away); check the line settings and that it is not in a streaming mode",
                    super::error::Rounded(DRAIN_LIMIT)
                ),
            });
        }
        match port.read(&mut chunk) {
            Ok(0) => return Ok(()),
            Ok(n) => {
                thrown += n;
                quiet_since = Instant::now();
            }
            Err(e) if e.kind() == std::io::ErrorKind::TimedOut => {}
            Err(e) => return Err(serial_io_error("serial drain", e)),
        }
    }
}

/// Maps a serial I/O error; a device that went away (a USB adapter unplugged, the far end of a
/// pseudo-terminal closed: EIO) is [`LinkError::Closed`].
fn serial_io_error(op: &'static str, e: std::io::Error) -> LinkError {
    #[cfg(unix)]
    if e.raw_os_error() == Some(libc::EIO) {
        return LinkError::Closed { op };
    }
    super::io::io_error(op, e)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn asrl_numbers_map_to_ports_and_paths_pass_through() {
        assert_eq!(device_path("/dev/ttyUSB0"), "/dev/ttyUSB0");
        if !cfg!(windows) {
            assert_eq!(device_path("1"), "/dev/ttyS0");
        }
    }

    #[test]
    fn bad_settings_name_the_field() {
        let s = SerialSettings {
            parity: "mark".into(),
            ..Default::default()
        };
        let e = s.builder("/dev/null").unwrap_err().to_string();
        assert!(e.contains("parity"), "{e}");
        let s = SerialSettings {
            data_bits: 9,
            ..Default::default()
        };
        assert!(s
            .builder("x")
            .unwrap_err()
            .to_string()
            .contains("data_bits"));
        for bad in ["", "\r\n\r\n\r"] {
            let s = SerialSettings {
                line_terminator: bad.into(),
                ..Default::default()
            };
            let e = s.builder("x").unwrap_err().to_string();
            assert!(e.contains("line_terminator") && e.contains("1 to 4"), "{e}");
        }
        let cr = SerialSettings {
            line_terminator: "\r\n".into(),
            ..Default::default()
        };
        assert_eq!(cr.reply_end(), b'\n');
    }
}
