//! A network endpoint that can be closed and reopened on the same ports, as a scope's remote
//! interface is switched between VICP and VXI-11 (Utilities > Remote on the real one).
//!
//! While closed, its ports stay bound but do not listen: a client's connection is refused at
//! once (TCP reset), as by a real instrument whose port is closed, and no other program takes the
//! port meanwhile, so reopening finds it free. Opening starts the protocol server on exactly those
//! ports; closing stops it (and drops its clients) before the ports are held again.

use std::io;
use std::net::SocketAddr;
use std::sync::Arc;

use tokio::net::TcpSocket;

use super::launch::{self, describe, Endpoint, Ports, Transport};
use super::{Handler, ServerError, ServerHandle, ServerOptions};

/// One switchable network endpoint (not serial, not a portmapper).
pub(crate) struct Switchable {
    instrument: String,
    handler: Arc<dyn Handler>,
    transport: Transport,
    options: ServerOptions,
    /// The ports in use, fixed once the endpoint has them (OS-chosen ports are kept).
    ports: Ports,
    state: State,
    endpoint: Endpoint,
}

enum State {
    Open(ServerHandle),
    /// Bound, not listening: connections are refused, the ports stay ours.
    Closed(Vec<TcpSocket>),
}

impl Switchable {
    /// Starts the endpoint open, or closed with `closed_reason`. Port 0 lets the OS choose; the
    /// chosen ports are kept for every later reopening.
    pub(crate) async fn start(
        instrument: &str,
        handler: Arc<dyn Handler>,
        transport: Transport,
        ports: Ports,
        options: ServerOptions,
        closed_reason: Option<String>,
    ) -> Result<Switchable, ServerError> {
        if transport == Transport::Serial || ports.portmapper.is_some() {
            return Err(ServerError::Start {
                protocol: transport.name(),
                source: io::Error::other(
                    "only network endpoints without a portmapper can be switched",
                ),
            });
        }
        let mut this = Switchable {
            instrument: instrument.to_string(),
            handler,
            transport,
            options,
            ports,
            state: State::Closed(Vec::new()),
            endpoint: describe(instrument, transport, loopback(0), None, None),
        };
        match closed_reason {
            None => this.open().await?,
            Some(reason) => {
                let sockets = this.hold_ports()?;
                this.endpoint = this.describe_ports();
                this.endpoint.active = false;
                this.endpoint.reason = Some(reason);
                this.state = State::Closed(sockets);
            }
        }
        Ok(this)
    }

    /// Where clients find it, and whether it accepts them now.
    pub(crate) fn endpoint(&self) -> &Endpoint {
        &self.endpoint
    }

    /// True while it accepts connections.
    pub(crate) fn is_open(&self) -> bool {
        matches!(self.state, State::Open(_))
    }

    /// Starts serving on the endpoint's ports (nothing when already open). When the ports cannot
    /// be had (another program took one), the endpoint stays closed and says why.
    pub(crate) async fn open(&mut self) -> Result<(), ServerError> {
        if self.is_open() {
            return Ok(());
        }
        // Release the held ports, then listen on them.
        self.state = State::Closed(Vec::new());
        let started = launch::start_network(
            &self.instrument,
            Arc::clone(&self.handler),
            self.transport,
            self.ports,
            self.options.clone(),
        )
        .await;
        match started {
            Ok((handle, endpoint)) => {
                self.ports.main = handle.local_addr().port();
                self.ports.abort = handle.listener("abort").map_or(0, |a| a.port());
                self.endpoint = endpoint;
                self.state = State::Open(handle);
                Ok(())
            }
            Err(err) => {
                self.endpoint.active = false;
                self.endpoint.reason = Some(format!("could not be reopened: {err}"));
                if let Ok(held) = self.hold_ports() {
                    self.state = State::Closed(held);
                }
                Err(err)
            }
        }
    }

    /// Stops serving (clients are dropped) and holds the ports closed; returns once a new
    /// connection is refused. `reason` is reported in the endpoint's description.
    pub(crate) async fn close(&mut self, reason: String) -> Result<(), ServerError> {
        self.endpoint.active = false;
        self.endpoint.reason = Some(reason);
        let held = match std::mem::replace(&mut self.state, State::Closed(Vec::new())) {
            State::Open(handle) => {
                handle.stop().await;
                Vec::new()
            }
            State::Closed(held) => held,
        };
        let held = if held.is_empty() {
            self.hold_ports()?
        } else {
            held
        };
        self.state = State::Closed(held);
        Ok(())
    }

    /// Binds (without listening) every port of the endpoint, choosing the OS-assigned ones.
    fn hold_ports(&mut self) -> Result<Vec<TcpSocket>, ServerError> {
        let main = hold(self.transport, self.ports.main)?;
        self.ports.main = port_of(self.transport, &main)?;
        let mut sockets = vec![main];
        if self.transport == Transport::Vxi11 {
            let abort = hold(self.transport, self.ports.abort)?;
            self.ports.abort = port_of(self.transport, &abort)?;
            sockets.push(abort);
        }
        Ok(sockets)
    }

    fn describe_ports(&self) -> Endpoint {
        let abort = (self.transport == Transport::Vxi11).then(|| loopback(self.ports.abort));
        describe(
            &self.instrument,
            self.transport,
            loopback(self.ports.main),
            abort,
            None,
        )
    }
}

fn loopback(port: u16) -> SocketAddr {
    SocketAddr::from(([127, 0, 0, 1], port))
}

/// A socket bound to `port` on 127.0.0.1 that does not listen. SO_REUSEADDR, as the servers
/// set it: the connections of the server just stopped may linger in TIME_WAIT on this port.
fn hold(transport: Transport, port: u16) -> Result<TcpSocket, ServerError> {
    let addr = loopback(port);
    let bind = || -> io::Result<TcpSocket> {
        let socket = TcpSocket::new_v4()?;
        socket.set_reuseaddr(true)?;
        socket.bind(addr)?;
        Ok(socket)
    };
    bind().map_err(|source| ServerError::Bind {
        protocol: transport.name(),
        addr,
        source,
    })
}

fn port_of(transport: Transport, socket: &TcpSocket) -> Result<u16, ServerError> {
    socket
        .local_addr()
        .map(|a| a.port())
        .map_err(|source| ServerError::Start {
            protocol: transport.name(),
            source,
        })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::emulator::loopback::Loopback;
    use std::time::Duration;
    use tokio::io::{AsyncBufReadExt, AsyncWriteExt, BufReader};
    use tokio::net::TcpStream;

    const LIMIT: Duration = Duration::from_secs(10);

    async fn connect(addr: &str) -> io::Result<TcpStream> {
        tokio::time::timeout(LIMIT, TcpStream::connect(addr))
            .await
            .expect("a connection is accepted or refused at once, not left hanging")
    }

    async fn identity(addr: &str) -> String {
        let stream = connect(addr).await.expect("open endpoint accepts");
        let (rd, mut wr) = stream.into_split();
        wr.write_all(b"*IDN?\n").await.unwrap();
        let mut line = String::new();
        tokio::time::timeout(LIMIT, BufReader::new(rd).read_line(&mut line))
            .await
            .unwrap()
            .unwrap();
        line
    }

    #[tokio::test]
    async fn closed_refuses_at_once_and_reopens_on_the_same_port() {
        let handler: Arc<dyn Handler> = Arc::new(Loopback::new());
        let mut ep = Switchable::start(
            "loopback",
            handler,
            Transport::Raw,
            Ports::default(),
            ServerOptions::default(),
            Some("switched off".into()),
        )
        .await
        .unwrap();
        let addr = ep.endpoint().address.clone();
        assert!(!ep.endpoint().active);
        assert_eq!(ep.endpoint().reason.as_deref(), Some("switched off"));
        let err = connect(&addr).await.expect_err("closed endpoint refuses");
        assert_eq!(err.kind(), io::ErrorKind::ConnectionRefused);

        ep.open().await.unwrap();
        assert_eq!(ep.endpoint().address, addr, "same port");
        assert!(ep.endpoint().active && ep.endpoint().reason.is_none());
        assert!(identity(&addr).await.starts_with("MOCK_LAB,LOOPBACK"));
        // A client connected while it closes is dropped; new ones are refused.
        let held = connect(&addr).await.unwrap();
        ep.close("off again".into()).await.unwrap();
        let err = connect(&addr).await.expect_err("refused after closing");
        assert_eq!(err.kind(), io::ErrorKind::ConnectionRefused);
        drop(held);
        ep.open().await.unwrap();
        assert!(identity(&addr).await.starts_with("MOCK_LAB,LOOPBACK"));
    }

    #[tokio::test]
    async fn vxi11_holds_and_reopens_both_channels() {
        let handler: Arc<dyn Handler> = Arc::new(Loopback::new());
        let mut ep = Switchable::start(
            "loopback",
            handler,
            Transport::Vxi11,
            Ports::default(),
            ServerOptions::default(),
            None,
        )
        .await
        .unwrap();
        let core = ep.endpoint().address.clone();
        let abort = ep.endpoint().abort_address.clone().unwrap();
        ep.close("off".into()).await.unwrap();
        for addr in [&core, &abort] {
            let err = connect(addr).await.expect_err("refused");
            assert_eq!(err.kind(), io::ErrorKind::ConnectionRefused, "{addr}");
        }
        ep.open().await.unwrap();
        assert_eq!(ep.endpoint().address, core);
        assert_eq!(ep.endpoint().abort_address.as_deref(), Some(abort.as_str()));
        for addr in [&core, &abort] {
            connect(addr).await.expect("accepts again");
        }
    }
}
