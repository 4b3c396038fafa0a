//! `radbench process`'s options as keywords (the Python package's `process(window="hann")`):
//! the processing choices through serde ([`ProcessingChoices`], the type the command line and
//! a campaign's `[processing]` use), the command's own options (the waveform of a capture
//! radbench did not make, the background, ...) through its parser; errors name the keyword
//! (`window`), not the command line's option (`--window`), with a did-you-mean for an unknown
//! one.

use crate::exit::{bad_input, did_you_mean, Classified, Classify};
use crate::measure::{MeasureError, ModelOrderChoice, ProcessingChoices};
use serde_json::{Map, Value};

/// A command-line parse error on one line: what is wrong and what is allowed (clap's possible
/// values and tips), without its usage and `--help` lines.
pub(super) fn parse_error(e: &clap::Error) -> anyhow::Error {
    let text = e.to_string();
    let parts: Vec<&str> = text
        .lines()
        .map(str::trim)
        .filter(|l| !l.is_empty() && !l.starts_with("Usage:") && !l.starts_with("For more"))
        .map(|l| l.trim_start_matches("error: "))
        .collect();
    if parts.is_empty() {
        return bad_input("invalid options");
    }
    bad_input(parts.join("; "))
}

/// Keywords of the command line's flags that choose the off state, as the choice they make.
const FLAG_KEYWORDS: [(&str, &str); 2] = [
    ("forward_only", "forward_backward"),
    ("no_interpolation", "interpolate"),
];

/// A JSON object of keywords split into the processing choices (deserialized, a bad value
/// named by its keyword) and the command's own options as its command-line text (`None` and
/// `false` left out, `true` a flag).
pub(super) fn split(keywords: &str) -> anyhow::Result<(ProcessingChoices, Vec<String>)> {
    let map: Map<String, Value> = serde_json::from_str(keywords)
        .map_err(|e| bad_input(format!("keywords: not a JSON object of options: {e}")))?;
    let mut choices = Map::new();
    let mut own = Vec::new();
    for (key, value) in map {
        if value.is_null() {
            continue;
        }
        if let Some((_, choice)) = FLAG_KEYWORDS.iter().find(|(k, _)| *k == key) {
            if value.as_bool() == Some(true) {
                choices.insert(choice.to_string(), Value::Bool(false));
            }
            continue;
        }
        if ProcessingChoices::KEYS.contains(&key.as_str()) {
            // One at a time first: a refused value is named by its keyword.
            let one = Map::from_iter([(key.clone(), value.clone())]);
            if let Err(e) = serde_json::from_value::<ProcessingChoices>(Value::Object(one)) {
                return Err(bad_input(format!("{key}: {e}")));
            }
            choices.insert(key, value);
            continue;
        }
        match value {
            Value::Bool(false) => {}
            Value::Bool(true) => own.push(format!("--{}", key.replace('_', "-"))),
            Value::String(s) => own.push(format!("--{}={s}", key.replace('_', "-"))),
            other => own.push(format!("--{}={other}", key.replace('_', "-"))),
        }
    }
    let choices: ProcessingChoices =
        serde_json::from_value(Value::Object(choices)).map_err(|e| bad_input(e.to_string()))?;
    if !choices.algorithms.is_empty() {
        return Err(bad_input(
            "algorithms: a campaign's list; processing in memory takes one `algorithm`",
        ));
    }
    if let Some(ModelOrderChoice::Named(_)) = choices.music_p {
        return Err(bad_input(
            "p: \"targets\" counts a campaign step's targets; give a number of targets (or none: \
             estimated with MDL)",
        ));
    }
    Ok((choices, own))
}

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

    /// The error of processing a short record of zeros with `keywords` (a JSON object).
    fn json_message(keywords: &str) -> String {
        let raw = crate::measure::RawIq {
            samples: vec![num_complex::Complex64::new(0.0, 0.0); 64],
            sample_rate_hz: 16e9,
            first_point_s: 0.0,
        };
        let err = ProcessRequest::from_keywords(keywords)
            .and_then(|r| r.samples(raw))
            .expect_err("refused");
        crate::exit::render(&err)
    }

    #[test]
    fn keywords_as_json_make_the_command_lines_choices() {
        let request = ProcessRequest::from_keywords(
            r#"{"waveform":"ofdm","algorithm":"music","m":32,"p":2,"window":"hann",
                "forward_only":true,"no_interpolation":false,"min_range":0.3,"seed":3,
                "zero_pad":null}"#,
        )
        .unwrap();
        let cli = ProcessRequest::parse(
            &[
                "--waveform=ofdm",
                "--algorithm=music",
                "--m=32",
                "--p=2",
                "--window=hann",
                "--forward-only",
                "--min-range=0.3",
                "--seed=3",
            ]
            .map(String::from),
        )
        .unwrap();
        assert_eq!(request.args.choices, cli.args.choices);
        assert_eq!(request.args.seed, Some(3));
        assert_eq!(
            format!("{:?}", request.overrides),
            format!("{:?}", cli.overrides)
        );
    }

    #[test]
    fn a_json_keyword_is_named_as_given() {
        let text = json_message(r#"{"waveform":"msk-lfm","window":"hanning"}"#);
        assert!(text.starts_with("window: "), "{text}");
        assert!(text.contains("hann"), "{text}");
        let text = json_message(r#"{"waveform":"msk-lfm","windw":"hann"}"#);
        assert!(
            text.starts_with("unknown keyword `windw`; did you mean `window`?"),
            "{text}"
        );
        let text = json_message(r#"{"waveform":"msk-lfm","p":"targets"}"#);
        assert!(text.starts_with("p: \"targets\""), "{text}");
        let text = json_message(r#"{"waveform":"ofdm","zero_pad":0}"#);
        assert!(text.contains("zero_pad") && !text.contains("--"), "{text}");
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
