//! The link of every step in `report.html`: small multiples of the link figure each step's
//! capture drew (`step-NNN/link.svg`: for OFDM the constellation of the decoded data symbols and
//! the per-subcarrier channel estimate, magnitude and phase; for MSK-LFM the constellation of its
//! (I, Q) symbol pairs and the phase trajectory against the one sent), each captioned with the
//! step's swept value, its EVM (rms and 95th percentile) and MER from `results.json`. Read from
//! the run folder, so `campaign report` draws it again byte for byte.

use super::html::escape;
use crate::campaign::{Results, StepResult};
use std::fmt::Write as _;
use std::path::Path;

/// Steps shown at most: the first, the last and evenly between (every step's figure stays in its
/// folder, and the report names the ones not shown).
pub(crate) const MAX_SHOWN: usize = 12;

/// One step's link figure.
pub(crate) struct StepLink {
    pub index: usize,
    /// The inline SVG (no XML prolog).
    pub svg: String,
    pub caption: String,
}

/// The step's swept value, as the waterfall labels it.
fn value(s: &StepResult) -> String {
    match (&s.nominal.parameter, s.nominal.value) {
        (Some(p), Some(v)) => format!("{p} {}", (v * 1e6).round() / 1e6),
        _ => s.nominal.describe(),
    }
}

fn caption(s: &StepResult) -> String {
    let p = s.algorithms.values().find_map(|a| a.payload.as_ref());
    let mut text = format!("step {}: {}", s.index, value(s));
    if let Some(p) = p {
        let _ = write!(text, "; {} bit errors in {}", p.bit_errors, p.bits);
        match (p.evm_rms_pct, p.evm_p95_pct) {
            (Some(rms), Some(p95)) => {
                let _ = write!(
                    text,
                    "; EVM {rms:.2} % rms, {p95:.2} % at the 95th percentile"
                );
            }
            (Some(rms), None) => {
                let _ = write!(text, "; EVM {rms:.2} % rms");
            }
            _ => {}
        }
        if let Some(m) = p.mer_db {
            let _ = write!(text, "; MER {m:.1} dB");
        }
    }
    text
}

/// The steps whose folder holds a `link.svg`, in order; `(shown, not shown)`: at most
/// [`MAX_SHOWN`] shown, the first and the last among them.
pub(crate) fn step_links(dir: &Path, results: &Results) -> (Vec<StepLink>, Vec<usize>) {
    let with: Vec<(&StepResult, String)> = results
        .steps
        .iter()
        .filter_map(|s| {
            let path = dir.join(format!("step-{:03}", s.index)).join("link.svg");
            let text = std::fs::read_to_string(path).ok()?;
            let k = text.find("<svg")?;
            Some((s, text[k..].trim().to_string()))
        })
        .collect();
    let n = with.len();
    let picked: Vec<usize> = if n <= MAX_SHOWN {
        (0..n).collect()
    } else {
        let mut p: Vec<usize> = (0..MAX_SHOWN)
            .map(|k| (k as f64 * (n - 1) as f64 / (MAX_SHOWN - 1) as f64).round() as usize)
            .collect();
        p.dedup();
        p
    };
    let mut shown = Vec::new();
    let mut hidden = Vec::new();
    for (k, (s, svg)) in with.into_iter().enumerate() {
        if picked.contains(&k) {
            shown.push(StepLink {
                index: s.index,
                svg,
                caption: caption(s),
            });
        } else {
            hidden.push(s.index);
        }
    }
    (shown, hidden)
}

/// The section of `report.html` (empty when no step decoded data).
pub(crate) fn section(dir: &Path, results: &Results) -> String {
    let (shown, hidden) = step_links(dir, results);
    if shown.is_empty() {
        return String::new();
    }
    let mut out = String::from(
        "<section id=\"link-steps\">\n<h2>The link of every step</h2>\n<p>Each step's decoded \
         data as its capture drew it (the step folder's <code>link.svg</code>): OFDM, the \
         constellation of the data symbols (equalised, against the ideal points) and the \
         per-subcarrier channel estimate (magnitude and phase); MSK-LFM, the constellation of its \
         (I, Q) symbol pairs and the phase trajectory against the one sent. EVM and MER as in \
         the steps table.</p>\n<div class=\"links\">\n",
    );
    for l in &shown {
        let _ = writeln!(
            out,
            "<figure id=\"link-step-{:03}\" class=\"link\">\n{}\n<figcaption>{}</figcaption>\n</figure>",
            l.index,
            l.svg,
            escape(&l.caption)
        );
    }
    out.push_str("</div>\n");
    if !hidden.is_empty() {
        let list: Vec<String> = hidden.iter().map(usize::to_string).collect();
        let _ = writeln!(
            out,
            "<p>{} steps shown of {}; the others' figures are in their step folders (steps {}).</p>",
            shown.len(),
            shown.len() + hidden.len(),
            list.join(", ")
        );
    }
    out.push_str("</section>\n");
    out
}
