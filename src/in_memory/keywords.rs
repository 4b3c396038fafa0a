//! `radbench process`'s options as keywords (the Python package's `process(window="hann")`):
//! the same parser, with errors that name the keyword (`window`), not the command line's option
//! (`--window`), and a did-you-mean for an unknown one.

use crate::exit::{did_you_mean, Classified, Classify};
use crate::measure::MeasureError;

/// The keyword of a command-line option: `--zero-pad` -> `zero_pad`.
fn keyword(long: &str) -> String {
    long.replace('-', "_")
}

/// Refuses an option none of `longs` names, naming it as the keyword it was given as.
pub(super) fn check_known(
    options: &[String],
    longs: &[String],
    refused: &[&str],
) -> anyhow::Result<()> {
    for o in options {
        let Some(name) = o.strip_prefix("--") else {
            continue;
        };
        let name = name.split('=').next().unwrap_or(name);
        if longs.iter().any(|l| l == name) || refused.contains(&format!("--{name}").as_str()) {
            // A refused option is refused by name by the parser.
            continue;
        }
        let keywords: Vec<String> = longs
            .iter()
            .filter(|l| !refused.contains(&format!("--{l}").as_str()))
            .map(|l| keyword(l))
            .collect();
        return Err(crate::exit::bad_input(format!(
            "unknown keyword `{}`{}; the keywords are: {}",
            keyword(name),
            did_you_mean(&keyword(name), keywords.iter().map(String::as_str)),
            keywords.join(", ")
        )));
    }
    Ok(())
}

/// `err`'s message with every `--option` of `longs` written as its keyword; its exit class kept.
pub(super) fn in_keywords(err: anyhow::Error, longs: &[String]) -> anyhow::Error {
    let class = if let Some(c) = err.downcast_ref::<Classified>() {
        c.class
    } else if let Some(m) = err.downcast_ref::<MeasureError>() {
        m.exit_class()
    } else {
        return err;
    };
    anyhow::Error::new(Classified {
        class,
        message: respell(&crate::exit::render(&err), longs),
    })
}

/// `text` with each `--long` (a whole option name of `longs`) replaced by its keyword.
fn respell(text: &str, longs: &[String]) -> String {
    let mut out = String::with_capacity(text.len());
    let mut rest = text;
    while let Some(i) = rest.find("--") {
        out.push_str(&rest[..i]);
        let after = &rest[i + 2..];
        let end = after
            .find(|c: char| !(c.is_ascii_alphanumeric() || c == '-'))
            .unwrap_or(after.len());
        let name = &after[..end];
        let mut tail = &after[end..];
        if longs.iter().any(|l| l == name) {
            out.push_str(&keyword(name));
            // clap's value placeholder (`--window <NAME>`) means nothing to a keyword.
            if let Some(placeholder) = tail.strip_prefix(" <").and_then(|t| t.split_once('>')) {
                tail = placeholder.1;
            }
        } else {
            out.push_str(&rest[i..i + 2 + end]);
        }
        rest = tail;
    }
    out.push_str(rest);
    out
}

#[cfg(test)]
mod tests {
    use super::super::ProcessRequest;

    /// The error of processing a short record of zeros with `options` as keywords.
    fn message(options: &[&str]) -> String {
        let mut options: Vec<String> = options.iter().map(|s| s.to_string()).collect();
        if !options.iter().any(|o| o.starts_with("--waveform")) {
            options.push("--waveform=msk-lfm".into());
        }
        let raw = crate::measure::RawIq {
            samples: vec![num_complex::Complex64::new(0.0, 0.0); 64],
            sample_rate_hz: 16e9,
            first_point_s: 0.0,
        };
        let err = ProcessRequest::parse_keywords(&options)
            .and_then(|r| r.samples(raw))
            .expect_err("refused");
        let class = err
            .downcast_ref::<crate::exit::Classified>()
            .map(|c| c.class);
        assert_eq!(class, Some(crate::exit::ExitClass::BadInput), "{err}");
        crate::exit::render(&err)
    }

    #[test]
    fn an_unknown_keyword_is_named_as_given_with_a_did_you_mean() {
        let text = message(&["--windw=hann"]);
        assert!(
            text.starts_with("unknown keyword `windw`; did you mean `window`?"),
            "{text}"
        );
        assert!(text.contains("zero_pad"), "{text}");
        assert!(!text.contains("--"), "{text}");
    }

    #[test]
    fn a_bad_value_names_the_keyword() {
        let text = message(&["--window=hanning"]);
        assert!(text.contains("window"), "{text}");
        assert!(!text.contains("--window"), "{text}");
        // Checked after parsing, when processing: named the same way.
        let text = message(&["--waveform=ofdm", "--zero-pad=0"]);
        assert!(text.contains("zero_pad"), "{text}");
        assert!(!text.contains("--zero-pad"), "{text}");
    }

    #[test]
    fn respelling_keeps_what_is_not_an_option() {
        let longs = vec!["m".to_string(), "min-range".to_string()];
        assert_eq!(
            super::respell("--m 3 and --min-range, not --mx or -- x", &longs),
            "m 3 and min_range, not --mx or -- x"
        );
        assert_eq!(
            super::respell("invalid value 'x' for '--min-range <METRES>'", &longs),
            "invalid value 'x' for 'min_range'"
        );
    }
}
