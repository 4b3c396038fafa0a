//! Protocol servers. Each binds 127.0.0.1 (port 0 in tests), reports its address, serves several
//! clients at once, and hands whole messages to a pluggable [`Handler`].
//!
//! | module | protocol |
//! |---|---|
//! | [`raw`] | raw SCPI socket (LF-terminated, block-aware) |
//! | [`vxi11`] | VXI-11 core + abort channels, optional portmapper |
//! | [`hislip`] | HiSLIP 1.0 synchronous + asynchronous channels |
//! | [`vicp`] | LeCroy VICP (version 1a: sequence numbers, out-of-band serial poll) |
//! | [`serial`] | line-based serial endpoint on a pseudo-terminal |
//!
//! [`launch`] starts an instrument on any of them and describes the endpoint (address, VISA
//! resource string); `switch` closes and reopens a network endpoint on the same ports (a
//! scope's remote interface); `framing` holds the block-aware 488.2 message splitter they share.
//!
//! Every server takes [`ServerOptions`]: the largest message it accepts (length fields are
//! checked against it before anything is allocated) and the [`Faults`] the tests can switch on.
//! Handler calls run on tokio's blocking pool, so a handler that blocks (a scope's `WAIT`)
//! stalls only its own client.

pub(crate) mod conn;
pub(crate) mod framing;
pub mod hislip;
pub mod launch;
pub(crate) mod pool;
pub mod raw;
pub mod serial;
pub(crate) mod switch;
pub mod vicp;
pub mod vxi11;

use std::net::SocketAddr;
use std::sync::Arc;

use bytes::Bytes;
use thiserror::Error;
use tokio::task::JoinHandle;

use crate::faults::Faults;

/// What an emulated instrument does with whole messages. Servers frame bytes into messages
/// (terminator outside `#N` blocks, VXI-11 END, HiSLIP DataEnd, VICP EOI) and call these methods
/// from a blocking thread, so a handler may block (for example a scope's `WAIT`).
pub trait Handler: Send + Sync + 'static {
    /// One whole program message from a client. Returns the whole response messages it produced,
    /// in order (empty for commands that answer nothing). A response carries no transport framing;
    /// every server appends the 488.2 response terminator (LF, outside any `#N` block) when the
    /// response lacks one, and END-delimited transports end the message right after it.
    fn message(&self, data: &[u8]) -> Vec<Vec<u8>>;
    /// The same as [`Handler::message`], taking shared ownership of the bytes so a handler can
    /// keep a large block without copying it, and answering with [`Response`]s that may share
    /// their bytes (a stored block goes out without a copy). The servers call this one; the
    /// default forwards to [`Handler::message`].
    fn respond(&self, data: Bytes) -> Vec<Response> {
        self.message(&data)
            .into_iter()
            .map(Response::from)
            .collect()
    }
    /// IEEE 488.2 device clear: abandon pending input and output.
    fn device_clear(&self) {}
    /// The status byte, for serial polls (HiSLIP AsyncStatusQuery, VXI-11 device_readstb, VICP).
    /// The servers OR in MAV (bit 4) themselves when they hold output the client has not read.
    fn status_byte(&self) -> u8 {
        0
    }
    /// A group-execute trigger (VXI-11 device_trigger, HiSLIP Trigger).
    fn trigger(&self) {}
    /// On a serial line: what ends every request and every reply, for devices that are not
    /// IEEE 488.2 (a module's firmware ending lines with CR, say). `None`: LF, 488.2 framing.
    fn line_terminator(&self) -> Option<&[u8]> {
        None
    }
}

/// One response message: byte pieces sent back to back. The pieces are shared ([`Bytes`]), so a
/// 64 MB block held by the instrument goes to the socket without being copied.
///
/// Terminator rule: a response of one piece (e.g. made from a `Vec<u8>`) gets the LF terminator
/// unless it already ends with one outside any block; a response of several pieces never carries
/// its own terminator, and the servers always append it.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct Response {
    parts: Vec<Bytes>,
}

impl Response {
    /// A response made of `parts` in order (e.g. a block header and a shared payload), without
    /// a terminator of its own.
    pub(crate) fn from_parts(parts: Vec<Bytes>) -> Response {
        Response {
            parts: parts.into_iter().filter(|p| !p.is_empty()).collect(),
        }
    }

    /// The pieces, in order.
    pub fn parts(&self) -> &[Bytes] {
        &self.parts
    }

    /// Total length in bytes.
    pub fn len(&self) -> usize {
        self.parts.iter().map(Bytes::len).sum()
    }

    /// True when the response has no bytes.
    pub fn is_empty(&self) -> bool {
        self.parts.is_empty()
    }

    /// All bytes in one buffer (a copy; tests and small responses).
    pub fn to_vec(&self) -> Vec<u8> {
        self.parts.concat()
    }

    /// Appends the LF response terminator unless the response already carries one (see the
    /// terminator rule above).
    pub fn terminated(mut self) -> Response {
        let carries_one = match self.parts.as_slice() {
            [only] => framing::has_terminator(only),
            _ => false,
        };
        if !carries_one {
            self.parts.push(Bytes::from_static(b"\n"));
        }
        self
    }

    /// Several responses joined with `sep` into one (`*IDN?;*OPC?`). One-piece responses are
    /// joined into one buffer, so the terminator check sees the whole joined text as before.
    pub fn join(responses: Vec<Response>, sep: &'static [u8]) -> Response {
        if responses.iter().all(|r| r.parts.len() <= 1) {
            let texts: Vec<Vec<u8>> = responses.iter().map(Response::to_vec).collect();
            return Response::from(texts.join(sep));
        }
        let mut parts = Vec::new();
        for (i, r) in responses.into_iter().enumerate() {
            if i > 0 {
                parts.push(Bytes::from_static(sep));
            }
            parts.extend(r.parts);
        }
        Response::from_parts(parts)
    }
}

impl From<Vec<u8>> for Response {
    fn from(bytes: Vec<u8>) -> Response {
        Response::from(Bytes::from(bytes))
    }
}

impl From<Bytes> for Response {
    fn from(bytes: Bytes) -> Response {
        Response {
            parts: if bytes.is_empty() {
                Vec::new()
            } else {
                vec![bytes]
            },
        }
    }
}

/// Settings shared by every server.
#[derive(Debug, Clone)]
pub struct ServerOptions {
    /// Largest message accepted from a client, in bytes. Length fields (blocks, HiSLIP, VICP,
    /// RPC records) above it are refused before any allocation.
    pub max_message_size: usize,
    /// Faults the tests can switch on while the server runs.
    pub faults: Arc<Faults>,
}

/// Default largest message: a 64 MB block plus headroom, times four.
pub const DEFAULT_MAX_MESSAGE_SIZE: usize = 256 << 20;

impl Default for ServerOptions {
    fn default() -> Self {
        ServerOptions {
            max_message_size: DEFAULT_MAX_MESSAGE_SIZE,
            faults: Faults::new(),
        }
    }
}

impl ServerOptions {
    /// Default options with the given faults.
    pub fn with_faults(faults: Arc<Faults>) -> ServerOptions {
        ServerOptions {
            faults,
            ..ServerOptions::default()
        }
    }
}

/// Why a server could not start.
#[derive(Debug, Error)]
pub enum ServerError {
    /// The listening socket could not be bound.
    #[error(
        "cannot listen on {addr} for {protocol}: {source}; pick a free port (0 lets the OS choose)"
    )]
    Bind {
        /// Protocol being served.
        protocol: &'static str,
        /// Address asked for.
        addr: SocketAddr,
        /// The OS error.
        source: std::io::Error,
    },
    /// The pseudo-terminal for the serial endpoint could not be created.
    #[error("cannot create a pseudo-terminal for the serial endpoint: {0}; check that /dev/ptmx is available")]
    Pty(#[from] serialport::Error),
    /// A socket or thread operation failed while starting.
    #[error("cannot start the {protocol} server: {source}")]
    Start {
        /// Protocol being served.
        protocol: &'static str,
        /// The OS error.
        source: std::io::Error,
    },
}

/// A running server: its addresses, and the tasks to stop when it is dropped.
#[derive(Debug)]
pub struct ServerHandle {
    protocol: &'static str,
    addr: SocketAddr,
    extra: Vec<(&'static str, SocketAddr)>,
    tasks: Vec<JoinHandle<()>>,
}

impl ServerHandle {
    pub(crate) fn new(protocol: &'static str, addr: SocketAddr, task: JoinHandle<()>) -> Self {
        ServerHandle {
            protocol,
            addr,
            extra: Vec::new(),
            tasks: vec![task],
        }
    }

    pub(crate) fn add_listener(
        &mut self,
        name: &'static str,
        addr: SocketAddr,
        task: JoinHandle<()>,
    ) {
        self.extra.push((name, addr));
        self.tasks.push(task);
    }

    /// The protocol served ("raw", "vxi11", "hislip", "vicp").
    pub fn protocol(&self) -> &'static str {
        self.protocol
    }

    /// The main listening address (the VXI-11 core channel for VXI-11).
    pub fn local_addr(&self) -> SocketAddr {
        self.addr
    }

    /// A secondary listener by name (VXI-11: "abort", "portmapper").
    pub fn listener(&self, name: &str) -> Option<SocketAddr> {
        self.extra.iter().find(|(n, _)| *n == name).map(|(_, a)| *a)
    }

    /// Stops accepting and drops every connection.
    pub fn shutdown(&mut self) {
        for task in self.tasks.drain(..) {
            task.abort();
        }
    }

    /// Stops accepting and returns once the listening sockets are closed (a port can then be
    /// bound again at once; [`ServerHandle::shutdown`] only asks the tasks to stop).
    pub async fn stop(mut self) {
        let tasks: Vec<JoinHandle<()>> = self.tasks.drain(..).collect();
        for task in &tasks {
            task.abort();
        }
        for task in tasks {
            // Cancelled (or already finished): either way its listener is gone.
            let _ = task.await;
        }
    }
}

impl Drop for ServerHandle {
    fn drop(&mut self) {
        self.shutdown();
    }
}

/// Binds a TCP listener, mapping the error to [`ServerError::Bind`].
pub(crate) async fn bind(
    protocol: &'static str,
    addr: SocketAddr,
) -> Result<tokio::net::TcpListener, ServerError> {
    tokio::net::TcpListener::bind(addr)
        .await
        .map_err(|source| ServerError::Bind {
            protocol,
            addr,
            source,
        })
}

/// The loopback address with an OS-chosen port: what tests bind.
pub fn loopback_any() -> SocketAddr {
    SocketAddr::from(([127, 0, 0, 1], 0))
}
