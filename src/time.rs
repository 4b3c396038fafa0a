//! Wall-clock time as RFC 3339 UTC text, for journals, run files and SigMF (no time-zone crate
//! needed: radbench only ever writes UTC).

use std::time::SystemTime;

/// `YYYY-MM-DDTHH:MM:SS.ffffffZ` (microseconds), e.g. `2026-11-21T19:43:30.123456Z`.
pub(crate) fn rfc3339_micros(t: SystemTime) -> String {
    let since = t.duration_since(SystemTime::UNIX_EPOCH).unwrap_or_default();
    format!(
        "{}.{:06}Z",
        date_time(since.as_secs()),
        since.subsec_micros()
    )
}

/// `YYYY-MM-DDTHH:MM:SS.mmmZ` (milliseconds), e.g. `2026-11-21T19:55:00.042Z`.
pub(crate) fn rfc3339_millis(t: SystemTime) -> String {
    let since = t.duration_since(SystemTime::UNIX_EPOCH).unwrap_or_default();
    format!(
        "{}.{:03}Z",
        date_time(since.as_secs()),
        since.subsec_millis()
    )
}

fn date_time(secs: u64) -> String {
    let (y, m, d) = civil_from_days((secs / 86_400) as i64);
    let rem = secs % 86_400;
    format!(
        "{y:04}-{m:02}-{d:02}T{:02}:{:02}:{:02}",
        rem / 3600,
        (rem / 60) % 60,
        rem % 60
    )
}

/// Days since 1970-01-01 to (year, month, day) in the proleptic Gregorian calendar
/// (H. Hinnant's algorithm).
pub(crate) fn civil_from_days(z: i64) -> (i64, u32, u32) {
    let z = z + 719_468;
    let era = z.div_euclid(146_097);
    let doe = z.rem_euclid(146_097);
    let yoe = (doe - doe / 1460 + doe / 36_524 - doe / 146_096) / 365;
    let y = yoe + era * 400;
    let doy = doe - (365 * yoe + yoe / 4 - yoe / 100);
    let mp = (5 * doy + 2) / 153;
    let d = (doy - (153 * mp + 2) / 5 + 1) as u32;
    let m = if mp < 10 { mp + 3 } else { mp - 9 } as u32;
    (if m <= 2 { y + 1 } else { y }, m, d)
}

/// Days since 1970-01-01 of a civil date (Howard Hinnant's algorithm).
pub(crate) fn days_from_civil(y: i64, m: u32, d: u32) -> i64 {
    let y = if m <= 2 { y - 1 } else { y };
    let era = y.div_euclid(400);
    let yoe = y - era * 400;
    let m = i64::from(m);
    let doy = (153 * (if m > 2 { m - 3 } else { m + 9 }) + 2) / 5 + i64::from(d) - 1;
    let doe = yoe * 365 + yoe / 4 - yoe / 100 + doy;
    era * 146_097 + doe - 719_468
}

/// Seconds since the epoch of an RFC 3339 UTC stamp `YYYY-MM-DDTHH:MM:SS[.fff]Z`.
pub(crate) fn parse_utc(text: &str) -> Option<f64> {
    let t = text.trim();
    let (date, time) = t.split_once(['T', ' '])?;
    let mut d = date.split('-');
    let (y, m, day): (i64, u32, u32) = (
        d.next()?.parse().ok()?,
        d.next()?.parse().ok()?,
        d.next()?.parse().ok()?,
    );
    let time = time.trim_end_matches('Z');
    let mut parts = time.split(':');
    let (h, mi): (f64, f64) = (parts.next()?.parse().ok()?, parts.next()?.parse().ok()?);
    let s: f64 = parts.next().unwrap_or("0").parse().ok()?;
    if !(1..=12).contains(&m) || !(1..=31).contains(&day) {
        return None;
    }
    Some(days_from_civil(y, m, day) as f64 * 86_400.0 + h * 3600.0 + mi * 60.0 + s)
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::time::Duration;

    #[test]
    fn known_instants() {
        let epoch = SystemTime::UNIX_EPOCH;
        assert_eq!(rfc3339_micros(epoch), "1970-01-01T00:00:00.000000Z");
        assert_eq!(rfc3339_millis(epoch), "1970-01-01T00:00:00.000Z");
        let leap = epoch + Duration::from_micros(951_782_400_000_001);
        assert_eq!(rfc3339_micros(leap), "2000-02-29T00:00:00.000001Z");
        let t = epoch + Duration::from_millis(1_795_290_900_042);
        assert_eq!(rfc3339_millis(t), "2026-11-21T19:55:00.042Z");
    }
}
