//! Finds the line of a scene field (`targets[1].amplitude`, `impairments.dc_offset_v[0]`) in the
//! TOML text it was read from, so that a value refused by validation can be pointed at.

use toml_edit::ImDocument;

/// The 1-based line where `field` is written, or where its nearest written parent is; `None`
/// when nothing of the path is in the text (a default value).
pub(super) fn line_of_field(text: &str, field: &str) -> Option<usize> {
    let doc = ImDocument::parse(text).ok()?;
    let mut item = doc.as_item();
    let mut best = None;
    for step in steps(field) {
        let next = match step {
            Step::Key(key) => item.get(key),
            Step::Index(i) => item.get(i),
        };
        let Some(next) = next else { break };
        item = next;
        if let Some(span) = item.span() {
            best = Some(span.start);
        }
    }
    best.map(|offset| text[..offset].matches('\n').count() + 1)
}

enum Step<'a> {
    Key(&'a str),
    Index(usize),
}

/// `a.b[2].c` -> key a, key b, index 2, key c.
fn steps(field: &str) -> Vec<Step<'_>> {
    let mut out = Vec::new();
    for part in field.split('.') {
        let mut pieces = part.split('[');
        if let Some(key) = pieces.next().filter(|k| !k.is_empty()) {
            out.push(Step::Key(key));
        }
        for index in pieces {
            if let Ok(i) = index.trim_end_matches(']').parse() {
                out.push(Step::Index(i));
            }
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fields_are_found_in_tables_arrays_and_inline_forms() {
        let text = "snr_db = 20\n\n[[targets]]\nrange_m = 1.0\n\n[[targets]]\nrange_m = 2.0\n\
                    amplitude = 1e300\n\n[impairments]\ndc_offset_v = [\n  0.0,\n  9.0,\n]\n\
                    leakage = { amplitude = 50.0 }\n";
        assert_eq!(line_of_field(text, "snr_db"), Some(1));
        assert_eq!(line_of_field(text, "targets[1].amplitude"), Some(8));
        assert_eq!(line_of_field(text, "impairments.dc_offset_v[1]"), Some(13));
        assert_eq!(
            line_of_field(text, "impairments.leakage.amplitude"),
            Some(15)
        );
        // Not written: the nearest written parent, or nothing.
        assert_eq!(line_of_field(text, "targets[1].velocity_mps"), Some(6));
        assert_eq!(line_of_field(text, "carrier_hz"), None);
        assert_eq!(line_of_field("not toml [", "snr_db"), None);
    }
}
