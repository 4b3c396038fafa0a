//! The bench doctor: checks a bench without radiating and says what to fix.
//!
//! Every instrument of the bench file is opened on its resource (reachability, then its
//! identity against the catalog); a scope that does not answer on its protocol is asked on the
//! other one (the VICP / VXI-11 remote-interface trap); a Gotmic module that does not answer in
//! the catalog's CRC mode is asked in the other mode; the modules' status, interlock, LO lock and
//! temperature are read; the AWG plays a segment of zero codes with only its marker output on
//! (I and Q outputs off, the transmitter off) and the scope must see the marker's edge on its
//! external trigger; the two timebases' references are read; the bench file's calibrations are
//! checked (present, age, the instruments they were measured with). Nothing that radiates is sent:
//! no front end is enabled and no I/Q output is switched on, and the bench ends in its safe state
//! whatever happens (the I/O journal of `--trace-io` shows every exchange).

use super::bench::Bench;
use super::error::MeasureError;
use super::interrupt::Interrupt;
use super::response::Calibration as ResponseCalibration;
use super::station::capture_rate;
use crate::address::Resource;
use crate::catalog::{Catalog, InstrumentModel};
use crate::driver::open;
use crate::driver::safe_state::{self, Shared};
use crate::driver::{
    Awg, AwgSettings, Digitizer, DigitizerSettings, DriverError, IqWaveform, Journal, Outcome,
    RfFrontEnd, SafeState,
};
use serde::Serialize;
use std::time::Duration;

/// Longest wait for one instrument to be reached and identified.
const OPEN_TIMEOUT: Duration = Duration::from_secs(5);
/// The most all the checks may take together, whatever the instruments do (a stall after every
/// answer, replies that never end): each wait is cut to what is left of it, and a check that
/// finds nothing left is skipped. The safe state after the marker check is not cut (at most
/// `SAFE_STEP_TIMEOUT` a step). docs/doctor.md.
pub(crate) const CHECKS_TOTAL: Duration = Duration::from_secs(40);
/// Longest wait for the marker's edge at the scope, seconds.
const MARKER_WAIT_S: f64 = 1.0;
/// Longest the whole marker check may take (configure, download, acquire), seconds.
const MARKER_DEADLINE: Duration = Duration::from_secs(20);
/// Bound on each step of the safe state.
const SAFE_STEP_TIMEOUT: Duration = Duration::from_secs(5);
/// A calibration older than this is flagged, days.
const CALIBRATION_MAX_AGE_DAYS: f64 = 30.0;
/// A module within this of its over-temperature limit is flagged, degrees C.
const TEMPERATURE_MARGIN_C: f64 = 5.0;

/// How one check came out.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Status {
    Pass,
    /// Holds, but worth a look (not a failure: the exit code stays 0).
    Warn,
    Fail,
    /// Not checked, because something it needs failed first.
    Skip,
}

impl Status {
    pub fn mark(self) -> &'static str {
        match self {
            Status::Pass => "ok",
            Status::Warn => "WARN",
            Status::Fail => "FAIL",
            Status::Skip => "skip",
        }
    }
}

/// One line of the checklist.
#[derive(Debug, Clone, Serialize)]
pub struct Check {
    /// A stable name, e.g. `scope.remote_interface`.
    pub id: String,
    pub status: Status,
    /// What was found.
    pub detail: String,
    /// What to do about it (failures and warnings).
    pub fix: Option<String>,
}

/// The whole checklist.
#[derive(Debug, Clone, Serialize)]
pub struct Report {
    pub bench: String,
    pub checks: Vec<Check>,
    /// True when no check failed.
    pub ok: bool,
}

#[derive(Default)]
struct List(Vec<Check>);

impl List {
    fn push(&mut self, id: impl Into<String>, status: Status, detail: impl Into<String>) {
        self.0.push(Check {
            id: id.into(),
            status,
            detail: detail.into(),
            fix: None,
        });
    }

    fn pass(&mut self, id: impl Into<String>, detail: impl Into<String>) {
        self.push(id, Status::Pass, detail);
    }

    fn skip(&mut self, id: impl Into<String>, detail: impl Into<String>) {
        self.push(id, Status::Skip, detail);
    }

    fn bad(
        &mut self,
        id: impl Into<String>,
        status: Status,
        detail: impl Into<String>,
        fix: impl Into<String>,
    ) {
        self.0.push(Check {
            id: id.into(),
            status,
            detail: detail.into(),
            fix: Some(fix.into()),
        });
    }

    fn fail(&mut self, id: impl Into<String>, detail: impl Into<String>, fix: impl Into<String>) {
        self.bad(id, Status::Fail, detail, fix);
    }

    fn warn(&mut self, id: impl Into<String>, detail: impl Into<String>, fix: impl Into<String>) {
        self.bad(id, Status::Warn, detail, fix);
    }
}

/// When the doctor's checks must be done ([`CHECKS_TOTAL`] from the start).
#[derive(Debug, Clone, Copy)]
struct Deadline(tokio::time::Instant);

impl Deadline {
    fn start() -> Deadline {
        Deadline(tokio::time::Instant::now() + CHECKS_TOTAL)
    }

    /// `wait`, or what is left before the deadline when that is less.
    fn bound(self, wait: Duration) -> Duration {
        wait.min(
            self.0
                .saturating_duration_since(tokio::time::Instant::now()),
        )
    }
}

/// Whether a TCP listener answers at the resource's address: `None` for serial resources, else
/// `Ok(address)` or `Err(what happened)`.
async fn tcp_probe(resource: &Resource, deadline: Deadline) -> Option<Result<String, String>> {
    use crate::address::{HISLIP_DEFAULT_PORT, PORTMAPPER_PORT, VICP_DEFAULT_PORT};
    let (host, port) = match resource {
        Resource::Socket { host, port, .. } => (host, *port),
        Resource::Vxi11 { host, port, .. } => (host, port.unwrap_or(PORTMAPPER_PORT)),
        Resource::Hislip { host, port, .. } => (host, port.unwrap_or(HISLIP_DEFAULT_PORT)),
        Resource::Vicp { host, port, .. } => (host, port.unwrap_or(VICP_DEFAULT_PORT)),
        Resource::Serial { .. } => return None,
    };
    let host = host.trim_start_matches('[').trim_end_matches(']');
    let address = if host.contains(':') {
        format!("[{host}]:{port}")
    } else {
        format!("{host}:{port}")
    };
    let wait = deadline.bound(OPEN_TIMEOUT);
    let result = match tokio::time::timeout(wait, tokio::net::TcpStream::connect(&address)).await {
        Ok(Ok(_)) => Ok(address),
        Ok(Err(e)) => Err(format!("{address}: {e}")),
        Err(_) => Err(format!(
            "{address}: no answer to the connection within {} s",
            seconds(wait)
        )),
    };
    Some(result)
}

/// An open with a bound: `Err` text when it fails or takes too long.
async fn bounded<T>(
    deadline: Deadline,
    work: impl std::future::Future<Output = Result<T, DriverError>>,
) -> Result<T, String> {
    let wait = deadline.bound(OPEN_TIMEOUT);
    match tokio::time::timeout(wait, work).await {
        Ok(Ok(v)) => Ok(v),
        Ok(Err(e)) => Err(e.to_string()),
        Err(_) => Err(format!(
            "no identity within {} s (the link opened but the instrument did not answer)",
            seconds(wait)
        )),
    }
}

/// A wait in seconds as the checklist says it (`5`, `2.5`).
fn seconds(wait: Duration) -> String {
    format!("{}", (wait.as_secs_f64() * 10.0).round() / 10.0)
}

fn wrong_instrument(err: &str) -> bool {
    err.contains("`*IDN?`") && err.contains("which is not") || err.contains("ID register")
}

/// Reachability and identity of a network instrument from the probe and the driver's open.
fn reach_and_identity(
    list: &mut List,
    name: &str,
    resource: &str,
    probe: Option<Result<String, String>>,
    opened: &Result<String, String>,
    model: &InstrumentModel,
) {
    let reach = format!("{name}.reachable");
    let ident = format!("{name}.identity");
    match (&probe, opened) {
        (Some(Err(e)), _) => {
            list.fail(
                reach,
                format!("{resource}: nothing answers the connection ({e})"),
                "check that the instrument is on and on the network, and the host and port of \
                 its resource string in the bench file",
            );
            list.skip(ident, "not reachable");
        }
        (_, Ok(idn)) => {
            list.pass(reach, format!("{resource} answers"));
            list.pass(
                ident,
                format!(
                    "`{idn}` matches the catalog's {} ({})",
                    model.instrument.model, model.instrument.key
                ),
            );
        }
        (_, Err(e)) if wrong_instrument(e) => {
            list.pass(reach, format!("{resource} answers"));
            list.fail(
                ident,
                e.clone(),
                format!(
                    "the resource reaches another instrument: point it at the {} (or change \
                     `model` to the instrument that is there)",
                    model.instrument.model
                ),
            );
        }
        (_, Err(e)) => {
            list.fail(
                reach,
                format!("{resource}: {e}"),
                "check the resource string, the cable or network, and that nothing else holds \
                 the instrument's link",
            );
            list.skip(ident, "not reached");
        }
    }
}

/// Opens a front end in the catalog's framing; when that fails, asks it in the other framing
/// (a module that answers there is on the wrong CRC mode, not dead).
async fn open_front(
    name: &str,
    res: &Resource,
    model: &InstrumentModel,
    journal: Option<Journal>,
    deadline: Deadline,
) -> (
    Result<Box<dyn RfFrontEnd>, String>,
    Option<Box<dyn RfFrontEnd>>,
) {
    match bounded(
        deadline,
        open::open_rf(res.clone(), model, journal.clone(), name),
    )
    .await
    {
        Ok(g) => (Ok(g), None),
        Err(e) => {
            let answered = bounded(
                deadline,
                open::open_rf_other_mode(res.clone(), model, journal, name),
            )
            .await
            .ok();
            (Err(e), answered)
        }
    }
}

/// The scope's other remote interface at the same host: the resource to try, from the lab's
/// endpoint list on a simulated bench, else the protocol's standard port.
async fn other_scope_resource(
    bench: &Bench,
    resource: &Resource,
    deadline: Deadline,
) -> Option<Resource> {
    let want = match resource {
        Resource::Vicp { .. } => "vxi11",
        Resource::Vxi11 { .. } => "vicp",
        _ => return None,
    };
    let request = serde_json::json!({"cmd": "endpoints"});
    let asked = bench.control(&request);
    if let Ok(Some(Ok(reply))) = tokio::time::timeout(deadline.bound(OPEN_TIMEOUT), asked).await {
        let found = reply["endpoints"].as_array().and_then(|list| {
            list.iter()
                .find(|e| e["instrument"] == "scope" && e["transport"] == want)
                .and_then(|e| e["resource"].as_str())
                .and_then(|r| r.parse().ok())
        });
        if found.is_some() {
            return found;
        }
    }
    let host = resource.host()?;
    let text = if want == "vicp" {
        format!("VICP::{host}::INSTR")
    } else {
        format!("TCPIP0::{host}::inst0::INSTR")
    };
    text.parse().ok()
}

fn interface_name(protocol: &str) -> &'static str {
    match protocol {
        "vicp" => "TCPIP (VICP)",
        "hislip" => "HiSLIP",
        "socket" => "a raw socket",
        _ => "LXI (VXI-11)",
    }
}

/// Runs every check. `journal` records every exchange (`--trace-io`).
pub async fn run(
    bench: &Bench,
    journal: Option<Journal>,
    interrupt: &Interrupt,
) -> Result<Report, MeasureError> {
    let file = &bench.file;
    let catalog: Catalog = file.catalog()?;
    let mut list = List::default();

    let awg_model = catalog.get(&file.awg.model)?.clone();
    let scope_model = catalog.get(&file.scope.model)?.clone();
    let parse = |text: &str, section: &'static str| -> Result<Resource, MeasureError> {
        text.parse().map_err(|source| MeasureError::Resource {
            section,
            text: text.to_string(),
            source,
        })
    };
    let awg_res = parse(&file.awg.resource, "awg")?;
    let scope_res = parse(&file.scope.resource, "scope")?;
    let fronts: Vec<(&'static str, Resource, InstrumentModel)> =
        [("tx", &file.tx, "tx"), ("rx", &file.rx, "rx")]
            .into_iter()
            .filter_map(|(name, entry, section)| entry.as_ref().map(|e| (name, e, section)))
            .map(|(name, e, section)| {
                Ok((
                    name,
                    parse(&e.resource, section)?,
                    catalog.get(&e.model)?.clone(),
                ))
            })
            .collect::<Result<_, MeasureError>>()?;

    // The AWG and the scope: the listener first, then the driver's open (identity checked).
    let deadline = Deadline::start();
    let (awg_probe, scope_probe) = tokio::join!(
        tcp_probe(&awg_res, deadline),
        tcp_probe(&scope_res, deadline)
    );
    let awg_open = async {
        if matches!(awg_probe, Some(Err(_))) {
            return Err("not reachable".to_string());
        }
        bounded(
            deadline,
            open::open_awg(awg_res.clone(), &awg_model, journal.clone(), "awg"),
        )
        .await
    };
    let scope_open = async {
        if matches!(scope_probe, Some(Err(_))) {
            return Err("not reachable".to_string());
        }
        bounded(
            deadline,
            open::open_digitizer(scope_res.clone(), &scope_model, journal.clone(), "scope"),
        )
        .await
    };
    let front_opens = async {
        let mut out = Vec::new();
        for (name, res, model) in &fronts {
            out.push(open_front(name, res, model, journal.clone(), deadline).await);
        }
        out
    };
    // Ctrl-C while the instruments are being opened ends the doctor at once: nothing is on yet.
    let (awg, scope, fronts_opened) = tokio::select! {
        opened = async { tokio::join!(awg_open, scope_open, front_opens) } => opened,
        signal = interrupt.wait() => return Err(stopped(signal)),
    };

    // AWG.
    let awg_idn: Result<String, String> = awg
        .as_ref()
        .map(|a| a.identity().to_string())
        .map_err(Clone::clone);
    reach_and_identity(
        &mut list,
        "awg",
        &file.awg.resource,
        awg_probe,
        &awg_idn,
        &awg_model,
    );

    // Scope, and its remote interface.
    let scope_idn: Result<String, String> = scope
        .as_ref()
        .map(|s| s.identity().to_string())
        .map_err(Clone::clone);
    let protocol = scope_res.protocol();
    let scope_unanswered = matches!(scope_probe, Some(Err(_)))
        || matches!(&scope, Err(e) if e.contains("remote interface"));
    if scope_unanswered {
        let other = other_scope_resource(bench, &scope_res, deadline).await;
        let other_answer = match &other {
            Some(r) => bounded(
                deadline,
                open::open_digitizer(r.clone(), &scope_model, None, "scope"),
            )
            .await
            .map(|s| s.identity().to_string()),
            None => Err("no other interface to try".into()),
        };
        let this = interface_name(protocol);
        match (other, other_answer) {
            (Some(r), Ok(idn)) => {
                let that = interface_name(r.protocol());
                list.pass(
                    "scope.reachable",
                    format!(
                        "the scope answers at {r} ({idn}), not at {}",
                        file.scope.resource
                    ),
                );
                list.skip("scope.identity", "checked on the other interface only");
                list.fail(
                    "scope.remote_interface",
                    format!(
                        "the scope does not answer over {this} as the bench file says, but does \
                         over {that}: its remote interface is set to {that}"
                    ),
                    format!(
                        "on the scope set Utilities > Utilities Setup > Remote to {this}, or write \
                         resource = \"{r}\" in the bench file's [scope]"
                    ),
                );
            }
            _ => {
                reach_and_identity(
                    &mut list,
                    "scope",
                    &file.scope.resource,
                    scope_probe,
                    &scope_idn,
                    &scope_model,
                );
                list.fail(
                    "scope.remote_interface",
                    format!("the scope answers neither over {this} nor over the other interface"),
                    "check that the scope is on, its host, and Utilities > Utilities Setup > \
                     Remote",
                );
            }
        }
    } else {
        reach_and_identity(
            &mut list,
            "scope",
            &file.scope.resource,
            scope_probe,
            &scope_idn,
            &scope_model,
        );
        if scope.is_ok() {
            list.pass(
                "scope.remote_interface",
                format!(
                    "the scope answers over {}, as the bench file says",
                    interface_name(protocol)
                ),
            );
        } else {
            list.skip("scope.remote_interface", "the scope was not identified");
        }
    }

    // Front ends: reachability, CRC mode, identity, status.
    let mut modules: Vec<(&'static str, Box<dyn RfFrontEnd>)> = Vec::new();
    let mut tx_on = false;
    for ((name, _, model), (opened, other)) in fronts.iter().zip(fronts_opened) {
        let entry = if *name == "tx" { &file.tx } else { &file.rx };
        let resource = entry.as_ref().map_or("", |e| e.resource.as_str());
        let catalog_mode = open::rf_line_mode(model).unwrap_or("its line protocol");
        let crc = format!("{name}.crc_mode");
        match (opened, other) {
            (Ok(g), _) => {
                list.pass(format!("{name}.reachable"), format!("{resource} answers"));
                list.pass(
                    crc,
                    format!("the module speaks {catalog_mode}, as the catalog says"),
                );
                list.pass(
                    format!("{name}.identity"),
                    format!(
                        "`{}` matches the catalog's {}",
                        g.identity(),
                        model.instrument.model
                    ),
                );
                modules.push((name, g));
            }
            (Err(e), Some(g)) => {
                list.pass(format!("{name}.reachable"), format!("{resource} answers"));
                list.fail(
                    crc,
                    format!(
                        "the module does not answer in {catalog_mode} ({e}) but answers in the \
                         other mode: its CRC mode is not the catalog's"
                    ),
                    format!(
                        "set the module's line protocol to {catalog_mode} (its configuration \
                         fixes the CRC mode), or correct the [protocol] section of the {} \
                         instrument file",
                        model.instrument.key
                    ),
                );
                list.pass(
                    format!("{name}.identity"),
                    format!(
                        "`{}` matches the catalog's {}",
                        g.identity(),
                        model.instrument.model
                    ),
                );
                modules.push((name, g));
            }
            (Err(e), None) => {
                let (status, fix) = if e.contains("cannot open") || e.contains("No such file") {
                    (
                        "reachable",
                        "check the serial device path of the resource string and that the \
                         adapter is plugged in (and readable by this user)",
                    )
                } else if wrong_instrument(&e) {
                    (
                        "identity",
                        "the serial port reaches another module: swap the Tx and Rx resource \
                         strings or fix the device path",
                    )
                } else {
                    (
                        "reachable",
                        "check the cable, the module's power and the line settings (the \
                         catalog's [serial] section)",
                    )
                };
                list.fail(format!("{name}.{status}"), format!("{resource}: {e}"), fix);
                list.skip(crc, "the module did not answer");
            }
        }
    }
    for m in &file.manual {
        list.warn(
            format!("{}.driver", m.section),
            format!(
                "manual (driver = \"manual\"): radbench does not talk to the {} module and \
                 cannot switch it off; runs ask the operator to confirm its settings",
                m.name()
            ),
            super::manual::manual_doctor_fix(m),
        );
    }
    for (name, g) in &mut modules {
        let limits = fronts
            .iter()
            .find(|(n, _, _)| n == name)
            .and_then(|(_, _, model)| model.rf.clone());
        match tokio::time::timeout(deadline.bound(OPEN_TIMEOUT), g.status()).await {
            Ok(Ok(s)) => {
                if s.powered && s.faults.is_empty() {
                    list.pass(format!("{name}.status"), "powered, no latched fault");
                } else if !s.powered {
                    list.fail(
                        format!("{name}.status"),
                        "the module does not report POWERED",
                        "check its supply",
                    );
                } else {
                    list.fail(
                        format!("{name}.status"),
                        format!("latched faults {:?}", s.faults),
                        "find and fix their cause, then clear them (they block RF)",
                    );
                }
                let needs_closed = limits
                    .as_ref()
                    .is_some_and(|l| l.enable_requires_interlock_closed);
                match (s.interlock_open, needs_closed) {
                    (false, _) => list.pass(format!("{name}.interlock"), "closed"),
                    (true, true) => list.fail(
                        format!("{name}.interlock"),
                        "open: RF cannot be enabled",
                        "close it: waveguide load or antenna connected, door closed",
                    ),
                    (true, false) => list.warn(
                        format!("{name}.interlock"),
                        "open (this model does not need it closed to enable)",
                        "close it if the bench's safety relies on it",
                    ),
                }
                if s.lo_locked {
                    list.pass(format!("{name}.lo_lock"), "LO locked");
                } else {
                    let range = limits.as_ref().map_or(String::new(), |l| {
                        format!(
                            " ({:.3} ..= {:.3} GHz, x{} multiplier)",
                            l.lo_min_hz / 1e9,
                            l.lo_max_hz / 1e9,
                            l.lo_multiplier
                        )
                    });
                    list.fail(
                        format!("{name}.lo_lock"),
                        "the LO is not locked",
                        format!("check the LO input{range}"),
                    );
                }
                let limit = limits
                    .as_ref()
                    .map_or(f64::INFINITY, |l| l.over_temperature_c);
                let t = s.temperature_c;
                if s.over_temperature || t > limit {
                    list.fail(
                        format!("{name}.temperature"),
                        format!("{t:.1} degC, over its limit of {limit} degC"),
                        "let the module cool down and check its heat sink and airflow",
                    );
                } else if t > limit - TEMPERATURE_MARGIN_C {
                    list.warn(
                        format!("{name}.temperature"),
                        format!("{t:.1} degC, within {TEMPERATURE_MARGIN_C} degC of its limit ({limit} degC)"),
                        "improve the cooling before a long campaign",
                    );
                } else {
                    list.pass(
                        format!("{name}.temperature"),
                        format!("{t:.1} degC (limit {limit} degC)"),
                    );
                }
                if *name == "tx" && s.rf_enabled {
                    tx_on = true;
                    list.fail(
                        "tx.rf_off",
                        "the transmitter is radiating now (RF enabled)",
                        "switch it off (any radbench command ends in the safe state; or by hand)",
                    );
                } else if *name == "tx" {
                    list.pass("tx.rf_off", "RF off");
                }
            }
            Ok(Err(e)) => list.fail(
                format!("{name}.status"),
                e.to_string(),
                "check the cable and the module",
            ),
            Err(_) => list.fail(
                format!("{name}.status"),
                "no status in time (5 s, or what was left of the doctor's checks)",
                "check the cable and the module",
            ),
        }
    }

    // Timebases.
    let (awg, mut scope) = (awg.ok(), scope.ok());
    let mut awg = awg;
    match (&mut awg, &mut scope) {
        (Some(a), Some(s)) => {
            let awg_ref = tokio::time::timeout(deadline.bound(OPEN_TIMEOUT), a.applied()).await;
            let scope_ref =
                tokio::time::timeout(deadline.bound(OPEN_TIMEOUT), s.reference_clock()).await;
            match (awg_ref, scope_ref) {
                (Ok(Ok(applied)), Ok(Ok(sref))) => {
                    let a_ext = applied
                        .reference_source
                        .to_ascii_uppercase()
                        .starts_with("EXT");
                    let s_ext = sref.to_ascii_uppercase().starts_with("EXT");
                    let detail = format!(
                        "AWG reference {}, scope reference {sref}",
                        applied.reference_source
                    );
                    if a_ext && s_ext {
                        list.pass("timebases", format!("shared external reference ({detail})"));
                    } else {
                        list.warn(
                            "timebases",
                            format!("not shared: {detail}; each instrument runs on its own clock"),
                            "for long records or phase-stable captures feed one 10 MHz to both: \
                             the AWG's REF IN with `reference_clock_hz = 10e6` in the bench \
                             file's [awg] (radbench then sends :ROSC:SOUR EXT), and the scope's \
                             reference input set to external (LeCroy RCLK EXTERNAL); captures \
                             work without",
                        );
                    }
                }
                (a, s) => {
                    let why = |r: Result<Result<String, DriverError>, _>| match r {
                        Ok(Ok(v)) => v,
                        Ok(Err(e)) => e.to_string(),
                        Err(_) => "no reply in time".to_string(),
                    };
                    list.warn(
                        "timebases",
                        format!(
                            "cannot tell: AWG {}; scope {}",
                            why(a.map(|r| r.map(|x| x.reference_source))),
                            why(s)
                        ),
                        "read the reference settings on both front panels",
                    );
                }
            }
        }
        _ => list.skip("timebases", "the AWG or the scope was not identified"),
    }

    // The marker at the scope's trigger, transmitter off.
    match (awg, scope) {
        _ if interrupt.received().is_some() => list.skip("marker", "interrupted: not tried"),
        // Too little left for the scope's wait: nothing is switched on.
        (Some(_), Some(_))
            if deadline.bound(MARKER_DEADLINE).as_secs_f64() < 2.0 * MARKER_WAIT_S =>
        {
            list.skip(
                "marker",
                format!(
                    "not tried: the doctor's {} s for its checks were spent before it",
                    CHECKS_TOTAL.as_secs()
                ),
            )
        }
        (Some(a), Some(s)) if !tx_on => {
            let deadline = deadline.bound(MARKER_DEADLINE);
            marker_check(&mut list, a, s, modules, &scope_model, interrupt, deadline).await?;
        }
        (Some(_), Some(_)) => list.skip("marker", "the transmitter is on: not tried"),
        _ => list.skip("marker", "the AWG or the scope was not identified"),
    }

    // Calibrations.
    calibration_checks(&mut list, bench, &awg_idn.ok(), &scope_idn.ok());

    let ok = list.0.iter().all(|c| c.status != Status::Fail);
    Ok(Report {
        bench: bench.describe(),
        checks: list.0,
        ok,
    })
}

/// The doctor stopped by `signal` outside the marker check (whose own guard reports its safe
/// state): nothing is switched on.
pub fn stopped(signal: super::interrupt::StopSignal) -> MeasureError {
    MeasureError::Interrupted {
        signal,
        report: "nothing is switched on; the checks after the signal were not run".into(),
    }
}

/// Plays zero codes with only the marker output on and arms the scope on its external trigger;
/// the bench's safe state runs after it whatever happens.
async fn marker_check(
    list: &mut List,
    awg: Box<dyn Awg>,
    mut scope: Box<dyn Digitizer>,
    modules: Vec<(&'static str, Box<dyn RfFrontEnd>)>,
    scope_model: &InstrumentModel,
    interrupt: &Interrupt,
    deadline: Duration,
) -> Result<(), MeasureError> {
    let awg: Shared<dyn Awg> = safe_state::share(awg);
    let fronts_off = if modules.is_empty() {
        "no front end driven by radbench"
    } else {
        "the front ends it drives off"
    };
    let mut tx = None;
    let mut rx = None;
    for (name, g) in modules {
        let shared = safe_state::share(g);
        if name == "tx" {
            tx = Some(shared);
        } else {
            rx = Some(shared);
        }
    }
    let safe = SafeState::new(
        safe_state::Bench {
            tx,
            rx,
            awg: Some(awg.clone()),
        },
        SAFE_STEP_TIMEOUT,
    );
    // A panic while the AWG plays runs this bench's safe state too.
    crate::driver::set_panic_safe_state(safe.clone());
    let settings = AwgSettings::default();
    let limits = scope_model.digitizer.clone();
    let work = async {
        let rate = match &limits {
            Some(l) => capture_rate(l, settings.sample_rate_hz)?,
            None => settings.sample_rate_hz,
        };
        let n = 16_000usize;
        let waveform = IqWaveform {
            i: vec![0; n],
            q: vec![0; n],
            marker_high_samples: 64,
        };
        let loaded = {
            let mut a = awg.lock().await;
            a.configure(&settings).await?;
            a.load(&waveform).await?
        };
        let scope_settings = DigitizerSettings {
            sample_rate_hz: rate,
            repetition_s: loaded.padded_samples as f64 / settings.sample_rate_hz,
            longest_echo_s: 0.0,
            pre_trigger_s: 0.0,
            trigger_level_v: settings.marker_offset_v,
            segments: 1,
            ..DigitizerSettings::default()
        };
        let scope_settings = match &limits {
            Some(l) => DigitizerSettings {
                i_volts_per_div: l.volts_per_div_default,
                q_volts_per_div: l.volts_per_div_default,
                ..scope_settings
            },
            None => scope_settings,
        };
        scope.configure(&scope_settings).await?;
        {
            let mut a = awg.lock().await;
            a.enable_marker().await?;
            a.run().await?;
        }
        let seen = scope.acquire(MARKER_WAIT_S).await;
        let _ = scope.stop().await;
        Ok::<_, MeasureError>(seen)
    };
    let bounded_work = async {
        tokio::time::timeout(deadline, work)
            .await
            .unwrap_or(Err(MeasureError::RfDeadline {
                seconds: deadline.as_secs_f64(),
            }))
    };
    let (outcome, report) = crate::driver::run_guarded(&safe, bounded_work, interrupt.wait()).await;
    crate::driver::clear_panic_safe_state(&safe);
    let safe_ok = report.is_safe();
    match outcome {
        Outcome::Interrupted => {
            return Err(MeasureError::Interrupted {
                signal: interrupt
                    .received()
                    .unwrap_or(super::interrupt::StopSignal::Interrupt),
                report: report.to_string(),
            })
        }
        Outcome::Finished(Ok(Ok(()))) => list.pass(
            "marker",
            "the AWG's marker (I and Q outputs off, transmitter off) triggers the scope's \
             external input",
        ),
        Outcome::Finished(Ok(Err(DriverError::NoTrigger { waited_s, .. }))) => list.fail(
            "marker",
            format!(
                "no marker edge reached the scope's external trigger within {waited_s} s, with \
                 the AWG running and its marker output on"
            ),
            "check the cable from the AWG's marker output to the scope's EXT trigger input, and \
             the trigger level (the marker's mid level)",
        ),
        Outcome::Finished(Ok(Err(e))) => list.fail(
            "marker",
            format!("the scope's acquisition failed: {e}"),
            "check the scope's trigger settings and its link",
        ),
        Outcome::Finished(Err(e)) => list.fail(
            "marker",
            format!("could not set up the marker test: {e}"),
            "fix the error above (the AWG's or the scope's settings)",
        ),
    }
    if safe_ok {
        list.pass(
            "safe_state",
            format!("after the checks: AWG outputs off and stopped, {fronts_off}"),
        );
    } else {
        list.fail(
            "safe_state",
            format!("the safe state did not complete: {report}"),
            "switch the AWG's outputs and the front ends off by hand, then check their links",
        );
    }
    Ok(())
}

/// The age of a stamp in days, or why it cannot be told.
fn age_days(stamp: &str) -> Result<f64, String> {
    let then = crate::time::parse_utc(stamp)
        .ok_or_else(|| format!("`{stamp}` is not an RFC 3339 UTC time"))?;
    let now = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map(|d| d.as_secs_f64())
        .unwrap_or(0.0);
    Ok((now - then) / 86_400.0)
}

fn calibration_checks(
    list: &mut List,
    bench: &Bench,
    awg_idn: &Option<String>,
    scope_idn: &Option<String>,
) {
    let Some(path) = &bench.path else {
        list.pass(
            "calibration.delay",
            "the built-in mock lab: its nominal system delay is its calibration",
        );
        return;
    };
    let Some(cal) = &bench.file.calibration else {
        list.fail(
            "calibration.delay",
            format!(
                "{} has no [calibration]: ranges would include the fixed system delay",
                path.display()
            ),
            format!(
                "put a pillar at a known range and run `radbench calibrate --reference-range \
                 METRES --bench {} --allow-rf`",
                path.display()
            ),
        );
        return;
    };
    let delay = format!("system delay {:.3} ns", cal.system_delay_s * 1e9);
    match cal.measured_at.as_deref().map(age_days) {
        None => list.warn(
            "calibration.delay",
            format!("{delay}, with no `measured_at`: its age is unknown"),
            "measure it again with `radbench calibrate` (it records the date)",
        ),
        Some(Err(e)) => list.warn(
            "calibration.delay",
            format!("{delay}; measured_at {e}"),
            "measure it again with `radbench calibrate` (it records the date)",
        ),
        Some(Ok(days)) if days > CALIBRATION_MAX_AGE_DAYS => list.warn(
            "calibration.delay",
            format!("{delay}, measured {days:.0} days ago"),
            format!(
                "calibrations older than {CALIBRATION_MAX_AGE_DAYS} days are flagged: measure it \
                 again if cables or horns moved"
            ),
        ),
        Some(Ok(days)) if days < -1.0 / 24.0 => list.warn(
            "calibration.delay",
            format!("{delay}, measured_at lies {:.1} days in the future", -days),
            "check this computer's clock and the stamp",
        ),
        Some(Ok(days)) => list.pass(
            "calibration.delay",
            format!("{delay}, measured {days:.1} days ago"),
        ),
    }
    let Some(response) = bench.file.response_path(path) else {
        list.pass(
            "calibration.response",
            "no response calibration named (captures are processed uncorrected)",
        );
        return;
    };
    match ResponseCalibration::load(&response) {
        Err(e) => list.fail(
            "calibration.response",
            e.to_string(),
            "run `radbench calibrate response` again, or remove `response` from [calibration]",
        ),
        Ok(c) => {
            let seen = &c.header.instruments;
            let mut differs = Vec::new();
            if let Some(now) = awg_idn {
                if *now != seen.awg {
                    differs.push(format!("AWG then `{}`, now `{now}`", seen.awg));
                }
            }
            if let Some(now) = scope_idn {
                if *now != seen.scope {
                    differs.push(format!("scope then `{}`, now `{now}`", seen.scope));
                }
            }
            let age = age_days(&c.header.measured_at)
                .map(|d| format!("measured {d:.1} days ago"))
                .unwrap_or_else(|e| e);
            if !differs.is_empty() {
                list.fail(
                    "calibration.response",
                    format!(
                        "{} ({age}) was measured with other instruments: {}",
                        response.display(),
                        differs.join("; ")
                    ),
                    "measure it again on this bench: `radbench calibrate response \
                     --reference-range R --bench FILE --allow-rf`",
                );
            } else if age_days(&c.header.measured_at).is_ok_and(|d| d > CALIBRATION_MAX_AGE_DAYS) {
                list.warn(
                    "calibration.response",
                    format!("{} ({age})", response.display()),
                    "measure it again if the chain changed",
                );
            } else {
                list.pass(
                    "calibration.response",
                    format!("{} ({age}), same instruments", response.display()),
                );
            }
        }
    }
}

#[cfg(test)]
mod tests {

    #[test]
    fn utc_stamps_parse_to_epoch_seconds() {
        use crate::time::parse_utc;
        assert_eq!(parse_utc("1970-01-01T00:00:00Z"), Some(0.0));
        assert_eq!(parse_utc("2000-03-01T00:00:00.000Z"), Some(951_868_800.0));
        assert_eq!(parse_utc("2026-11-21T20:00:00.500Z"), Some(1_795_291_200.5));
        assert!(parse_utc("yesterday").is_none());
        assert!(parse_utc("2026-13-01T00:00:00Z").is_none());
    }
}
