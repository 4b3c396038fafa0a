//! Layer 1: transports that move whole messages (architecture rule 1).
//!
//! A [`Link`] opens the transport named by a [`Resource`] and offers the same operations on all of
//! them: write a message (given as parts, sent without copying them together), read a message
//! (HiSLIP DataEnd, VXI-11 END, VICP EOI, or a newline outside `#N` blocks), device clear, status
//! byte, reconnect, close. Every exchange goes to the I/O `journal` when one is attached.
//!
//! | module | wire |
//! |---|---|
//! | `socket` | raw TCP, newline-terminated, block-aware (`framing`) |
//! | [`vxi11`] | ONC-RPC record marking, portmapper, core and abort channels |
//! | [`hislip`] | HiSLIP 1.0 sync + async channels |
//! | [`vicp`] | LeCroy VICP headers with sequence numbers |
//! | `serial` | `serialport` on its own thread |
//!
//! Deadlines and limits (docs/io-timeouts.md): a read ends by `start + read timeout +
//! min(bytes of this message received, max_message_bytes) / min_rate`; bytes thrown away (stale
//! replies) and lengths a header only announces earn no time, and no receive buffer grows past
//! the largest message plus a little framing slack. After undecodable bytes, or the instrument
//! closing the connection, the link is reopened.
//!
//! Cancellation: every operation may be dropped (e.g. by `tokio::time::timeout` or `select!`).
//! Reads keep their progress in the link, so nothing is lost; an operation dropped half-way marks
//! the link dirty, and the next operation first clears the device (after an abandoned read) or
//! reopens the connection (after an abandoned write, which may have left half a frame on the wire).

pub(crate) mod error;
pub(crate) mod framing;
pub mod hislip;
pub(crate) mod io;
pub(crate) mod journal;
pub(crate) mod serial;
pub(crate) mod socket;
pub mod vicp;
pub mod vxi11;

pub use framing::TerminatedDecoder;
pub use io::{
    buffer_ceiling, reserve_announced, reserve_within, Decode, FrameHeader, Framed, FramedDecoder,
};
pub use journal::{sha256_hex, JournalError};
pub use serial::{device_path, OnOpen, SerialLink};

pub(crate) use error::Rounded;
pub use error::{CodecError, ErrorKind, LinkError};
pub use io::{Direction, LinkOptions, Progress, ProgressFn, Timeouts};
pub use journal::{Journal, Origin};
pub use serial::SerialSettings;

use crate::address::{Resource, HISLIP_DEFAULT_PORT, VICP_DEFAULT_PORT};
use bytes::Bytes;
use std::time::{Duration, Instant};

enum Inner {
    Socket(socket::SocketLink),
    Vxi11(vxi11::Vxi11Link),
    Hislip(hislip::HislipLink),
    Vicp(vicp::VicpLink),
    Serial(serial::SerialLink),
}

/// What an interrupted operation left behind.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Dirty {
    Clean,
    /// A reply may be pending or half-read: clear the device.
    Read,
    /// Half a message may be on the wire: reopen the connection.
    Write,
}

/// An open connection to one instrument.
pub struct Link {
    resource: Resource,
    options: LinkOptions,
    inner: Option<Inner>,
    dirty: Dirty,
    journal: Option<Journal>,
    origin: Origin,
}

async fn open_inner(resource: &Resource, options: &LinkOptions) -> Result<Inner, LinkError> {
    Ok(match resource {
        Resource::Socket { host, port, .. } => {
            Inner::Socket(socket::SocketLink::connect(host, *port, options).await?)
        }
        Resource::Vxi11 {
            host, port, device, ..
        } => Inner::Vxi11(vxi11::Vxi11Link::connect(host, *port, device, options).await?),
        Resource::Hislip {
            host, index, port, ..
        } => Inner::Hislip(
            hislip::HislipLink::connect(
                host,
                port.unwrap_or(HISLIP_DEFAULT_PORT),
                &Resource::hislip_sub_address(*index),
                options,
            )
            .await?,
        ),
        Resource::Vicp { host, port, .. } => Inner::Vicp(
            vicp::VicpLink::connect(host, port.unwrap_or(VICP_DEFAULT_PORT), options).await?,
        ),
        Resource::Serial { device } => {
            Inner::Serial(serial::SerialLink::open(device, options).await?)
        }
    })
}

fn micros(since: Instant) -> u64 {
    since.elapsed().as_micros().min(u128::from(u64::MAX)) as u64
}

impl Link {
    /// Opens the transport the resource names.
    pub async fn open(resource: Resource, options: LinkOptions) -> Result<Self, LinkError> {
        Self::open_journalled(resource, options, None, "").await
    }

    /// Opens with an I/O journal; `instrument` names the instrument in the journal (e.g. `awg`).
    pub(crate) async fn open_journalled(
        resource: Resource,
        options: LinkOptions,
        journal: Option<Journal>,
        instrument: &str,
    ) -> Result<Self, LinkError> {
        let origin = Origin {
            instrument: instrument.to_string(),
            resource: resource.to_string(),
        };
        let started = Instant::now();
        let opened = open_inner(&resource, &options).await;
        if let Some(j) = &journal {
            match &opened {
                Ok(_) => j.event(&origin, "connect", None, micros(started)),
                Err(e) => j.failure(&origin, "event", e, micros(started)),
            }
        }
        Ok(Self {
            inner: Some(opened?),
            resource,
            options,
            dirty: Dirty::Clean,
            journal,
            origin,
        })
    }

    /// Wraps an already running serial link (tests use a pseudo-terminal pair).
    pub fn from_serial(resource: Resource, link: serial::SerialLink, options: LinkOptions) -> Self {
        Self {
            origin: Origin {
                instrument: String::new(),
                resource: resource.to_string(),
            },
            resource,
            options,
            inner: Some(Inner::Serial(link)),
            dirty: Dirty::Clean,
            journal: None,
        }
    }

    pub fn resource(&self) -> &Resource {
        &self.resource
    }

    pub fn options(&self) -> &LinkOptions {
        &self.options
    }

    /// What ends a request on this link: the serial settings' `line_terminator` on a serial
    /// line, LF (IEEE 488.2) everywhere else.
    pub(crate) fn line_end(&self) -> &[u8] {
        if matches!(self.resource, Resource::Serial { .. }) {
            self.options.serial.line_terminator.as_bytes()
        } else {
            b"\n"
        }
    }

    /// Timeouts, size limit and progress can be changed between operations.
    pub(crate) fn options_mut(&mut self) -> &mut LinkOptions {
        &mut self.options
    }

    /// Whether the transport marks message ends itself (HiSLIP, VXI-11, VICP). Without it (raw
    /// socket, serial), a newline ends a message and `#0` blocks must not contain one.
    pub(crate) fn has_message_end(&self) -> bool {
        !matches!(
            self.resource,
            Resource::Socket { .. } | Resource::Serial { .. }
        )
    }

    fn journal_result<T>(
        &self,
        direction: &'static str,
        started: Instant,
        result: &Result<T, LinkError>,
        parts: &[&[u8]],
    ) {
        let Some(j) = &self.journal else { return };
        match result {
            Ok(_) => j.message(&self.origin, direction, parts, micros(started)),
            Err(e) => j.failure(&self.origin, direction, e, micros(started)),
        }
    }

    async fn recover(&mut self) -> Result<(), LinkError> {
        match self.dirty {
            Dirty::Clean => Ok(()),
            Dirty::Read => match self.clear_inner().await {
                Ok(()) => Ok(()),
                Err(e) => {
                    tracing::info!(
                        "device clear after an abandoned read failed ({e}); reconnecting"
                    );
                    self.reconnect().await
                }
            },
            Dirty::Write => self.reconnect().await,
        }
    }

    /// Sends one message made of `parts` (e.g. a command header, a block payload, a newline).
    pub async fn write_message(&mut self, parts: &[&[u8]]) -> Result<(), LinkError> {
        self.recover().await?;
        let total: u64 = parts.iter().map(|p| p.len() as u64).sum();
        if total > self.options.max_message_bytes as u64 {
            return Err(LinkError::MessageTooLarge {
                size: total,
                limit: self.options.max_message_bytes as u64,
            });
        }
        let started = Instant::now();
        self.dirty = Dirty::Write;
        let options = &self.options;
        let result = match self.inner.as_mut().ok_or(LinkError::NotOpen)? {
            Inner::Socket(l) => l.write_message(parts, options).await,
            Inner::Vxi11(l) => l.write_message(parts, options).await,
            Inner::Hislip(l) => l.write_message(parts, options).await,
            Inner::Vicp(l) => l.write_message(parts, options).await,
            Inner::Serial(l) => l.write_message(parts, options).await,
        };
        self.settle(&result, Dirty::Write);
        self.journal_result("write", started, &result, parts);
        result
    }

    /// Reads one whole message (terminator included when the transport uses one).
    pub async fn read_message(&mut self) -> Result<Bytes, LinkError> {
        self.read_message_waiting(None).await
    }

    /// Like [`read_message`](Self::read_message), but the reply may take up to `read` to start
    /// (a long `*OPC?`, a scope's `WAIT`). The link's own timeouts stay as they are, so a dropped
    /// read cannot leave them changed.
    pub(crate) async fn read_message_within(&mut self, read: Duration) -> Result<Bytes, LinkError> {
        self.read_message_waiting(Some(read)).await
    }

    async fn read_message_waiting(&mut self, read: Option<Duration>) -> Result<Bytes, LinkError> {
        self.recover().await?;
        let started = Instant::now();
        self.dirty = Dirty::Read;
        let adjusted;
        let options = match read {
            Some(read) => {
                adjusted = LinkOptions {
                    timeouts: Timeouts {
                        read,
                        ..self.options.timeouts
                    },
                    ..self.options.clone()
                };
                &adjusted
            }
            None => &self.options,
        };
        let result = match self.inner.as_mut().ok_or(LinkError::NotOpen)? {
            Inner::Socket(l) => l.read_message(options).await,
            Inner::Vxi11(l) => l.read_message(options).await,
            Inner::Hislip(l) => l.read_message(options).await,
            Inner::Vicp(l) => l.read_message(options).await,
            Inner::Serial(l) => l.read_message(options).await,
        };
        self.settle(&result, Dirty::Read);
        if let Some(j) = &self.journal {
            match &result {
                Ok(data) => j.received(&self.origin, data, micros(started)),
                Err(e) => j.failure(&self.origin, "read", e, micros(started)),
            }
        }
        result
    }

    fn settle<T>(&mut self, result: &Result<T, LinkError>, on_error: Dirty) {
        let serial = matches!(self.inner, Some(Inner::Serial(_)));
        self.dirty = match result {
            Ok(_) => Dirty::Clean,
            // Undecodable bytes: where the next frame starts is unknown, and a protocol clear
            // would read through the same bytes. A fresh connection starts at a frame boundary.
            // (A serial clear already forgets the buffered bytes, and reopening a port the
            // serial thread may still hold would fail.)
            Err(LinkError::Codec { .. } | LinkError::Protocol { .. }) if !serial => Dirty::Write,
            // A connection the instrument closed cannot be cleared, only reopened.
            Err(LinkError::Closed { .. }) if !serial => Dirty::Write,
            Err(e) if e.leaves_link_dirty() => on_error,
            Err(_) => Dirty::Clean,
        };
    }

    async fn clear_inner(&mut self) -> Result<(), LinkError> {
        let options = &self.options;
        let result = match self.inner.as_mut().ok_or(LinkError::NotOpen)? {
            Inner::Socket(l) => l.device_clear(options).await,
            Inner::Vxi11(l) => l.device_clear(options).await,
            Inner::Hislip(l) => l.device_clear(options).await,
            Inner::Vicp(l) => l.device_clear(options).await,
            Inner::Serial(l) => l.device_clear().await,
        };
        if result.is_ok() {
            self.dirty = Dirty::Clean;
        }
        result
    }

    /// IEEE 488.2 device clear: the instrument drops pending input and output, and any reply still
    /// in flight is discarded here. On a raw socket this reopens the connection.
    pub async fn device_clear(&mut self) -> Result<(), LinkError> {
        if self.dirty == Dirty::Write {
            self.reconnect().await?;
        }
        let started = Instant::now();
        let result = self.clear_inner().await;
        if result.is_err() {
            self.dirty = Dirty::Write;
        }
        if let Some(j) = &self.journal {
            match &result {
                Ok(()) => j.event(&self.origin, "device_clear", None, micros(started)),
                Err(e) => j.failure(&self.origin, "event", e, micros(started)),
            }
        }
        result
    }

    /// The status byte by the protocol's own serial poll (VXI-11 readstb, HiSLIP
    /// AsyncStatusQuery, VICP in-band poll). Raw socket and serial return
    /// [`LinkError::Unsupported`]; the session then asks `*STB?`.
    pub async fn read_stb(&mut self) -> Result<u8, LinkError> {
        self.recover().await?;
        let started = Instant::now();
        let options = &self.options;
        let protocol = self.resource.protocol();
        let result = match self.inner.as_mut().ok_or(LinkError::NotOpen)? {
            Inner::Vxi11(l) => l.read_stb(options).await,
            Inner::Hislip(l) => l.read_stb(options).await,
            Inner::Vicp(l) => l.read_stb(options).await,
            Inner::Socket(_) | Inner::Serial(_) => {
                return Err(LinkError::Unsupported {
                    protocol,
                    op: "serial poll",
                })
            }
        };
        if let Some(j) = &self.journal {
            match &result {
                Ok(stb) => j.event(
                    &self.origin,
                    "status_byte",
                    Some((*stb).into()),
                    micros(started),
                ),
                Err(e) => j.failure(&self.origin, "event", e, micros(started)),
            }
        }
        result
    }

    /// Closes and reopens the connection (after an instrument reboot or a dropped link).
    pub async fn reconnect(&mut self) -> Result<(), LinkError> {
        let started = Instant::now();
        self.inner = None;
        let opened = open_inner(&self.resource, &self.options).await;
        if let Some(j) = &self.journal {
            match &opened {
                Ok(_) => j.event(&self.origin, "reconnect", None, micros(started)),
                Err(e) => j.failure(&self.origin, "event", e, micros(started)),
            }
        }
        self.inner = Some(opened?);
        self.dirty = Dirty::Clean;
        Ok(())
    }

    /// Closes the link politely (VXI-11 destroy_link); the link can be reopened with `reconnect`.
    pub async fn close(&mut self) -> Result<(), LinkError> {
        let started = Instant::now();
        let result = match self.inner.take() {
            Some(Inner::Vxi11(mut l)) if self.dirty == Dirty::Clean => l.close(&self.options).await,
            Some(Inner::Serial(l)) => l.close().await,
            _ => Ok(()),
        };
        if let Some(j) = &self.journal {
            j.event(&self.origin, "close", None, micros(started));
        }
        result
    }
}
