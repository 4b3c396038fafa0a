//! The thesis' lab chapter for the terminal (`radbench campaign thesis-lab`): a table when it
//! fits [`WIDTH`] columns, else one block per row; the notes under it wrapped to the same width.

use super::builtin::{LabRow, LAB_REFERENCE_M};
use std::fmt::Write as _;

/// The widest line printed: a terminal of 100 columns shows every line whole.
pub(crate) const WIDTH: usize = 100;

/// The rows as a table, or as a list when the table would be wider than `WIDTH` (100 columns),
/// and the notes on how to read them.
pub fn lab_table(rows: &[LabRow]) -> String {
    let table = columns(rows);
    let mut out = if table.lines().all(|l| l.chars().count() <= WIDTH) {
        table
    } else {
        list(rows)
    };
    let chain = chain(rows);
    let agree = rows.iter().filter(|r| r.agrees).count();
    out += &wrap(
        "",
        &format!(
            "{agree} of {} rows agree on the {chain} chain. The mock lab is not the thesis' \
             room: where they differ, the reason names the physical effect.",
            rows.len()
        ),
        "",
    );
    if with_rx(rows) {
        out += &wrap(
            "",
            &format!(
                "agree judges the uncorrected {chain} column against the thesis' lab. The rx \
                 column is the same chain with the receive correction, both with the AWG's codes \
                 pre-distorted and the receiver's DC and I/Q corrected; the same calibrations for \
                 both (radbench calibrate response, measured in-process on one pillar at \
                 {LAB_REFERENCE_M} m, once with the 1 GHz chirp for the MSK-LFM rows and once \
                 with OFDM for the OFDM rows; beyond the band it was measured on, as for the \
                 2 GHz chirp's upper half, a table holds its edge values)."
            ),
            "",
        );
    }
    out
}

fn chain(rows: &[LabRow]) -> &str {
    rows.first().map_or("ideal", |r| r.chain.as_str())
}

fn with_rx(rows: &[LabRow]) -> bool {
    rows.iter().any(|r| r.radbench_rx.is_some())
}

/// The column heads and each row's cells, in the table's order (the rx and both columns only
/// when some row has them).
fn cells(rows: &[LabRow]) -> (Vec<String>, Vec<Vec<String>>) {
    let chain = chain(rows);
    let rx = with_rx(rows);
    let mut head: Vec<String> = ["section", "scenario", "thesis (lab)", "radbench (ideal)"]
        .map(String::from)
        .into();
    head.push(format!("radbench ({chain})"));
    if rx {
        head.push(format!("radbench ({chain}, rx)"));
        head.push(format!("radbench ({chain}, both)"));
    }
    head.extend(["agree", "reason"].map(String::from));
    let body = rows
        .iter()
        .map(|r| {
            let mut c = vec![
                r.section.to_string(),
                r.scenario.clone(),
                r.thesis.clone(),
                r.radbench_ideal.clone(),
                r.radbench.clone(),
            ];
            if rx {
                c.push(r.radbench_rx.clone().unwrap_or_else(|| "-".into()));
                c.push(r.radbench_both.clone().unwrap_or_else(|| "-".into()));
            }
            c.push(if r.agrees { "yes" } else { "no" }.into());
            c.push(r.reason.clone().unwrap_or_default());
            c
        })
        .collect();
    (head, body)
}

/// One line per row, columns padded to their widest cell (the last, the reason, not padded).
fn columns(rows: &[LabRow]) -> String {
    let (head, body) = cells(rows);
    let widths: Vec<usize> = (0..head.len())
        .map(|k| {
            body.iter()
                .map(|c| c[k].chars().count())
                .chain([head[k].chars().count()])
                .max()
                .unwrap_or(0)
        })
        .collect();
    let line = |c: &[String]| {
        let last = c.len() - 1;
        let mut text: String = c[..last]
            .iter()
            .zip(&widths)
            .map(|(cell, w)| format!("{cell:<w$} "))
            .collect();
        text += &c[last];
        text.trim_end().to_string() + "\n"
    };
    let mut out = line(&head);
    for c in &body {
        out += &line(c);
    }
    out
}

/// One block per row: its section and scenario, then each figure on a line of its own, the
/// reason wrapped under it.
fn list(rows: &[LabRow]) -> String {
    let (head, body) = cells(rows);
    let label = head[2..].iter().map(|h| h.len()).max().unwrap_or(0);
    let mut out = String::new();
    for c in &body {
        let _ = writeln!(out, "{} {}", c[0], c[1]);
        for (h, cell) in head[2..].iter().zip(&c[2..]) {
            if cell.is_empty() {
                continue;
            }
            let indent = " ".repeat(label + 4);
            out += &wrap(&format!("  {h:<label$}  "), cell, &indent);
        }
    }
    out
}

/// `prefix` and `text` broken at spaces into lines of at most [`WIDTH`] characters, every line
/// after the first starting with `indent` (a word longer than a line stays whole).
fn wrap(prefix: &str, text: &str, indent: &str) -> String {
    let mut out = String::new();
    let mut line = prefix.to_string();
    let mut words = 0;
    for word in text.split_whitespace() {
        if words > 0 && line.chars().count() + 1 + word.chars().count() > WIDTH {
            out += &line;
            out.push('\n');
            line = indent.to_string();
            words = 0;
        }
        if words > 0 {
            line.push(' ');
        }
        line += word;
        words += 1;
    }
    out += line.trim_end();
    out.push('\n');
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::path::PathBuf;

    fn row(scenario: &str, reason: Option<&str>, rx: bool) -> LabRow {
        LabRow {
            section: "4.3.2",
            scenario: scenario.into(),
            thesis: "13.3 cm".into(),
            radbench_ideal: "13.26 ± 0.01 cm".into(),
            radbench: "13.41 ± 0.02 cm".into(),
            radbench_rx: rx.then(|| "13.28 ± 0.01 cm".into()),
            radbench_both: rx.then(|| "13.27 ± 0.01 cm".into()),
            chain: "thesis-lab".into(),
            agrees: true,
            reason: reason.map(String::from),
            dir: PathBuf::new(),
            window_psl_db: None,
        }
    }

    #[test]
    fn a_narrow_table_stays_a_table() {
        let text = lab_table(&[row("width, 1 GHz", None, false)]);
        assert!(text.starts_with("section scenario"), "{text}");
        assert!(text.lines().all(|l| l.chars().count() <= WIDTH), "{text}");
    }

    #[test]
    fn a_wide_table_becomes_a_list_within_100_columns() {
        let reason = "the thesis' room has reflections off the table and the walls that widen \
                      the main lobe; the mock lab's chain has none of them";
        let rows = [
            row("range resolution of the 1 GHz chirp", Some(reason), true),
            row("side-lobe level, OFDM", None, true),
        ];
        // As a table this would be far wider than a terminal.
        assert!(columns(&rows).lines().any(|l| l.chars().count() > WIDTH));
        let text = lab_table(&rows);
        for l in text.lines() {
            assert!(
                l.chars().count() <= WIDTH,
                "{} columns: {l}",
                l.chars().count()
            );
        }
        assert!(
            text.starts_with("4.3.2 range resolution of the 1 GHz chirp\n"),
            "{text}"
        );
        assert!(
            text.contains("  radbench (thesis-lab, rx)    13.28 ± 0.01 cm\n"),
            "{text}"
        );
        assert!(text.contains("  agree "), "{text}");
        assert!(text.contains("the walls that\n"), "{text}");
        assert!(text.contains("2 of 2 rows agree"), "{text}");
    }

    #[test]
    fn wrapping_indents_the_lines_after_the_first() {
        let text = wrap("", &"word ".repeat(40), "    ");
        let lines: Vec<&str> = text.lines().collect();
        assert!(lines.len() > 1);
        assert!(lines.iter().all(|l| l.len() <= WIDTH));
        assert!(lines[1].starts_with("    word"));
    }
}
