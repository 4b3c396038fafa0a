//! The whole simulated lab on 127.0.0.1: the [`Bench`] served on every transport each instrument
//! supports, the scene control channel, and a description of it all (JSON for scripts, a bench file
//! for radbench).
//!
//! | instrument | transports |
//! |---|---|
//! | `awg` (M8195A) | raw socket, HiSLIP, VXI-11 |
//! | `scope` (LabMaster) | VICP, VXI-11 (only the one selected as its remote interface answers) |
//! | `tx`, `rx` (Gotmic) | serial, on pseudo-terminals |
//! | `loopback` (test instrument, optional) | raw socket, VXI-11, HiSLIP, VICP, serial |

use crate::bench::Bench;
use crate::catalog::CatalogError;
use crate::control;
use crate::emulator::lecroy::RemoteInterface;
use crate::emulator::loopback::Loopback;
use crate::faults::Faults;
use crate::scene::Scene;
use crate::server::launch::{self, Endpoint, Ports, Running, Transport};
use crate::server::{Handler, ServerError, ServerOptions, DEFAULT_MAX_MESSAGE_SIZE};
use std::net::{Ipv4Addr, SocketAddr};
use std::sync::Arc;

/// How to start the lab.
#[derive(Debug, Clone)]
pub struct LabOptions {
    pub scene: Scene,
    /// Consecutive ports from this one instead of OS-assigned ones (see [`PORTS_PER_INSTRUMENT`]).
    pub port_base: Option<u16>,
    /// Port of the scope's VICP endpoint (pyvisa's VICP resource reaches only 1861).
    pub vicp_port: Option<u16>,
    /// Also run a VXI-11 portmapper on this port (111 is standard and needs root).
    pub portmapper_port: Option<u16>,
    /// Largest message a server accepts.
    pub max_message_size: usize,
    /// The scope's remote interface (Utilities > Remote on the real one).
    pub scope_remote: RemoteInterface,
    /// Also serve the generic loopback test instrument.
    pub with_loopback: bool,
    /// Port of the loopback instrument's VICP endpoint (interop tests through pyvisa need 1861).
    pub loopback_vicp_port: Option<u16>,
}

impl Default for LabOptions {
    fn default() -> Self {
        Self {
            scene: Scene::default(),
            port_base: None,
            vicp_port: None,
            portmapper_port: None,
            max_message_size: DEFAULT_MAX_MESSAGE_SIZE,
            scope_remote: RemoteInterface::Vicp,
            with_loopback: false,
            loopback_vicp_port: None,
        }
    }
}

/// Ports used per instrument with a port base: raw, VXI-11 core, VXI-11 abort, HiSLIP, VICP.
pub const PORTS_PER_INSTRUMENT: u16 = 5;

/// Why the lab did not start.
#[derive(Debug, thiserror::Error)]
pub enum LabError {
    #[error("the built-in instrument catalog is broken: {0}")]
    Catalog(#[from] CatalogError),
    #[error("cannot start {instrument} on {transport}: {source}")]
    Server {
        instrument: String,
        transport: &'static str,
        source: ServerError,
    },
    #[error("cannot start the scene control channel: {0}")]
    Control(std::io::Error),
    #[error("--port-base {0} is too high: the lab's ports would pass 65535; choose a lower base")]
    PortBase(u16),
}

/// The running lab; dropping it stops every server.
pub struct Lab {
    pub bench: Arc<Bench>,
    pub endpoints: Vec<Endpoint>,
    /// The scene control channel's address.
    pub control: SocketAddr,
    /// Fault switches shared by every server of the lab.
    pub faults: Arc<Faults>,
    _running: Vec<Running>,
}

struct Served {
    name: &'static str,
    handler: Arc<dyn Handler>,
    transports: &'static [Transport],
}

/// Starts the lab. Must run inside a tokio runtime; returns once every endpoint listens.
pub async fn start(options: LabOptions) -> Result<Lab, LabError> {
    let bench = Arc::new(Bench::new(options.scene.clone())?);
    bench.scope.set_remote_interface(options.scope_remote);
    let mut served = vec![
        Served {
            name: "awg",
            handler: bench.awg.clone(),
            transports: &[Transport::Raw, Transport::Hislip, Transport::Vxi11],
        },
        Served {
            name: "scope",
            handler: Arc::new(bench.scope.port(RemoteInterface::Vicp)),
            transports: &[Transport::Vicp],
        },
        Served {
            name: "scope",
            handler: Arc::new(bench.scope.port(RemoteInterface::Vxi11)),
            transports: &[Transport::Vxi11],
        },
        Served {
            name: "tx",
            handler: bench.tx.clone(),
            transports: &[Transport::Serial],
        },
        Served {
            name: "rx",
            handler: bench.rx.clone(),
            transports: &[Transport::Serial],
        },
    ];
    if options.with_loopback {
        served.push(Served {
            name: "loopback",
            handler: Arc::new(Loopback::new()),
            transports: &[
                Transport::Raw,
                Transport::Vxi11,
                Transport::Hislip,
                Transport::Vicp,
                Transport::Serial,
            ],
        });
    }
    let faults = Faults::new();
    let mut running = Vec::new();
    let mut endpoints = Vec::new();
    let mut slot = 0u16;
    let mut last_name = "";
    let mut portmapper = options.portmapper_port;
    for s in &served {
        if s.name != last_name && !last_name.is_empty() {
            slot += 1;
        }
        last_name = s.name;
        for &transport in s.transports {
            let mut ports = ports_for(options.port_base, slot, transport)?;
            if transport == Transport::Vicp && s.name == "scope" {
                ports.main = options.vicp_port.unwrap_or(ports.main);
            }
            if transport == Transport::Vicp && s.name == "loopback" {
                ports.main = options.loopback_vicp_port.unwrap_or(ports.main);
            }
            if transport == Transport::Vxi11 {
                ports.portmapper = portmapper.take();
            }
            let server_options = ServerOptions {
                max_message_size: options.max_message_size,
                faults: faults.clone(),
            };
            let (server, endpoint) =
                launch::start(s.name, s.handler.clone(), transport, ports, server_options)
                    .await
                    .map_err(|source| LabError::Server {
                        instrument: s.name.to_string(),
                        transport: transport.name(),
                        source,
                    })?;
            running.push(server);
            endpoints.push(endpoint);
        }
    }
    let control = control::serve(
        bench.scene.clone(),
        SocketAddr::from((Ipv4Addr::LOCALHOST, 0)),
    )
    .await
    .map_err(LabError::Control)?;
    Ok(Lab {
        bench,
        endpoints,
        control,
        faults,
        _running: running,
    })
}

fn ports_for(base: Option<u16>, slot: u16, transport: Transport) -> Result<Ports, LabError> {
    let mut ports = Ports::default();
    let Some(base) = base else {
        return Ok(ports);
    };
    let first = u32::from(base) + u32::from(slot) * u32::from(PORTS_PER_INSTRUMENT);
    let port = |offset: u32| u16::try_from(first + offset).map_err(|_| LabError::PortBase(base));
    ports.main = match transport {
        Transport::Raw => port(0)?,
        Transport::Vxi11 => port(1)?,
        Transport::Hislip => port(3)?,
        Transport::Vicp => port(4)?,
        Transport::Serial => 0,
    };
    if transport == Transport::Vxi11 {
        ports.abort = port(2)?;
    }
    Ok(ports)
}

impl Lab {
    /// The endpoint of `instrument` on `transport`, if served.
    pub fn endpoint(&self, instrument: &str, transport: Transport) -> Option<&Endpoint> {
        self.endpoints
            .iter()
            .find(|e| e.instrument == instrument && e.transport == transport)
    }

    /// One JSON object naming every endpoint and the control channel.
    pub fn describe_json(&self) -> serde_json::Value {
        serde_json::json!({
            "endpoints": self.endpoints,
            "control": self.control.to_string(),
        })
    }

    /// A radbench bench file for this lab, using the given transports for the AWG and the scope.
    pub fn bench_toml(&self, awg: Transport, scope: Transport) -> String {
        let resource = |name: &str, t: Transport| {
            self.endpoint(name, t)
                .map(|e| e.resource.clone())
                .unwrap_or_default()
        };
        format!(
            "# radbench bench file for the simulated lab (mock_lab); written by `mock-lab serve`.\n\
             # Every resource below is on 127.0.0.1 and lives as long as that process.\n\n\
             [awg]\nmodel = \"keysight-m8195a\"\nresource = \"{}\"\n\n\
             [scope]\nmodel = \"lecroy-labmaster10zi-a\"\nresource = \"{}\"\n\n\
             [tx]\nmodel = \"gotmic-eband-tx\"\nresource = \"{}\"\n\n\
             [rx]\nmodel = \"gotmic-eband-rx\"\nresource = \"{}\"\n\n\
             [simulation]\ncontrol = \"{}\"\n",
            resource("awg", awg),
            resource("scope", scope),
            resource("tx", Transport::Serial),
            resource("rx", Transport::Serial),
            self.control,
        )
    }
}

/// How [`serve_until_stopped`] describes the lab on standard output.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Announce {
    /// A table of endpoints and a ready-to-use bench file.
    Human,
    /// One JSON line naming every endpoint and the control channel (for scripts).
    Json,
}

/// Starts the lab, announces it on standard output, and serves until Ctrl-C (or, with
/// `until_stdin_closes`, until standard input reaches end of file, so a parent process that dies
/// takes the lab along).
pub async fn serve_until_stopped(
    options: LabOptions,
    announce: Announce,
    until_stdin_closes: bool,
) -> Result<(), LabError> {
    use std::io::Write;
    let lab = start(options).await?;
    let mut out = std::io::stdout().lock();
    let text = match announce {
        Announce::Json => format!("{}\n", lab.describe_json()),
        Announce::Human => {
            // Everything printed is a valid bench file: the table is made of comments.
            let mut t = format!(
                "# {:<9} {:<7} {:<24} resource\n",
                "instrument", "proto", "address"
            );
            for e in &lab.endpoints {
                t += &format!(
                    "# {:<9} {:<7} {:<24} {}\n",
                    e.instrument,
                    e.transport.name(),
                    e.address,
                    e.resource
                );
            }
            t += &format!("# {:<9} {:<7} {}\n#\n", "control", "json", lab.control);
            t +=
                "# serving on 127.0.0.1 until Ctrl-C; this output is a ready-to-use bench file\n\n";
            t += &lab.bench_toml(Transport::Hislip, Transport::Vicp);
            t
        }
    };
    // A closed stdout (a script that read the first line and left) must not stop the lab.
    let _ = out.write_all(text.as_bytes()).and_then(|()| out.flush());
    drop(out);
    let stdin_closed = async {
        if until_stdin_closes {
            let _ = tokio::task::spawn_blocking(|| {
                use std::io::Read;
                let mut sink = [0u8; 4096];
                let mut stdin = std::io::stdin();
                while matches!(stdin.read(&mut sink), Ok(n) if n > 0) {}
            })
            .await;
        } else {
            std::future::pending::<()>().await;
        }
    };
    tokio::select! {
        _ = tokio::signal::ctrl_c() => {}
        _ = stdin_closed => {}
    }
    drop(lab);
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::time::Duration;
    use tokio::io::{AsyncBufReadExt, AsyncWriteExt, BufReader};

    #[tokio::test]
    async fn lab_serves_every_instrument_and_describes_itself() {
        let lab = tokio::time::timeout(Duration::from_secs(10), start(LabOptions::default()))
            .await
            .expect("starts within 10 s")
            .unwrap();
        for (name, t) in [
            ("awg", Transport::Raw),
            ("awg", Transport::Hislip),
            ("awg", Transport::Vxi11),
            ("scope", Transport::Vicp),
            ("scope", Transport::Vxi11),
            ("tx", Transport::Serial),
            ("rx", Transport::Serial),
        ] {
            let e = lab
                .endpoint(name, t)
                .unwrap_or_else(|| panic!("{name} on {t:?}"));
            assert!(
                e.address.starts_with("127.0.0.1:") || e.address.starts_with("/dev/"),
                "{}",
                e.address
            );
        }
        let toml = lab.bench_toml(Transport::Hislip, Transport::Vicp);
        assert!(toml.contains("hislip0,"), "{toml}");
        assert!(toml.contains("VICP::127.0.0.1,"), "{toml}");
        let json = lab.describe_json();
        assert_eq!(json["control"], lab.control.to_string());

        // The AWG answers on its raw socket.
        let raw = lab.endpoint("awg", Transport::Raw).unwrap().address.clone();
        let stream = tokio::net::TcpStream::connect(&raw).await.unwrap();
        let (rd, mut wr) = stream.into_split();
        wr.write_all(b"*IDN?\n").await.unwrap();
        let mut line = String::new();
        tokio::time::timeout(
            Duration::from_secs(5),
            BufReader::new(rd).read_line(&mut line),
        )
        .await
        .unwrap()
        .unwrap();
        assert!(line.starts_with("MOCK_LAB,M8195A-EMU"), "{line}");
    }
}
