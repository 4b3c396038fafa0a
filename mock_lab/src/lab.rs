//! The whole simulated lab on 127.0.0.1: the [`Bench`] served on every transport each instrument
//! supports, the scene control channel, and a description of it all (JSON for scripts, a bench file
//! for radbench).
//!
//! | instrument | transports |
//! |---|---|
//! | `awg` (M8195A) | raw socket, HiSLIP, VXI-11 |
//! | `scope` (LabMaster, the default) | VICP, VXI-11 (only the one selected as its remote interface listens; the other refuses connections and is listed with `"active": false` and the reason) |
//! | `scope` (another of [`ScopeModel::ALL`], `scope_model`) | the transports of its row |
//! | `tx`, `rx` (Gotmic) | serial, on pseudo-terminals |
//! | `loopback` (test instrument, optional) | raw socket, VXI-11, HiSLIP, VICP, serial |

use crate::bench::Bench;
use crate::catalog::{CatalogError, RfModel};
use crate::control;
use crate::emulator::lecroy::{Lecroy, RemoteInterface};
use crate::emulator::loopback::Loopback;
use crate::emulator::scopes::ScopeEmulator;
pub use crate::emulator::scopes::ScopeModel;
use crate::faults::Faults;
use crate::scene::Scene;
use crate::server::launch::{self, Endpoint, Ports, Running, Transport};
use crate::server::switch::Switchable;
use crate::server::{Handler, ServerError, ServerOptions, DEFAULT_MAX_MESSAGE_SIZE};
use std::net::{Ipv4Addr, SocketAddr};
use std::sync::{Arc, Mutex, MutexGuard};
use std::time::Duration;

/// How to start the lab.
#[derive(Debug, Clone)]
pub struct LabOptions {
    pub scene: Scene,
    /// Consecutive ports from this one instead of OS-assigned ones (five per instrument: raw,
    /// VXI-11 core and abort, HiSLIP, VICP).
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
    /// Which scope the lab serves as `scope`.
    pub scope_model: ScopeModel,
    /// Port of the loopback instrument's VICP endpoint (interop tests through pyvisa need 1861).
    pub loopback_vicp_port: Option<u16>,
    /// The Tx and Rx modules' catalog files instead of the built-in ones (a lab's own description
    /// of its modules' line protocol and register map, `catalog::rf_from_str`).
    pub front_ends: Option<(RfModel, RfModel)>,
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
            front_ends: None,
            scope_model: ScopeModel::default(),
        }
    }
}

/// Ports used per instrument with a port base: raw, VXI-11 core, VXI-11 abort, HiSLIP, VICP.
pub(crate) const PORTS_PER_INSTRUMENT: u16 = 5;

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
    #[error("cannot install the handlers that stop the lab on SIGINT and SIGTERM: {0}")]
    Signals(std::io::Error),
    #[error(
        "--port-base {base} is out of range: the lab uses {needed} consecutive ports from it, \
         so give 1 ..= {highest} (or leave it out for ports chosen by the OS)"
    )]
    PortBase {
        base: u16,
        needed: u16,
        highest: u16,
    },
}

impl LabError {
    /// The process exit code this failure calls for: 2 bad input (an option out of range), 3 the
    /// lab cannot serve (a port taken, no pseudo-terminal), 1 a bug (the built-in catalog).
    pub fn exit_code(&self) -> u8 {
        match self {
            LabError::PortBase { .. } => 2,
            LabError::Server { .. } | LabError::Control(_) | LabError::Signals(_) => 3,
            LabError::Catalog(_) => 1,
        }
    }
}

impl LabOptions {
    /// Instrument slots of [`PORTS_PER_INSTRUMENT`] ports each, up to the last one with network
    /// ports, in serving order: awg, scope, tx, rx (serial: their slots stay unused), loopback.
    fn slots(&self) -> u16 {
        if self.with_loopback {
            5
        } else {
            2
        }
    }

    /// Checks the options before anything is bound: a port base whose ports would pass 65535
    /// (or start at 0) is refused here, as bad input.
    pub fn validate(&self) -> Result<(), LabError> {
        let Some(base) = self.port_base else {
            return Ok(());
        };
        let needed = self.slots() * PORTS_PER_INSTRUMENT;
        let highest = u16::MAX - (needed - 1);
        if base == 0 || base > highest {
            return Err(LabError::PortBase {
                base,
                needed,
                highest,
            });
        }
        Ok(())
    }
}

/// The running lab; dropping it stops every server.
pub struct Lab {
    pub bench: Arc<Bench>,
    /// The scene control channel's address.
    pub control: SocketAddr,
    /// Fault switches shared by every server of the lab.
    pub faults: Arc<Faults>,
    /// Fault switches of the scope's servers only (the lab-wide ones apply to them too).
    pub scope_faults: Arc<Faults>,
    /// The same for the AWG's servers, and the Tx and Rx modules' serial ports.
    pub awg_faults: Arc<Faults>,
    pub tx_faults: Arc<Faults>,
    pub rx_faults: Arc<Faults>,
    /// Every endpoint as it is now, in serving order.
    endpoints: Arc<Mutex<Vec<Endpoint>>>,
    /// The scope served as `scope`.
    pub scope_model: ScopeModel,
    _running: Vec<Running>,
    _follower: AbortOnDrop,
    _control: control::ControlServer,
}

impl Drop for Lab {
    fn drop(&mut self) {
        // A scope handler waiting for a trigger edge on a blocking thread would keep the
        // runtime's shutdown waiting until its `WAIT` times out (10 s).
        self.bench.scope.abandon_waits();
    }
}

struct Served {
    name: &'static str,
    handler: Arc<dyn Handler>,
    transports: &'static [Transport],
    /// The scope's endpoints: open only while the scope's remote interface is this one.
    remote: Option<RemoteInterface>,
}

/// The scope's VICP and VXI-11 endpoints, opened and closed with its remote interface.
struct ScopeSwitch {
    scope: Arc<Lecroy>,
    /// The bench, for its fault switches.
    bench: Arc<Bench>,
    /// Each instrument's link faults (`awg`, `scope`, `tx`, `rx`).
    links: LinkFaults,
    /// (protocol, index in the lab's endpoint list, server).
    servers: tokio::sync::Mutex<Vec<(RemoteInterface, usize, Switchable)>>,
    endpoints: Arc<Mutex<Vec<Endpoint>>>,
}

impl ScopeSwitch {
    /// Why the endpoint for `via` is closed, and how to open it.
    fn reason(&self, via: RemoteInterface) -> String {
        let refusal = self.scope.accepts(via).err().unwrap_or_default();
        let name = match via {
            RemoteInterface::Vicp => "vicp",
            RemoteInterface::Vxi11 => "vxi11",
        };
        format!(
            "{refusal} (on mock_lab: send {{\"cmd\":\"scope_remote\",\"interface\":\"{name}\"}} \
             to the control channel)"
        )
    }

    /// Opens the endpoint of the scope's remote interface and closes the other; returns when
    /// both are in their new state (the first error is returned, each endpoint says its own).
    async fn apply(&self) -> Result<(), ServerError> {
        let mut servers = self.servers.lock().await;
        let enabled = self.scope.remote_interface();
        let mut first_error = None;
        for (via, index, server) in servers.iter_mut() {
            let result = if *via == enabled {
                server.open().await
            } else {
                server.close(self.reason(*via)).await
            };
            if let Err(err) = result {
                tracing::warn!(protocol = ?via, "scope endpoint: {err}");
                first_error.get_or_insert(err);
            }
            if let Some(slot) = lock(&self.endpoints).get_mut(*index) {
                *slot = server.endpoint().clone();
            }
        }
        first_error.map_or(Ok(()), Err)
    }
}

impl control::Panel for ScopeSwitch {
    fn set_scope_remote(
        &self,
        remote: RemoteInterface,
    ) -> control::PanelFuture<'_, Result<serde_json::Value, String>> {
        Box::pin(async move {
            self.scope.set_remote_interface(remote);
            self.apply().await.map_err(|e| e.to_string())?;
            Ok(serde_json::json!({ "scope_remote": remote }))
        })
    }

    fn endpoints(&self) -> serde_json::Value {
        serde_json::json!(*lock(&self.endpoints))
    }

    fn fault(&self, fault: &control::BenchFault) -> Result<serde_json::Value, String> {
        let mode = |text: &Option<String>, which: &str| -> Result<Option<Option<bool>>, String> {
            match text.as_deref() {
                None => Ok(None),
                Some("on") => Ok(Some(Some(true))),
                Some("off") => Ok(Some(Some(false))),
                Some("free") => Ok(Some(None)),
                Some(other) => Err(format!("{which}: {other:?}: allowed: on, off or free")),
            }
        };
        // Everything checked before anything changes.
        let tx = mode(&fault.tx_crc, "tx_crc")?;
        let rx = mode(&fault.rx_crc, "rx_crc")?;
        let links = self.links.check(fault)?;
        if let Some(on) = fault.marker_cable {
            self.bench
                .marker_cable
                .store(on, std::sync::atomic::Ordering::SeqCst);
        }
        if let Some(m) = tx {
            self.bench.tx.set_crc_fixed(m);
        }
        if let Some(m) = rx {
            self.bench.rx.set_crc_fixed(m);
        }
        if let Some(options) = &fault.awg_options {
            let answer = (!options.is_empty()).then(|| options.clone());
            self.bench.awg.set_options(answer);
        }
        if let Some(max) = fault.awg_raster_max {
            self.bench.awg.set_raster_max((max > 0.0).then_some(max));
        }
        if let Some(faults) = links.drop {
            faults.drop_next_reply_midway();
        }
        if let Some((faults, for_)) = links.stall {
            faults.stall_for(for_);
        }
        if let Some((module, faults, for_)) = links.power_cycle {
            match module {
                "tx" => self.bench.tx.power_cycle(),
                _ => self.bench.rx.power_cycle(),
            }
            faults.silence_for(for_);
        }
        Ok(serde_json::json!({
            "marker_cable": self.bench.marker_cable.load(std::sync::atomic::Ordering::SeqCst),
        }))
    }
}

/// Each instrument's link faults, for the control channel's `drop`, `stall` and `power_cycle`.
#[derive(Clone)]
struct LinkFaults {
    awg: Arc<Faults>,
    scope: Arc<Faults>,
    tx: Arc<Faults>,
    rx: Arc<Faults>,
}

/// The link faults a `fault` request asks for, checked.
#[derive(Default)]
struct LinkRequest<'a> {
    drop: Option<&'a Faults>,
    stall: Option<(&'a Faults, Duration)>,
    power_cycle: Option<(&'static str, &'a Faults, Duration)>,
}

/// Longest stall or power cut the control channel accepts, seconds.
const LONGEST_FAULT_S: f64 = 3600.0;

impl LinkFaults {
    fn of(&self, name: &str, field: &str, allowed: &[&str]) -> Result<&Faults, String> {
        let faults = match name {
            "awg" if allowed.contains(&"awg") => &self.awg,
            "scope" if allowed.contains(&"scope") => &self.scope,
            "tx" if allowed.contains(&"tx") => &self.tx,
            "rx" if allowed.contains(&"rx") => &self.rx,
            _ => {
                return Err(format!(
                    "{field}: {name:?}: allowed: {}",
                    allowed.join(", ")
                ))
            }
        };
        Ok(faults)
    }

    /// Checks the request's `drop`, `stall`, `power_cycle` and `for_s` (nothing changes yet).
    fn check(&self, f: &control::BenchFault) -> Result<LinkRequest<'_>, String> {
        let needs_for = f.stall.is_some() || f.power_cycle.is_some();
        let for_ = match (f.for_s, needs_for) {
            (None, true) => return Err("for_s: needed with stall and power_cycle (seconds)".into()),
            (Some(_), false) => return Err("for_s: only with stall or power_cycle".into()),
            (Some(s), true) if !(s.is_finite() && (0.0..=LONGEST_FAULT_S).contains(&s)) => {
                return Err(format!(
                    "for_s: {s}: allowed: 0 to {LONGEST_FAULT_S} seconds"
                ))
            }
            (s, _) => Duration::from_secs_f64(s.unwrap_or(0.0)),
        };
        let mut request = LinkRequest::default();
        if let Some(name) = &f.drop {
            request.drop = Some(self.of(name, "drop", &["awg", "scope", "tx", "rx"])?);
        }
        if let Some(name) = &f.stall {
            request.stall = Some((self.of(name, "stall", &["awg", "scope"])?, for_));
        }
        if let Some(name) = &f.power_cycle {
            let faults = self.of(name, "power_cycle", &["tx", "rx"])?;
            let module = if name == "tx" { "tx" } else { "rx" };
            request.power_cycle = Some((module, faults, for_));
        }
        Ok(request)
    }
}

fn lock<T>(m: &Mutex<T>) -> MutexGuard<'_, T> {
    // Plain data: a panic elsewhere leaves it consistent.
    m.lock().unwrap_or_else(|p| p.into_inner())
}

/// Aborts a background task when dropped.
struct AbortOnDrop(tokio::task::JoinHandle<()>);

impl Drop for AbortOnDrop {
    fn drop(&mut self) {
        self.0.abort();
    }
}

/// What the lab serves: each instrument's handler and the transports it speaks.
fn served(
    bench: &Arc<Bench>,
    with_loopback: bool,
    scope: ScopeModel,
) -> Result<Vec<Served>, LabError> {
    let awg = Served {
        name: "awg",
        handler: bench.awg.clone(),
        transports: &[Transport::Raw, Transport::Hislip, Transport::Vxi11],
        remote: None,
    };
    let mut served = vec![awg];
    match scope.emulator {
        ScopeEmulator::BenchLecroy => served.extend([
            Served {
                name: "scope",
                handler: Arc::new(bench.scope.port(RemoteInterface::Vicp)),
                transports: &[Transport::Vicp],
                remote: Some(RemoteInterface::Vicp),
            },
            Served {
                name: "scope",
                handler: Arc::new(bench.scope.port(RemoteInterface::Vxi11)),
                transports: &[Transport::Vxi11],
                remote: Some(RemoteInterface::Vxi11),
            },
        ]),
        ScopeEmulator::Build(emulator) => served.push(Served {
            name: "scope",
            handler: emulator(bench.inputs())?,
            transports: scope.transports,
            remote: None,
        }),
    }
    served.extend([
        Served {
            name: "tx",
            handler: bench.tx.clone(),
            transports: &[Transport::Serial],
            remote: None,
        },
        Served {
            name: "rx",
            handler: bench.rx.clone(),
            transports: &[Transport::Serial],
            remote: None,
        },
    ]);
    if with_loopback {
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
            remote: None,
        });
    }
    Ok(served)
}

/// The ports of one endpoint: the slot's defaults, the fixed VICP ports asked for, and the
/// VXI-11 portmapper for the first instrument that takes it.
fn ports_of(
    options: &LabOptions,
    s: &Served,
    transport: Transport,
    slot: u16,
    portmapper: &mut Option<u16>,
) -> Result<Ports, LabError> {
    let mut ports = ports_for(options.port_base, slot, transport)?;
    if transport == Transport::Vicp && s.name == "scope" {
        ports.main = options.vicp_port.unwrap_or(ports.main);
    }
    if transport == Transport::Vicp && s.name == "loopback" {
        ports.main = options.loopback_vicp_port.unwrap_or(ports.main);
    }
    if transport == Transport::Vxi11 && s.remote.is_none() {
        ports.portmapper = portmapper.take();
    }
    Ok(ports)
}

/// Starts the lab. Must run inside a tokio runtime; returns once every endpoint listens.
pub async fn start(options: LabOptions) -> Result<Lab, LabError> {
    options.validate()?;
    let bench = Arc::new(match &options.front_ends {
        Some((tx, rx)) => Bench::with_front_ends(options.scene.clone(), tx.clone(), rx.clone())?,
        None => Bench::new(options.scene.clone())?,
    });
    bench.scope.set_remote_interface(options.scope_remote);
    let served = served(&bench, options.with_loopback, options.scope_model)?;
    let endpoints_now = Arc::new(Mutex::new(Vec::new()));
    let faults = Faults::new();
    let links = LinkFaults {
        awg: Faults::layered(faults.clone()),
        scope: Faults::layered(faults.clone()),
        tx: Faults::layered(faults.clone()),
        rx: Faults::layered(faults.clone()),
    };
    let scope_faults = links.scope.clone();
    let scope_switch = Arc::new(ScopeSwitch {
        scope: bench.scope.clone(),
        bench: bench.clone(),
        links: links.clone(),
        servers: tokio::sync::Mutex::new(Vec::new()),
        endpoints: endpoints_now.clone(),
    });
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
            let ports = ports_of(&options, s, transport, slot, &mut portmapper)?;
            let server_options = ServerOptions {
                max_message_size: options.max_message_size,
                faults: match s.name {
                    "awg" => links.awg.clone(),
                    "scope" => links.scope.clone(),
                    "tx" => links.tx.clone(),
                    "rx" => links.rx.clone(),
                    _ => faults.clone(),
                },
            };
            let failed = |source| LabError::Server {
                instrument: s.name.to_string(),
                transport: transport.name(),
                source,
            };
            if let Some(via) = s.remote {
                let closed = (via != options.scope_remote).then(|| scope_switch.reason(via));
                let server = Switchable::start(
                    s.name,
                    s.handler.clone(),
                    transport,
                    ports,
                    server_options,
                    closed,
                )
                .await
                .map_err(failed)?;
                endpoints.push(server.endpoint().clone());
                let index = endpoints.len() - 1;
                scope_switch.servers.lock().await.push((via, index, server));
                continue;
            }
            let (server, endpoint) =
                launch::start(s.name, s.handler.clone(), transport, ports, server_options)
                    .await
                    .map_err(failed)?;
            running.push(server);
            endpoints.push(endpoint);
        }
    }
    *lock(&endpoints_now) = endpoints;
    // Follows the scope's remote interface however it is changed (control channel, tests).
    let mut changes = bench.scope.watch_remote_interface();
    let follower_switch = scope_switch.clone();
    let follower = tokio::spawn(async move {
        while changes.changed().await.is_ok() {
            let _ = follower_switch.apply().await;
        }
    });
    let panel: Arc<dyn control::Panel> = scope_switch.clone();
    let control_server = control::serve(
        bench.scene.clone(),
        Some(panel),
        SocketAddr::from((Ipv4Addr::LOCALHOST, 0)),
    )
    .await
    .map_err(LabError::Control)?;
    Ok(Lab {
        bench,
        control: control_server.local_addr(),
        _control: control_server,
        faults,
        scope_faults,
        awg_faults: links.awg,
        tx_faults: links.tx,
        rx_faults: links.rx,
        endpoints: endpoints_now,
        scope_model: options.scope_model,
        _running: running,
        _follower: AbortOnDrop(follower),
    })
}

fn ports_for(base: Option<u16>, slot: u16, transport: Transport) -> Result<Ports, LabError> {
    let mut ports = Ports::default();
    let Some(base) = base else {
        return Ok(ports);
    };
    let first = u32::from(base) + u32::from(slot) * u32::from(PORTS_PER_INSTRUMENT);
    // `validate` has checked the whole range; this only keeps the arithmetic honest.
    let port = |offset: u32| {
        let needed = PORTS_PER_INSTRUMENT * (slot + 1);
        u16::try_from(first + offset).map_err(|_| LabError::PortBase {
            base,
            needed,
            highest: u16::MAX - (needed - 1),
        })
    };
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
    /// Every endpoint as it is now (`active` follows the scope's remote interface).
    pub fn endpoints(&self) -> Vec<Endpoint> {
        lock(&self.endpoints).clone()
    }

    /// The endpoint of `instrument` on `transport`, if served.
    pub fn endpoint(&self, instrument: &str, transport: Transport) -> Option<Endpoint> {
        lock(&self.endpoints)
            .iter()
            .find(|e| e.instrument == instrument && e.transport == transport)
            .cloned()
    }

    /// One JSON object naming every endpoint and the control channel.
    pub(crate) fn describe_json(&self) -> serde_json::Value {
        serde_json::json!({
            "endpoints": self.endpoints(),
            "control": self.control.to_string(),
        })
    }

    /// The scope's resource on `preferred`, or on the first transport it serves open when it
    /// does not serve that one (a UXR has no VICP): a bench file never names no scope.
    fn scope_resource(&self, preferred: Transport) -> String {
        let open = |e: &Endpoint| e.instrument == "scope" && e.reason.is_none();
        let endpoints = self.endpoints();
        endpoints
            .iter()
            .find(|e| open(e) && e.transport == preferred)
            .or_else(|| endpoints.iter().find(|e| open(e)))
            .map(|e| e.resource.clone())
            .unwrap_or_default()
    }

    /// A radbench bench file for this lab, using the given transports for the AWG and the scope
    /// (the scope's first open one when it does not serve the one given).
    pub fn bench_toml(&self, awg: Transport, scope: Transport) -> String {
        let resource = |name: &str, t: Transport| {
            self.endpoint(name, t)
                .map(|e| e.resource.clone())
                .unwrap_or_default()
        };
        // Front ends served from a lab's own instrument files are named by their files' keys;
        // radbench finds those files only through the bench file's `catalog`.
        let key = |model: &crate::catalog::RfModel, built_in: &'static str| {
            if model.key.is_empty() {
                built_in.to_string()
            } else {
                model.key.clone()
            }
        };
        let (tx, rx) = (
            key(self.bench.tx.model(), "gotmic-eband-tx"),
            key(self.bench.rx.model(), "gotmic-eband-rx"),
        );
        let own = if [tx.as_str(), rx.as_str()] == ["gotmic-eband-tx", "gotmic-eband-rx"] {
            ""
        } else {
            "# The Tx and Rx are served from your own instrument files: add catalog = \"FOLDER\"\n\
             # (the folder holding them) at the top of this file.\n"
        };
        format!(
            "# radbench bench file for the simulated lab (mock_lab); written by `mock-lab serve`.\n\
             # Every resource below is on 127.0.0.1 and lives as long as that process.\n{own}\n\
             [awg]\nmodel = \"keysight-m8195a\"\nresource = \"{}\"\n\n\
             [scope]\nmodel = \"{}\"\nresource = \"{}\"\n\n\
             [tx]\nmodel = \"{tx}\"\nresource = \"{}\"\n\n\
             [rx]\nmodel = \"{rx}\"\nresource = \"{}\"\n\n\
             [simulation]\ncontrol = \"{}\"\n",
            resource("awg", awg),
            self.scope_model.catalog_key(),
            self.scope_resource(scope),
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

/// Starts the lab, announces it on standard output, and serves until SIGINT (Ctrl-C), SIGTERM
/// or SIGHUP, or, with `until_stdin_closes`, until standard input reaches end of file (so a
/// parent process that dies takes the lab along). Every server is stopped before it returns.
pub async fn serve_until_stopped(
    options: LabOptions,
    announce: Announce,
    until_stdin_closes: bool,
) -> Result<(), LabError> {
    use std::io::Write;
    // Handlers first: from here on a signal stops the lab cleanly instead of killing it.
    let stop = stop_requested(until_stdin_closes).map_err(LabError::Signals)?;
    let lab = start(options).await?;
    let text = match announce {
        Announce::Json => format!("{}\n", lab.describe_json()),
        Announce::Human => describe_human(&lab),
    };
    // A closed stdout (a script that read the first line and left) must not stop the lab.
    let mut out = std::io::stdout().lock();
    let _ = out.write_all(text.as_bytes()).and_then(|()| out.flush());
    drop(out);
    let why = stop.await;
    tracing::info!("stopping: {why}");
    drop(lab);
    Ok(())
}

/// The endpoint table (comments) followed by a ready-to-use bench file.
fn describe_human(lab: &Lab) -> String {
    // Everything printed is a valid bench file: the table is made of comments.
    let mut t = format!(
        "# {:<9} {:<7} {:<24} resource\n",
        "instrument", "proto", "address"
    );
    for e in &lab.endpoints() {
        t += &format!(
            "# {:<9} {:<7} {:<24} {}\n",
            e.instrument,
            e.transport.name(),
            e.address,
            e.resource
        );
        if let Some(reason) = &e.reason {
            t += &format!("#   closed: {reason}\n");
        }
    }
    t += &format!("# {:<9} {:<7} {}\n#\n", "control", "json", lab.control);
    t += "# serving on 127.0.0.1 until Ctrl-C; this output is a ready-to-use bench file\n\n";
    t += &lab.bench_toml(Transport::Hislip, Transport::Vicp);
    t
}

/// A future that resolves with what asked the lab to stop. Signal handlers are installed now,
/// before the future is first polled, so no signal is lost in between.
fn stop_requested(
    until_stdin_closes: bool,
) -> std::io::Result<impl std::future::Future<Output = &'static str>> {
    use tokio::signal::unix::{signal, SignalKind};
    let mut interrupt = signal(SignalKind::interrupt())?;
    let mut terminate = signal(SignalKind::terminate())?;
    let mut hangup = signal(SignalKind::hangup())?;
    let stdin_closed = if until_stdin_closes {
        stdin_closed()
    } else {
        None
    };
    Ok(async move {
        let stdin = async {
            match stdin_closed {
                // A sender dropped without sending (the reader thread died) counts as closed.
                Some(closed) => {
                    let _ = closed.await;
                }
                None => std::future::pending::<()>().await,
            }
        };
        tokio::select! {
            _ = interrupt.recv() => "SIGINT",
            _ = terminate.recv() => "SIGTERM",
            _ = hangup.recv() => "SIGHUP",
            () = stdin => "standard input closed",
        }
    })
}

/// Resolves when standard input reaches end of file (or fails). The reading thread is detached:
/// it must never hold up the process's exit (a runtime waits for its blocking tasks). `None`
/// when no thread could be started (the lab then stops on signals only, and says so).
fn stdin_closed() -> Option<tokio::sync::oneshot::Receiver<()>> {
    let (tx, rx) = tokio::sync::oneshot::channel();
    let spawned = std::thread::Builder::new()
        .name("mock-lab-stdin".into())
        .spawn(move || {
            use std::io::Read;
            let mut sink = [0u8; 4096];
            let mut stdin = std::io::stdin();
            while matches!(stdin.read(&mut sink), Ok(n) if n > 0) {}
            let _ = tx.send(());
        });
    match spawned {
        Ok(_) => Some(rx),
        Err(err) => {
            tracing::warn!("cannot watch standard input ({err}); stop the lab with Ctrl-C");
            None
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::time::Duration;
    use tokio::io::{AsyncBufReadExt, AsyncWriteExt, BufReader};

    #[test]
    fn port_bases_whose_ports_pass_65535_are_bad_input() {
        let with = |port_base, with_loopback| LabOptions {
            port_base: Some(port_base),
            with_loopback,
            ..LabOptions::default()
        };
        for (base, loopback) in [(65535, false), (0, false), (65527, false), (65512, true)] {
            let err = with(base, loopback).validate().unwrap_err();
            assert_eq!(err.exit_code(), 2, "{base}: {err}");
        }
        assert!(with(65526, false).validate().is_ok());
        assert!(with(65511, true).validate().is_ok());
        let err = with(65535, true).validate().unwrap_err().to_string();
        assert!(
            err.contains("25 consecutive ports") && err.contains("1 ..= 65511"),
            "{err}"
        );
    }

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

    async fn connects(addr: &str) -> bool {
        match tokio::time::timeout(Duration::from_secs(5), tokio::net::TcpStream::connect(addr))
            .await
            .expect("accepted or refused at once, never left hanging")
        {
            Ok(_) => true,
            Err(e) if e.kind() == std::io::ErrorKind::ConnectionRefused => false,
            Err(e) => panic!("{addr}: {e}"),
        }
    }

    async fn control(lab: &Lab, request: &str) -> serde_json::Value {
        let stream = tokio::net::TcpStream::connect(lab.control).await.unwrap();
        let (rd, mut wr) = stream.into_split();
        wr.write_all(format!("{request}\n").as_bytes())
            .await
            .unwrap();
        let mut line = String::new();
        tokio::time::timeout(
            Duration::from_secs(10),
            BufReader::new(rd).read_line(&mut line),
        )
        .await
        .unwrap()
        .unwrap();
        serde_json::from_str(&line).unwrap()
    }

    #[tokio::test]
    async fn only_the_scopes_remote_interface_listens_and_a_switch_moves_it() {
        let lab = tokio::time::timeout(Duration::from_secs(10), start(LabOptions::default()))
            .await
            .unwrap()
            .unwrap();
        let vicp = lab.endpoint("scope", Transport::Vicp).unwrap();
        let vxi11 = lab.endpoint("scope", Transport::Vxi11).unwrap();
        assert!(vicp.active && vicp.reason.is_none());
        assert!(!vxi11.active);
        assert!(
            vxi11.reason.as_deref().unwrap().contains("TCPIP (VICP)"),
            "{vxi11:?}"
        );
        let json = lab.describe_json();
        let listed = json["endpoints"]
            .as_array()
            .unwrap()
            .iter()
            .find(|e| e["instrument"] == "scope" && e["transport"] == "vxi11")
            .unwrap();
        assert_eq!(listed["active"], false);
        assert!(listed["reason"]
            .as_str()
            .unwrap()
            .contains("remote interface"));
        assert!(connects(&vicp.address).await);
        assert!(!connects(&vxi11.address).await, "closed port refuses");
        assert!(!connects(vxi11.abort_address.as_deref().unwrap()).await);

        let v = control(&lab, r#"{"cmd":"scope_remote","interface":"vxi11"}"#).await;
        assert_eq!(v["ok"], true, "{v}");
        let now = lab.endpoint("scope", Transport::Vxi11).unwrap();
        assert_eq!(now.address, vxi11.address, "same port after the switch");
        assert!(now.active);
        assert!(connects(&vxi11.address).await);
        assert!(!connects(&vicp.address).await);
        assert!(!lab.endpoint("scope", Transport::Vicp).unwrap().active);

        // The control channel switches it back, and lists the endpoints as they are.
        let v = control(&lab, r#"{"cmd":"scope_remote","interface":"vicp"}"#).await;
        assert_eq!(v["ok"], true, "{v}");
        assert!(connects(&vicp.address).await);
        assert!(!connects(&vxi11.address).await);
        let v = control(&lab, r#"{"cmd":"endpoints"}"#).await;
        let scope: Vec<(String, bool)> = v["endpoints"]
            .as_array()
            .unwrap()
            .iter()
            .filter(|e| e["instrument"] == "scope")
            .map(|e| {
                (
                    e["transport"].as_str().unwrap().to_string(),
                    e["active"] == true,
                )
            })
            .collect();
        assert_eq!(scope, [("vicp".into(), true), ("vxi11".into(), false)]);
        let v = control(&lab, r#"{"cmd":"scope_remote","interface":"gpib"}"#).await;
        assert_eq!(v["ok"], false, "{v}");
    }

    #[tokio::test]
    async fn bench_faults_switch_from_the_control_channel_and_bad_ones_change_nothing() {
        use std::sync::atomic::Ordering;
        let lab = tokio::time::timeout(Duration::from_secs(10), start(LabOptions::default()))
            .await
            .unwrap()
            .unwrap();
        let v = control(
            &lab,
            r#"{"cmd":"fault","marker_cable":false,"tx_crc":"off"}"#,
        )
        .await;
        assert_eq!(v["ok"], true, "{v}");
        assert!(!lab.bench.marker_cable.load(Ordering::SeqCst));
        // The Tx now refuses to switch its CRC mode.
        assert!(lab.bench.tx.line("CRC ON").starts_with("ERR"));
        let v = control(
            &lab,
            r#"{"cmd":"fault","marker_cable":true,"rx_crc":"sideways"}"#,
        )
        .await;
        assert_eq!(v["ok"], false, "{v}");
        assert!(
            !lab.bench.marker_cable.load(Ordering::SeqCst),
            "nothing changed"
        );
        let v = control(
            &lab,
            r#"{"cmd":"fault","marker_cable":true,"tx_crc":"free"}"#,
        )
        .await;
        assert_eq!(v["ok"], true, "{v}");
        assert!(lab.bench.marker_cable.load(Ordering::SeqCst));
        assert_eq!(lab.bench.tx.line("CRC OFF"), "OK");
    }

    #[tokio::test]
    async fn link_faults_drop_stall_and_power_cycle_from_the_control_channel() {
        use crate::faults::ReplyFate;
        use tokio::io::AsyncReadExt;
        let lab = tokio::time::timeout(Duration::from_secs(10), start(LabOptions::default()))
            .await
            .unwrap()
            .unwrap();
        let raw = lab.endpoint("awg", Transport::Raw).unwrap().address.clone();
        // One *IDN? on a new connection: what arrived before the server closed or 5 s passed.
        let idn = || async {
            let mut stream = tokio::net::TcpStream::connect(&raw).await.unwrap();
            stream.write_all(b"*IDN?\n").await.unwrap();
            let mut got = Vec::new();
            let mut buf = [0u8; 256];
            while !got.ends_with(b"\n") {
                match tokio::time::timeout(Duration::from_secs(5), stream.read(&mut buf)).await {
                    Ok(Ok(0)) | Ok(Err(_)) | Err(_) => break,
                    Ok(Ok(n)) => got.extend_from_slice(&buf[..n]),
                }
            }
            String::from_utf8_lossy(&got).into_owned()
        };
        let whole = idn().await;
        assert!(whole.starts_with("MOCK_LAB,M8195A-EMU") && whole.ends_with('\n'));
        // drop: the next exchange is cut halfway and closed; the one after is whole.
        let v = control(&lab, r#"{"cmd":"fault","drop":"awg"}"#).await;
        assert_eq!(v["ok"], true, "{v}");
        let cut = idn().await;
        assert!(!cut.ends_with('\n') && whole.starts_with(&cut), "{cut:?}");
        assert_eq!(idn().await, whole);
        // stall: the reply is held for the time asked, then comes whole.
        let v = control(&lab, r#"{"cmd":"fault","stall":"awg","for_s":0.4}"#).await;
        assert_eq!(v["ok"], true, "{v}");
        let t = std::time::Instant::now();
        assert_eq!(idn().await, whole);
        assert!(
            t.elapsed() >= Duration::from_millis(350),
            "{:?}",
            t.elapsed()
        );
        // power_cycle: the module answers nothing for for_s, then is back at power-on (CRC off).
        assert!(lab.bench.tx.line("CRC ON").starts_with("OK"));
        assert!(lab.bench.tx.line("CRC OFF").starts_with("ERR"), "CRC is on");
        let v = control(&lab, r#"{"cmd":"fault","power_cycle":"tx","for_s":30}"#).await;
        assert_eq!(v["ok"], true, "{v}");
        assert_eq!(lab.tx_faults.plan_reply().fate, ReplyFate::Swallow);
        assert_eq!(lab.rx_faults.plan_reply().fate, ReplyFate::Deliver);
        assert_eq!(
            lab.bench.tx.line("CRC OFF"),
            "OK",
            "back at power-on: CRC off"
        );
        lab.tx_faults.clear();
        // Bad requests change nothing, and say what is allowed.
        for (request, says) in [
            (
                r#"{"cmd":"fault","stall":"tx","for_s":1}"#,
                "stall: \"tx\": allowed: awg, scope",
            ),
            (r#"{"cmd":"fault","stall":"awg"}"#, "for_s: needed"),
            (
                r#"{"cmd":"fault","drop":"awg","for_s":1}"#,
                "for_s: only with",
            ),
            (
                r#"{"cmd":"fault","power_cycle":"awg","for_s":1}"#,
                "allowed: tx, rx",
            ),
            (
                r#"{"cmd":"fault","power_cycle":"rx","for_s":-1}"#,
                "for_s: -1",
            ),
            (
                r#"{"cmd":"fault","drop":"awg","stall":"scope","for_s":1e9}"#,
                "0 to 3600",
            ),
        ] {
            let v = control(&lab, request).await;
            assert_eq!(v["ok"], false, "{request}: {v}");
            assert!(
                v["error"].as_str().unwrap().contains(says),
                "{request}: {v}"
            );
        }
        assert_eq!(idn().await, whole, "no drop was switched on");
        assert_eq!(
            lab.scope_faults.plan_reply(),
            crate::faults::ReplyPlan::CLEAN
        );
    }
}
