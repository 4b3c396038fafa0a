//! `calibration.delay` and `calibration.response`: the bench file's `[calibration]` present, its
//! age (`measured_at`), and the response calibration it names readable and measured with the
//! instruments connected now. A bench without them still captures, with ranges that include the
//! fixed system delay or processed uncorrected.

use super::checklist::List;
use crate::measure::bench::bench_file::BenchCalibration;
use crate::measure::bench::in_use::Bench;
use crate::measure::calibration::response::Calibration as ResponseCalibration;
use std::path::Path;

/// A calibration older than this is flagged, days.
const CALIBRATION_MAX_AGE_DAYS: f64 = 30.0;

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

/// The system delay (present, its age) and the response calibration (readable, the instruments
/// it was measured with against `awg_idn` and `scope_idn`, the identities found now). The
/// built-in lab and a bench file without `[calibration]` get the first only.
pub(super) fn check_calibrations(
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
    check_delay(list, cal);
    check_response(list, bench, path, awg_idn, scope_idn);
}

/// `calibration.delay` of a bench file's `[calibration]`: its age from `measured_at`.
fn check_delay(list: &mut List, cal: &BenchCalibration) {
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
}

/// `calibration.response`: the response calibration the bench file names, readable and measured
/// with the instruments identified now (`awg_idn`, `scope_idn`; one not identified is not
/// compared).
fn check_response(
    list: &mut List,
    bench: &Bench,
    path: &Path,
    awg_idn: &Option<String>,
    scope_idn: &Option<String>,
) {
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
