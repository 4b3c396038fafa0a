//! What a command form runs with (its call and its report), the parameters of the legacy commands
//! and the scope's number format, with the CMR/EXR codes the scope sets when they are wrong.

use super::state::ScopeState;
use super::Fault;
use crate::catalog::DigitizerModel;
use crate::emulator::scpi::message::Param;
use crate::emulator::scpi::numeric::{parse_with_unit, Unit};

/// What a command form runs with.
pub(super) struct Call<'a> {
    pub model: &'a DigitizerModel,
    /// The sticky header path (`C1`, `EX`) at the time of the command.
    pub path: &'a str,
    /// `(long, short)` names, for replies and messages.
    pub names: (&'static str, &'static str),
    pub params: &'a [Param],
}

/// A setting's value as a query reports it.
pub(super) struct Report {
    /// Whether the reply repeats the path (`C1:VDIV 5.00E-02 V`) when headers are on.
    pub on_path: bool,
    pub body: String,
}

impl Report {
    pub(super) fn plain(body: impl Into<String>) -> Report {
        Report {
            on_path: false,
            body: body.into(),
        }
    }

    pub(super) fn on_path(body: impl Into<String>) -> Report {
        Report {
            on_path: true,
            body: body.into(),
        }
    }
}

/// A command error: CMR code (1 unknown header, 2 illegal path, 3 illegal number, 5 unknown
/// keyword, 10 block not allowed); abandons the rest of the message.
pub(super) fn cmd_err(code: u8, text: impl Into<String>) -> Fault {
    Fault::Command(code, text.into())
}

/// An execution error: EXR code (22 environment, 25 parameter, 26 not implemented, 27 parameter
/// missing).
pub(super) fn exe_err(code: u8, text: impl Into<String>) -> Fault {
    Fault::Execution(code, text.into())
}

/// LeCroy-style number with unit: `2.00E-01 V`.
pub(super) fn number(value: f64, unit: &str) -> String {
    let s = format!("{value:.2E}");
    let formatted = match s.split_once('E') {
        Some((m, e)) => {
            let e: i32 = e.parse().unwrap_or(0);
            format!("{m}E{}{:02}", if e < 0 { '-' } else { '+' }, e.abs())
        }
        None => s,
    };
    if unit.is_empty() {
        formatted
    } else {
        format!("{formatted} {unit}")
    }
}

/// The text of a parameter; a block is a command error.
pub(super) fn text(p: &Param) -> Result<&str, Fault> {
    p.text()
        .map(str::trim)
        .ok_or_else(|| cmd_err(10, "a block is not allowed here"))
}

/// Every parameter's text, upper case.
pub(super) fn words(params: &[Param]) -> Result<Vec<String>, Fault> {
    params
        .iter()
        .map(|p| text(p).map(str::to_ascii_uppercase))
        .collect()
}

/// The one parameter of `name`.
pub(super) fn one<'a>(params: &'a [Param], name: &str) -> Result<&'a str, Fault> {
    match params {
        [p] => text(p),
        [] => Err(exe_err(27, format!("{name} needs a parameter"))),
        _ => Err(exe_err(25, format!("{name} takes one parameter"))),
    }
}

/// A number with an optional unit suffix.
pub(super) fn value(text: &str, unit: Unit) -> Result<f64, Fault> {
    parse_with_unit(&text.to_ascii_uppercase(), unit)
        .map_err(|_| cmd_err(3, format!("{text:?} is not a number")))
}

/// Clamps into `min..=max`, flagging VAB when the value had to be adapted.
pub(super) fn adapt(st: &mut ScopeState, v: f64, min: f64, max: f64) -> f64 {
    let clamped = v.clamp(min, max);
    if clamped != v {
        st.value_adapted = true;
    }
    clamped
}

/// The channel index of a `C<n>:` path (`C1` -> 0).
pub(super) fn channel_index(path: &str) -> Option<usize> {
    path.strip_prefix('C')
        .and_then(|n| n.parse::<usize>().ok())
        .and_then(|n| n.checked_sub(1))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn lecroy_number_format() {
        assert_eq!(number(0.2, "V"), "2.00E-01 V");
        assert_eq!(number(-5e-8, "S"), "-5.00E-08 S");
        assert_eq!(number(32e6, ""), "3.20E+07");
    }

    #[test]
    fn channel_paths() {
        assert_eq!(channel_index("C1"), Some(0));
        assert_eq!(channel_index("C0"), None);
        assert_eq!(channel_index("EX"), None);
    }
}
