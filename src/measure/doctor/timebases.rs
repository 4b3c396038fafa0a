//! `timebases`: the AWG's and the scope's reference settings, read back. Two instruments on
//! their own clocks drift apart over a long record; one 10 MHz fed to both keeps captures
//! phase-stable. A warning, not a failure: captures work without.

use super::bounds::{Deadline, OPEN_TIMEOUT};
use super::checklist::List;
use crate::catalog::InstrumentModel;
use crate::driver::{open, Awg, Digitizer, DriverError};

/// Whether the AWG and the scope share an external reference; skipped unless both were
/// identified. The fix names the scope family's own setting.
pub(super) async fn check_timebases(
    list: &mut List,
    awg: Option<&mut Box<dyn Awg>>,
    scope: Option<&mut Box<dyn Digitizer>>,
    scope_model: &InstrumentModel,
    deadline: Deadline,
) {
    let (Some(a), Some(s)) = (awg, scope) else {
        list.skip("timebases", "the AWG or the scope was not identified");
        return;
    };
    let awg_ref = tokio::time::timeout(deadline.bound(OPEN_TIMEOUT), a.applied()).await;
    let scope_ref = tokio::time::timeout(deadline.bound(OPEN_TIMEOUT), s.reference_clock()).await;
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
                    format!(
                        "for long records or phase-stable captures feed one 10 MHz to both: the \
                         AWG's REF IN with `reference_clock_hz = 10e6` in the bench file's [awg] \
                         (radbench then sends :ROSC:SOUR EXT), and the scope's reference input \
                         set to external ({}); captures work without",
                        open::scope_external_reference(scope_model)
                    ),
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
