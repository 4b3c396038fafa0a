//! Reachable, then the right instrument: the first two checks of a network instrument
//! (`<inst>.reachable`, `<inst>.identity`), and the AWG's, which are all it gets before the
//! timebases and the marker.

use super::checklist::List;
use super::connect::Probe;
use super::entries::Entry;

/// Whether an open failed because another instrument answered (its `*IDN?` or a Gotmic's ID
/// register is not the catalog model's).
pub(super) fn wrong_instrument(err: &str) -> bool {
    err.contains("`*IDN?`") && err.contains("which is not") || err.contains("ID register")
}

/// `awg.reachable` and `awg.identity`: the AWG must answer on its resource and be the catalog's
/// model before anything is played.
pub(super) fn check_awg(list: &mut List, awg: &Entry, probe: &Probe, idn: &Result<String, String>) {
    reach_and_identity(list, awg, probe, idn);
}

/// Reachability and identity of a network instrument from the probe and the driver's open.
pub(super) fn reach_and_identity(
    list: &mut List,
    instrument: &Entry,
    probe: &Probe,
    opened: &Result<String, String>,
) {
    let (resource, model) = (&instrument.written, &instrument.model);
    let reach = format!("{}.reachable", instrument.name);
    let ident = format!("{}.identity", instrument.name);
    match (probe, opened) {
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
