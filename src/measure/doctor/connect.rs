//! Every instrument of the bench reached at once: a TCP connection to each network instrument's
//! listener first (so "nothing answers" is told apart from "the wrong thing answers"), then each
//! driver's open, which checks the identity; a front end that does not answer in the catalog's
//! line mode is asked in the other one. Ctrl-C meanwhile ends the doctor: nothing is on yet.

use super::bounds::{bounded, seconds, stopped, Deadline, OPEN_TIMEOUT};
use super::entries::{Entries, Entry};
use crate::address::Resource;
use crate::driver::open;
use crate::driver::{Awg, Digitizer, Journal, RfFrontEnd};
use crate::measure::bench::interrupt::Interrupt;
use crate::measure::error::MeasureError;

/// What answered a TCP connection: `None` for serial resources, else `Ok(address)` or
/// `Err(what happened)`.
pub(super) type Probe = Option<Result<String, String>>;

/// A front end opened in the catalog's line mode, or why not and the module opened in the other
/// mode when it answers there.
pub(super) type FrontOpened = (
    Result<Box<dyn RfFrontEnd>, String>,
    Option<Box<dyn RfFrontEnd>>,
);

/// The instruments as the opening left them.
pub(super) struct Opened {
    pub(super) awg_probe: Probe,
    pub(super) scope_probe: Probe,
    pub(super) awg: Result<Box<dyn Awg>, String>,
    pub(super) scope: Result<Box<dyn Digitizer>, String>,
    /// One per front end of [`Entries::fronts`], in its order.
    pub(super) fronts: Vec<FrontOpened>,
}

impl Opened {
    /// The AWG's `*IDN?` reply, or why it was not identified.
    pub(super) fn awg_identity(&self) -> Result<String, String> {
        self.awg
            .as_ref()
            .map(|a| a.identity().to_string())
            .map_err(Clone::clone)
    }

    /// The scope's `*IDN?` reply on the bench file's resource, or why it was not identified.
    pub(super) fn scope_identity(&self) -> Result<String, String> {
        self.scope
            .as_ref()
            .map(|s| s.identity().to_string())
            .map_err(Clone::clone)
    }
}

/// Probes the AWG's and the scope's listeners, then opens the AWG, the scope and the front ends
/// together. `journal` records every exchange.
///
/// # Errors
/// [`MeasureError::Interrupted`] (through [`stopped`]) when a stop signal comes meanwhile.
pub(super) async fn open_all(
    entries: &Entries,
    journal: Option<Journal>,
    deadline: Deadline,
    interrupt: &Interrupt,
) -> Result<Opened, MeasureError> {
    let (awg, scope) = (&entries.awg, &entries.scope);
    let (awg_probe, scope_probe) = tokio::join!(
        tcp_probe(&awg.resource, deadline),
        tcp_probe(&scope.resource, deadline)
    );
    let awg_open = async {
        if matches!(awg_probe, Some(Err(_))) {
            return Err("not reachable".to_string());
        }
        bounded(
            deadline,
            open::open_awg(awg.resource.clone(), &awg.model, journal.clone(), "awg"),
        )
        .await
    };
    let scope_open = async {
        if matches!(scope_probe, Some(Err(_))) {
            return Err("not reachable".to_string());
        }
        bounded(
            deadline,
            open::open_digitizer(
                scope.resource.clone(),
                &scope.model,
                journal.clone(),
                "scope",
            ),
        )
        .await
    };
    let front_opens = async {
        let mut out = Vec::new();
        for front in &entries.fronts {
            out.push(open_front(front, journal.clone(), deadline).await);
        }
        out
    };
    // Ctrl-C while the instruments are being opened ends the doctor at once: nothing is on yet.
    let (awg, scope, fronts) = tokio::select! {
        opened = async { tokio::join!(awg_open, scope_open, front_opens) } => opened,
        signal = interrupt.wait() => return Err(stopped(signal)),
    };
    Ok(Opened {
        awg_probe,
        scope_probe,
        awg,
        scope,
        fronts,
    })
}

/// Whether a TCP listener answers at the resource's address.
async fn tcp_probe(resource: &Resource, deadline: Deadline) -> Probe {
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

/// Opens a front end in the catalog's framing; when that fails, asks it in the other framing
/// (a module that answers there is on the wrong CRC mode, not dead).
async fn open_front(front: &Entry, journal: Option<Journal>, deadline: Deadline) -> FrontOpened {
    let (name, res, model) = (front.name, &front.resource, &front.model);
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
