//! One query to an instrument on a fresh session, bounded: for `doctor --verify-catalog`, which
//! asks for values the drivers never need (`*OPT?`). A fresh session per query keeps an
//! unanswered query from putting the next one out of step.

use super::error::{session, DriverError};
use super::io::open_session;
use crate::address::Resource;
use crate::catalog::InstrumentModel;
use crate::transport::Journal;
use std::time::Duration;

/// The reply to `query` (its terminator removed), or why there is none: an error, or no answer
/// within `limit` (connecting included).
pub(crate) async fn ask_once(
    resource: Resource,
    model: &InstrumentModel,
    query: &str,
    limit: Duration,
    journal: Option<Journal>,
    name: &str,
) -> Result<String, String> {
    let work = async {
        let mut s = open_session(resource, model, "", journal, name)
            .await
            .map_err(session(name))?;
        s.query(query).await.map_err(session(name))
    };
    match tokio::time::timeout(limit, work).await {
        Ok(Ok(reply)) => Ok(reply.trim().to_string()),
        Ok(Err(e)) => Err(DriverError::to_string(&e)),
        Err(_) => Err(format!(
            "no answer to {query} within {}",
            crate::transport::Rounded(limit)
        )),
    }
}

/// A limit found by asking for an out-of-range value and reading back what the instrument made of
/// it (the LeCroy family adapts such a value to the nearest it can do), then putting the setting
/// back as it was. `set` holds `{}` where the value goes.
pub(crate) struct Probe<'a> {
    pub query: &'a str,
    pub set: &'a str,
    pub beyond: f64,
}

/// The value the instrument adapted `probe.beyond` to, restoring the setting after and reading it
/// back; or why not (a setting not restored included).
pub(crate) async fn probe_limit(
    resource: Resource,
    model: &InstrumentModel,
    probe: &Probe<'_>,
    limit: Duration,
    journal: Option<Journal>,
    name: &str,
) -> Result<f64, String> {
    let number = |reply: String| {
        reply_number(&reply)
            .ok_or_else(|| format!("{} answered {reply:?}, not a number", probe.query))
    };
    let work = async {
        let mut s = open_session(resource, model, "", journal, name)
            .await
            .map_err(|e| DriverError::to_string(&session(name)(e)))?;
        let as_text = |e| DriverError::to_string(&session(name)(e));
        let before = number(s.query(probe.query).await.map_err(as_text)?)?;
        s.write(&probe.set.replace("{}", &format!("{:e}", probe.beyond)))
            .await
            .map_err(as_text)?;
        let reached = s.query(probe.query).await.map_err(as_text).and_then(number);
        // Put the setting back even when the read-back failed, and read it once more: a write
        // has no reply, and one left in flight when this session closes may be carried out after
        // the next session's probe of the same setting (the instrument serves each connection on
        // its own), which then reads this value back instead of its own.
        let restored = match s
            .write(&probe.set.replace("{}", &format!("{before:e}")))
            .await
        {
            Ok(()) => s.query(probe.query).await.map_err(as_text).and_then(number),
            Err(e) => Err(as_text(e)),
        };
        let reached = reached?;
        let restored = restored?;
        if (restored - before).abs() > 1e-6 * before.abs().max(restored.abs()) {
            return Err(format!(
                "{} answered {restored:e} after it was set back to {before:e}: set it back by hand",
                probe.query
            ));
        }
        Ok(reached)
    };
    match tokio::time::timeout(limit, work).await {
        Ok(r) => r,
        Err(_) => Err(format!(
            "no answer to {} within {}",
            probe.query,
            crate::transport::Rounded(limit)
        )),
    }
}

/// The first number in a reply, its header and unit aside: `C1:VDIV 50E-3 V` -> 0.05,
/// `MSIZ 10MA` -> 1e7, `16000000000,16000000000` -> 1.6e10.
pub(crate) fn reply_number(reply: &str) -> Option<f64> {
    reply
        .split(|c: char| c.is_whitespace() || c == ',' || c == '"' || c == '\'')
        .find_map(|token| {
            let upper = token.to_ascii_uppercase();
            let (digits, scale) = [("MA", 1e6), ("K", 1e3), ("M", 1e6), ("G", 1e9)]
                .iter()
                .find_map(|(suffix, scale)| {
                    upper
                        .strip_suffix(suffix)
                        .filter(|d| d.ends_with(|c: char| c.is_ascii_digit()))
                        .map(|d| (d.to_string(), *scale))
                })
                .unwrap_or((upper.clone(), 1.0));
            digits.parse::<f64>().ok().map(|v| v * scale)
        })
}

#[cfg(test)]
mod tests {
    use super::reply_number;

    #[test]
    fn numbers_are_read_past_headers_and_units() {
        assert_eq!(reply_number("C1:VDIV 50E-3 V"), Some(0.05));
        assert_eq!(reply_number("MSIZ 10MA"), Some(1e7));
        assert_eq!(reply_number("VBS 8E+10"), Some(8e10));
        assert_eq!(reply_number("131072,131072"), Some(131072.0));
        assert_eq!(reply_number("+6.5000000000E+10"), Some(6.5e10));
        assert_eq!(reply_number("EXT"), None);
    }
}
