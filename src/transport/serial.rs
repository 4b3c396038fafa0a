//! Serial links (`ASRL<device>::INSTR`): a blocking `serialport` owned by one thread, bridged to
//! async with channels. Messages end at a newline outside binary blocks (as on a raw socket).
//!
//! Cancelling a request does not interrupt the thread mid-read: it finishes (or times out) and its
//! result is dropped, so a reply nobody waits for is never handed to the next reader.

use super::error::LinkError;
use super::framing::TerminatedDecoder;
use super::io::{Decode, LinkOptions};
use bytes::{Bytes, BytesMut};
use std::io::{Read, Write};
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
}

impl Default for SerialSettings {
    fn default() -> Self {
        Self {
            baud: 115_200,
            data_bits: 8,
            parity: "none".into(),
            stop_bits: 1,
            flow_control: "none".into(),
        }
    }
}

impl SerialSettings {
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
        Ok(serialport::new(path, self.baud)
            .data_bits(data_bits)
            .parity(parity)
            .stop_bits(stop_bits)
            .flow_control(flow)
            .timeout(POLL))
    }
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

/// How long one blocking read waits before the thread checks its deadline again.
const POLL: Duration = Duration::from_millis(20);

enum Request {
    Write(Vec<u8>, Duration, oneshot::Sender<Result<(), LinkError>>),
    Read(Duration, oneshot::Sender<Result<Bytes, LinkError>>),
    Clear(oneshot::Sender<Result<(), LinkError>>),
}

pub struct SerialLink {
    device: String,
    requests: mpsc::Sender<Request>,
}

impl SerialLink {
    pub async fn open(device: &str, options: &LinkOptions) -> Result<Self, LinkError> {
        let path = device_path(device);
        let builder = options.serial.builder(&path)?;
        let limit = options.max_message_bytes;
        let open_path = path.clone();
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
        Self::from_port(port, path, limit)
    }

    /// Runs a link over an already open port (tests use a pseudo-terminal pair).
    pub fn from_port(
        port: Box<dyn serialport::SerialPort>,
        device: String,
        limit: usize,
    ) -> Result<Self, LinkError> {
        let (tx, rx) = mpsc::channel();
        let name = device.clone();
        std::thread::Builder::new()
            .name(format!("serial {device}"))
            .spawn(move || serve(port, rx, name, limit))
            .map_err(|e| LinkError::Serial {
                device: device.clone(),
                detail: format!("cannot start the serial thread: {e}"),
            })?;
        Ok(Self {
            device,
            requests: tx,
        })
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
        let allowed = options.timeouts.read;
        self.ask(|tx| Request::Read(allowed, tx)).await
    }

    /// Discards everything buffered in both directions.
    pub async fn device_clear(&mut self) -> Result<(), LinkError> {
        self.ask(Request::Clear).await
    }
}

fn serve(
    mut port: Box<dyn serialport::SerialPort>,
    requests: mpsc::Receiver<Request>,
    device: String,
    limit: usize,
) {
    let mut decoder = TerminatedDecoder::new(b'\n', limit);
    let mut buf = BytesMut::with_capacity(4096);
    let io = |op: &'static str, e: std::io::Error| LinkError::Io { op, source: e };
    while let Ok(request) = requests.recv() {
        match request {
            Request::Write(data, allowed, reply) => {
                let started = Instant::now();
                let mut result = Ok(());
                let mut rest = &data[..];
                while !rest.is_empty() {
                    if started.elapsed() > allowed {
                        result = Err(LinkError::Timeout {
                            op: "serial write",
                            after: allowed,
                        });
                        break;
                    }
                    match port.write(rest) {
                        Ok(n) => rest = &rest[n..],
                        Err(e) if e.kind() == std::io::ErrorKind::TimedOut => continue,
                        Err(e) => {
                            result = Err(io("serial write", e));
                            break;
                        }
                    }
                }
                if result.is_ok() {
                    result = port.flush().map_err(|e| io("serial write", e));
                }
                let _ = reply.send(result);
            }
            Request::Read(allowed, reply) => {
                let started = Instant::now();
                let mut chunk = [0u8; 4096];
                let result = loop {
                    match decoder.decode(&mut buf) {
                        Ok(Some(frame)) => break Ok(frame),
                        Ok(None) => {}
                        Err(e) => {
                            decoder.reset();
                            buf.clear();
                            break Err(LinkError::codec("serial")(e));
                        }
                    }
                    let elapsed = started.elapsed();
                    if elapsed > allowed {
                        break Err(LinkError::Timeout {
                            op: "serial read",
                            after: elapsed,
                        });
                    }
                    match port.read(&mut chunk) {
                        Ok(0) => {
                            break Err(LinkError::Closed { op: "serial read" });
                        }
                        Ok(n) => buf.extend_from_slice(&chunk[..n]),
                        Err(e) if e.kind() == std::io::ErrorKind::TimedOut => {}
                        Err(e) => break Err(io("serial read", e)),
                    }
                };
                let _ = reply.send(result);
            }
            Request::Clear(reply) => {
                decoder.reset();
                buf.clear();
                let result =
                    port.clear(serialport::ClearBuffer::All)
                        .map_err(|e| LinkError::Serial {
                            device: device.clone(),
                            detail: format!("cannot clear buffers: {e}"),
                        });
                let _ = reply.send(result);
            }
        }
    }
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
    }
}
