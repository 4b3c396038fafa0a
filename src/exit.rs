//! Exit codes and how errors map to them.
//!
//! | code | meaning |
//! |---|---|
//! | 0 | success |
//! | 1 | internal error (a bug: please report it) |
//! | 2 | bad input: command line, TOML, parameters (the message names the field and what is allowed) |
//! | 3 | instrument or link failure (the instrument refused, or the connection failed) |
//! | 4 | processing failure (the data could not be processed into a result) |
//! | 129, 130, 143 | stopped by SIGHUP, SIGINT (Ctrl-C) or SIGTERM, after the bench was put in its safe state |
//!
//! A leaf module: it imports nothing of radbench, so every layer can classify its errors. Turning
//! an error chain into an exit code (downcasting to each layer's type) is the CLI's job
//! (`cli::classify`).

use std::fmt;

/// The class of a failure, which decides the process exit code.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ExitClass {
    Internal,
    BadInput,
    Instrument,
    Processing,
    /// Stopped by SIGINT (Ctrl-C).
    Interrupted,
    /// Stopped by SIGTERM.
    Terminated,
    /// Stopped by SIGHUP (the terminal went away).
    HungUp,
}

impl ExitClass {
    pub fn code(self) -> i32 {
        match self {
            ExitClass::Internal => 1,
            ExitClass::BadInput => 2,
            ExitClass::Instrument => 3,
            ExitClass::Processing => 4,
            ExitClass::Interrupted => 130,
            ExitClass::Terminated => 143,
            ExitClass::HungUp => 129,
        }
    }
}

/// Errors of every layer implement this so `main` can pick the exit code.
pub trait Classify {
    fn exit_class(&self) -> ExitClass;
}

/// An error that carries its class explicitly; the CLI wraps layer errors in it.
#[derive(Debug)]
pub struct Classified {
    pub class: ExitClass,
    pub message: String,
}

impl fmt::Display for Classified {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(&self.message)
    }
}

impl std::error::Error for Classified {}

/// Bad user input: the message must name the field and what is allowed.
pub fn bad_input(message: impl Into<String>) -> anyhow::Error {
    anyhow::Error::new(Classified {
        class: ExitClass::BadInput,
        message: message.into(),
    })
}

/// The message for the user: every error of the chain, joined with ": ", except a cause whose
/// text the message before it already quotes (layer errors name their source in their own
/// text, so `{:#}` would print it two or three times).
pub fn render(err: &anyhow::Error) -> String {
    render_chain(err.as_ref())
}

/// `render` of any error and its sources (the one renderer of error chains: the CLI's
/// messages and the campaign's records say the same).
pub(crate) fn render_chain(err: &(dyn std::error::Error + 'static)) -> String {
    let mut out = String::new();
    let mut cause = Some(err);
    while let Some(c) = cause {
        let text = c.to_string();
        if !text.is_empty() && !out.contains(&text) {
            if !out.is_empty() {
                out.push_str(": ");
            }
            out.push_str(&text);
        }
        cause = c.source();
    }
    out
}

/// The candidate a mistyped `word` most likely meant, for "did you mean" hints: the nearest by
/// edit distance (ignoring case), if it is within one edit per three letters (at least one).
/// `None` when nothing is that close, or when `word` is one of them.
pub fn nearest<'a>(word: &str, candidates: impl IntoIterator<Item = &'a str>) -> Option<&'a str> {
    let word = word.to_ascii_lowercase();
    let limit = (word.chars().count() / 3).max(1);
    let mut best: Option<(usize, &str)> = None;
    for c in candidates {
        let d = edit_distance(&word, &c.to_ascii_lowercase());
        if d == 0 {
            return None;
        }
        if d <= limit && best.is_none_or(|(b, _)| d < b) {
            best = Some((d, c));
        }
    }
    best.map(|(_, c)| c)
}

/// `"; did you mean `x`?"` when [`nearest`] finds one, else nothing: appended to a message that
/// already names the word and what is allowed.
pub fn did_you_mean<'a>(word: &str, candidates: impl IntoIterator<Item = &'a str>) -> String {
    nearest(word, candidates)
        .map(|c| format!("; did you mean `{c}`?"))
        .unwrap_or_default()
}

/// A serde message about an unknown key (`unknown field `x`, expected one of `a`, `b``, as
/// `deny_unknown_fields` words it) with a did-you-mean for the nearest expected key; any other
/// message as it is.
pub fn with_key_hint(message: &str) -> String {
    let Some(rest) = message.split("unknown field `").nth(1) else {
        return message.to_string();
    };
    let Some((key, expected)) = rest.split_once('`') else {
        return message.to_string();
    };
    let allowed: Vec<&str> = expected.split('`').skip(1).step_by(2).collect();
    let hint = did_you_mean(key, allowed);
    if hint.is_empty() {
        return message.to_string();
    }
    format!("{}{hint}", message.trim_end())
}

/// Edit distance: insertions, deletions, substitutions and swaps of two neighbours, one each
/// (optimal string alignment).
fn edit_distance(a: &str, b: &str) -> usize {
    let a: Vec<char> = a.chars().collect();
    let b: Vec<char> = b.chars().collect();
    // d[i][j]: the distance between a[..i] and b[..j].
    let mut d = vec![vec![0usize; b.len() + 1]; a.len() + 1];
    for (i, row) in d.iter_mut().enumerate() {
        row[0] = i;
    }
    for (j, cell) in d[0].iter_mut().enumerate() {
        *cell = j;
    }
    for i in 1..=a.len() {
        for j in 1..=b.len() {
            let cost = usize::from(a[i - 1] != b[j - 1]);
            let mut best = (d[i - 1][j] + 1)
                .min(d[i][j - 1] + 1)
                .min(d[i - 1][j - 1] + cost);
            if i > 1 && j > 1 && a[i - 1] == b[j - 2] && a[i - 2] == b[j - 1] {
                best = best.min(d[i - 2][j - 2] + 1);
            }
            d[i][j] = best;
        }
    }
    d[a.len()][b.len()]
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_slip_of_the_keyboard_finds_what_was_meant() {
        assert_eq!(nearest("hislp", ["hislip", "inst"]), Some("hislip"));
        assert_eq!(nearest("windw", ["window", "algorithm"]), Some("window"));
        assert_eq!(nearest("SOKCET", ["SOCKET", "INSTR"]), Some("SOCKET"));
        assert_eq!(
            nearest("tx_atenuation", ["tx_attenuation_db", "tx_attenuation"]),
            Some("tx_attenuation")
        );
        // Exact words, and words nothing is near, get no hint.
        assert_eq!(nearest("window", ["window"]), None);
        assert_eq!(nearest("gpib", ["hislip", "inst"]), None);
        assert_eq!(did_you_mean("x", ["window"]), "");
        assert_eq!(
            did_you_mean("widow", ["window"]),
            "; did you mean `window`?"
        );
        assert_eq!(edit_distance("kitten", "sitting"), 3);
        assert_eq!(
            with_key_hint("unknown field `repetitons`, expected one of `name`, `repetitions`"),
            "unknown field `repetitons`, expected one of `name`, `repetitions`; did you mean \
             `repetitions`?"
        );
        assert_eq!(
            with_key_hint("unknown field `zzz`, expected `name`"),
            "unknown field `zzz`, expected `name`"
        );
        assert_eq!(with_key_hint("missing field `awg`"), "missing field `awg`");
        assert_eq!(edit_distance("insrt", "instr"), 1);
    }
}
