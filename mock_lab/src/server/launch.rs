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
    let endpoint = |address: String, resource: String| Endpoint {
        instrument: instrument.to_string(),
        transport,
        address,
        resource,
        abort_address: None,
        portmapper_address: None,
    };
    match transport {
        Transport::Serial => {
            let handle = serial::serve(handler, options)?;
            let path = handle.device_path().to_string();
            let ep = endpoint(path.clone(), format!("ASRL{path}::INSTR"));
            Ok((Running::Serial(handle), ep))
        }
        Transport::Raw => {
            let handle = raw::serve(loopback(ports.main), handler, options).await?;
            let a = handle.local_addr();
            let ep = endpoint(
                a.to_string(),
                format!("TCPIP::{}::{}::SOCKET", a.ip(), a.port()),
            );
            Ok((Running::Network(handle), ep))
        }
        Transport::Hislip => {
            let handle = hislip::serve(loopback(ports.main), handler, options).await?;
            let a = handle.local_addr();
            let ep = endpoint(
                a.to_string(),
                format!("TCPIP::{}::hislip0,{}::INSTR", a.ip(), a.port()),
            );
            Ok((Running::Network(handle), ep))
        }
        Transport::Vicp => {
            let handle = vicp::serve(loopback(ports.main), handler, options).await?;
            let a = handle.local_addr();
            let resource = if a.port() == 1861 {
                format!("VICP::{}::INSTR", a.ip())
            } else {
                format!("VICP::{},{}::INSTR", a.ip(), a.port())
            };
            Ok((Running::Network(handle), endpoint(a.to_string(), resource)))
        }
        Transport::Vxi11 => {
            let addrs = Vxi11Addresses {
                core: loopback(ports.main),
                abort: loopback(ports.abort),
                portmapper: ports.portmapper.map(loopback),
            };
            let handle = vxi11::serve(addrs, handler, options).await?;
            let a = handle.local_addr();
            let mut ep = endpoint(
                a.to_string(),
                format!("TCPIP::{},{}::inst0::INSTR", a.ip(), a.port()),
            );
            ep.abort_address = handle.listener("abort").map(|a| a.to_string());
            ep.portmapper_address = handle.listener("portmapper").map(|a| a.to_string());
            Ok((Running::Network(handle), ep))
        }
    }
}
