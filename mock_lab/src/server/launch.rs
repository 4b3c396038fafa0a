//! Starting an instrument on a transport and describing the endpoint for clients: what the
//! `mock-lab` binary prints (one JSON line or a table) so tests and users know where to connect.

use std::net::{IpAddr, Ipv4Addr, SocketAddr};
use std::sync::Arc;

use serde::Serialize;

use super::serial::SerialHandle;
use super::vxi11::Vxi11Addresses;
use super::{hislip, raw, serial, vicp, vxi11, Handler, ServerError, ServerHandle, ServerOptions};

/// The transports an instrument can be served on.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Transport {
    /// Raw SCPI socket.
    Raw,
    /// VXI-11 (core channel on the given port, abort on another, optional portmapper).
    Vxi11,
    /// HiSLIP.
    Hislip,
    /// LeCroy VICP.
    Vicp,
    /// Line-based serial on a pseudo-terminal.
    Serial,
}

impl Transport {
    /// Every network transport, in the order the binary starts them.
    pub const NETWORK: [Transport; 4] = [
        Transport::Raw,
        Transport::Vxi11,
        Transport::Hislip,
        Transport::Vicp,
    ];

    /// Lower-case name, as in the JSON.
    pub fn name(self) -> &'static str {
        match self {
            Transport::Raw => "raw",
            Transport::Vxi11 => "vxi11",
            Transport::Hislip => "hislip",
            Transport::Vicp => "vicp",
            Transport::Serial => "serial",
        }
    }
}

/// Where a client finds one instrument on one transport.
#[derive(Debug, Clone, PartialEq, Eq, Serialize)]
pub struct Endpoint {
    /// Instrument name (for example `loopback`).
    pub instrument: String,
    /// Transport name.
    pub transport: Transport,
    /// `host:port` for network transports, the device path for serial.
    pub address: String,
    /// VISA-style resource string a client can open.
    pub resource: String,
    /// VXI-11 only: the abort channel's `host:port`.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub abort_address: Option<String>,
    /// VXI-11 only: the portmapper's `host:port`, when one runs.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub portmapper_address: Option<String>,
    /// Whether the endpoint accepts connections now. A closed one refuses them at once, as a
    /// real instrument's closed port does (the scope's VXI-11 port while its remote interface is
    /// VICP); `reason` says why and what opens it.
    pub active: bool,
    /// Why the endpoint is closed (only when it is).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub reason: Option<String>,
}

/// A running server of any kind; dropping it stops it.
#[derive(Debug)]
pub enum Running {
    /// A TCP server.
    Network(ServerHandle),
    /// A serial endpoint.
    Serial(SerialHandle),
}

/// Ports to use for one network transport (0 lets the OS choose).
#[derive(Debug, Clone, Copy, Default)]
pub struct Ports {
    /// Main port (VXI-11: core channel).
    pub main: u16,
    /// VXI-11 abort channel.
    pub abort: u16,
    /// VXI-11 portmapper; `None` runs none.
    pub portmapper: Option<u16>,
}

fn loopback(port: u16) -> SocketAddr {
    SocketAddr::new(IpAddr::V4(Ipv4Addr::LOCALHOST), port)
}

/// Starts `handler` as `instrument` on `transport` and describes the endpoint.
pub async fn start(
    instrument: &str,
    handler: Arc<dyn Handler>,
    transport: Transport,
    ports: Ports,
    options: ServerOptions,
) -> Result<(Running, Endpoint), ServerError> {
    if transport == Transport::Serial {
        let handle = serial::serve(handler, options)?;
        let path = handle.device_path().to_string();
        let ep = Endpoint {
            instrument: instrument.to_string(),
            transport,
            address: path.clone(),
            resource: format!("ASRL{path}::INSTR"),
            abort_address: None,
            portmapper_address: None,
            active: true,
            reason: None,
        };
        return Ok((Running::Serial(handle), ep));
    }
    let (handle, ep) = start_network(instrument, handler, transport, ports, options).await?;
    Ok((Running::Network(handle), ep))
}

/// [`start`] for the network transports; `Serial` is refused.
pub(crate) async fn start_network(
    instrument: &str,
    handler: Arc<dyn Handler>,
    transport: Transport,
    ports: Ports,
    options: ServerOptions,
) -> Result<(ServerHandle, Endpoint), ServerError> {
    let handle = match transport {
        Transport::Serial => {
            return Err(ServerError::Start {
                protocol: transport.name(),
                source: std::io::Error::other("a serial endpoint has no network server"),
            })
        }
        Transport::Raw => raw::serve(loopback(ports.main), handler, options).await?,
        Transport::Hislip => hislip::serve(loopback(ports.main), handler, options).await?,
        Transport::Vicp => vicp::serve(loopback(ports.main), handler, options).await?,
        Transport::Vxi11 => {
            let addrs = Vxi11Addresses {
                core: loopback(ports.main),
                abort: loopback(ports.abort),
                portmapper: ports.portmapper.map(loopback),
            };
            vxi11::serve(addrs, handler, options).await?
        }
    };
    let ep = describe(
        instrument,
        transport,
        handle.local_addr(),
        handle.listener("abort"),
        handle.listener("portmapper"),
    );
    Ok((handle, ep))
}

/// Describes a network endpoint listening (or closed) at these addresses.
pub fn describe(
    instrument: &str,
    transport: Transport,
    main: SocketAddr,
    abort: Option<SocketAddr>,
    portmapper: Option<SocketAddr>,
) -> Endpoint {
    let (ip, port) = (main.ip(), main.port());
    let resource = match transport {
        Transport::Raw => format!("TCPIP::{ip}::{port}::SOCKET"),
        Transport::Hislip => format!("TCPIP::{ip}::hislip0,{port}::INSTR"),
        Transport::Vicp if port == 1861 => format!("VICP::{ip}::INSTR"),
        Transport::Vicp => format!("VICP::{ip},{port}::INSTR"),
        Transport::Vxi11 => format!("TCPIP::{ip},{port}::inst0::INSTR"),
        Transport::Serial => format!("ASRL{main}::INSTR"),
    };
    Endpoint {
        instrument: instrument.to_string(),
        transport,
        address: main.to_string(),
        resource,
        abort_address: abort.map(|a| a.to_string()),
        portmapper_address: portmapper.map(|a| a.to_string()),
        active: true,
        reason: None,
    }
}
