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
//!
//! [`examine`] runs the check groups in this order, each in its file:
//!
//! | file | what it checks or holds |
//! |---|---|
//! | `entries.rs` | the bench file and the catalog: each instrument's model and resource (an error, not a check, when wrong) |
//! | `connect.rs` | every instrument reached at once: the TCP listeners, then each driver's open (Ctrl-C ends the doctor here) |
//! | `identity.rs` | `<inst>.reachable`, `<inst>.identity` of a network instrument; the AWG's |
//! | `scope.rs` | the scope's, and `scope.remote_interface` (the other interface tried) |
//! | `front_ends.rs` | the Tx and Rx: reachable, CRC mode, identity; manual ones; status, interlock, LO lock, temperature, `tx.rf_off` |
//! | `timebases.rs` | `timebases`: the AWG's and the scope's reference settings |
//! | `marker.rs` | `marker` (the AWG's marker at the scope's trigger, transmitter off) and `safe_state` after it |
//! | `calibration.rs` | `calibration.delay`, `calibration.response` |
//! | `checklist.rs` | the checklist being written and the [`Report`] it becomes |
//! | `bounds.rs` | each wait's bound and the checks' total (`CHECKS_TOTAL`), the error of a stop ([`stopped`]) |

mod bounds;
mod calibration;
mod checklist;
mod connect;
mod entries;
mod front_ends;
mod identity;
mod marker;
mod scope;
mod timebases;

pub use bounds::stopped;
pub use checklist::{Check, Report, Status};

use crate::driver::Journal;
use crate::measure::bench::in_use::Bench;
use crate::measure::bench::interrupt::Interrupt;
use crate::measure::error::MeasureError;
use bounds::Deadline;
use checklist::List;
use entries::Entries;
use marker::Connected;

/// Runs every check of `bench`, in the order the checklist shows them. `journal` records every
/// exchange (`--trace-io`).
///
/// # Errors
/// The bench file names a model the catalog lacks or a resource that does not parse; a stop
/// signal while the instruments are opened ([`stopped`]) or while the marker plays.
pub async fn examine(
    bench: &Bench,
    journal: Option<Journal>,
    interrupt: &Interrupt,
) -> Result<Report, MeasureError> {
    let entries = Entries::read(&bench.file)?;
    let deadline = Deadline::start();
    let opened = connect::open_all(&entries, journal, deadline, interrupt).await?;
    let mut list = List::default();
    let (awg_idn, scope_idn) = (opened.awg_identity(), opened.scope_identity());
    identity::check_awg(&mut list, &entries.awg, &opened.awg_probe, &awg_idn);
    scope::check_scope(
        &mut list,
        bench,
        &entries.scope,
        &opened.scope_probe,
        &scope_idn,
        deadline,
    )
    .await;
    let mut modules = front_ends::check_links(&mut list, &entries.fronts, opened.fronts);
    front_ends::check_manual(&mut list, &bench.file);
    let tx_on = front_ends::check_status(&mut list, &entries.fronts, &mut modules, deadline).await;
    let (mut awg, mut scope) = (opened.awg.ok(), opened.scope.ok());
    let scope_model = &entries.scope.model;
    timebases::check_timebases(
        &mut list,
        awg.as_mut(),
        scope.as_mut(),
        scope_model,
        deadline,
    )
    .await;
    let connected = Connected {
        awg,
        scope,
        modules,
        tx_on,
    };
    marker::check_marker(&mut list, connected, scope_model, interrupt, deadline).await?;
    calibration::check_calibrations(&mut list, bench, &awg_idn.ok(), &scope_idn.ok());
    Ok(list.into_report(bench.describe()))
}
