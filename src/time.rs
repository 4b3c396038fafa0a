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
