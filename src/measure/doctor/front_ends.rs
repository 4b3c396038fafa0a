//! The Tx and Rx front ends: reached on their serial line in the catalog's CRC mode and
//! identified; the manual ones (which radbench cannot switch off) named; then one status read of
//! each module radbench drives: power and latched faults, interlock, LO lock, temperature, and
//! whether the transmitter radiates now (the marker check is not tried then).

use super::bounds::{Deadline, OPEN_TIMEOUT};
use super::checklist::List;
use super::connect::FrontOpened;
use super::entries::Entry;
use super::identity::wrong_instrument;
use crate::catalog::RfLimits;
use crate::driver::{open, RfFrontEnd, RfStatus};
use crate::measure::bench::bench_file::BenchFile;
use crate::measure::bench::manual::manual_doctor_fix;

/// Temperatures within this of a module's over-temperature limit are flagged, degrees C.
const TEMPERATURE_MARGIN_C: f64 = 5.0;

/// A front end that answered (in either line mode), by its section: `tx` or `rx`.
pub(super) type Module = (&'static str, Box<dyn RfFrontEnd>);

/// `<front>.reachable`, `<front>.crc_mode` and `<front>.identity` of each front end: a module
/// that answers only in the other line mode is on the wrong CRC mode, not dead. Returns the
/// modules that answered, for the status read and the safe state.
pub(super) fn check_links(
    list: &mut List,
    fronts: &[Entry],
    opened: Vec<FrontOpened>,
) -> Vec<Module> {
    let mut modules = Vec::new();
    for (front, (opened, other)) in fronts.iter().zip(opened) {
        let (name, resource, model) = (front.name, &front.written, &front.model);
        let catalog_mode = open::rf_line_mode(model).unwrap_or("its line protocol");
        let crc = format!("{name}.crc_mode");
        // A module that answers (in the catalog's mode, or else in the other) is identified
        // either way.
        let identified = |list: &mut List, g: &dyn RfFrontEnd| {
            list.pass(
                format!("{name}.identity"),
                format!(
                    "`{}` matches the catalog's {}",
                    g.identity(),
                    model.instrument.model
                ),
            );
        };
        let reachable = format!("{name}.reachable");
        match (opened, other) {
            (Ok(g), _) => {
                list.pass(reachable, format!("{resource} answers"));
                list.pass(
                    crc,
                    format!("the module speaks {catalog_mode}, as the catalog says"),
                );
                identified(list, g.as_ref());
                modules.push((name, g));
            }
            (Err(e), Some(g)) => {
                list.pass(reachable, format!("{resource} answers"));
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
                identified(list, g.as_ref());
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
    modules
}

/// `<front>.driver`: a warning for each front end with `driver = "manual"`, which radbench does
/// not talk to and cannot switch off.
pub(super) fn check_manual(list: &mut List, file: &BenchFile) {
    for m in &file.manual {
        list.warn(
            format!("{}.driver", m.section),
            format!(
                "manual (driver = \"manual\"): radbench does not talk to the {} module and \
                 cannot switch it off; runs ask the operator to confirm its settings",
                m.name()
            ),
            manual_doctor_fix(m),
        );
    }
}

/// `<front>.status`, `.interlock`, `.lo_lock`, `.temperature` and `tx.rf_off` from one status
/// read of each module (bounded like an open). Returns whether the transmitter radiates now.
pub(super) async fn check_status(
    list: &mut List,
    fronts: &[Entry],
    modules: &mut [Module],
    deadline: Deadline,
) -> bool {
    let mut tx_on = false;
    for (name, g) in modules.iter_mut() {
        let limits = fronts
            .iter()
            .find(|f| f.name == *name)
            .and_then(|f| f.model.rf.clone());
        match tokio::time::timeout(deadline.bound(OPEN_TIMEOUT), g.status()).await {
            Ok(Ok(s)) => {
                power_and_faults(list, name, &s);
                interlock(list, name, &s, limits.as_ref());
                lo_lock(list, name, &s, limits.as_ref());
                temperature(list, name, &s, limits.as_ref());
                tx_on |= transmitter_radiates(list, name, &s);
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
    tx_on
}

fn power_and_faults(list: &mut List, name: &str, s: &RfStatus) {
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
}

fn interlock(list: &mut List, name: &str, s: &RfStatus, limits: Option<&RfLimits>) {
    let needs_closed = limits.is_some_and(|l| l.enable_requires_interlock_closed);
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
}

fn lo_lock(list: &mut List, name: &str, s: &RfStatus, limits: Option<&RfLimits>) {
    if s.lo_locked {
        list.pass(format!("{name}.lo_lock"), "LO locked");
    } else {
        let range = limits.map_or(String::new(), |l| {
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
}

fn temperature(list: &mut List, name: &str, s: &RfStatus, limits: Option<&RfLimits>) {
    let limit = limits.map_or(f64::INFINITY, |l| l.over_temperature_c);
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
}

/// `tx.rf_off` (the Tx only): true when it radiates now.
fn transmitter_radiates(list: &mut List, name: &str, s: &RfStatus) -> bool {
    if name != "tx" {
        return false;
    }
    if s.rf_enabled {
        list.fail(
            "tx.rf_off",
            "the transmitter is radiating now (RF enabled)",
            "switch it off (any radbench command ends in the safe state; or by hand)",
        );
        true
    } else {
        list.pass("tx.rf_off", "RF off");
        false
    }
}
