//! `report.html`: one file, no script, no external resource (plots are inline SVG, the style
//! sheet is inline), well-formed (every element closed) so it opens from disk anywhere.

use super::figures::Figure;
use super::markdown::{
    chain_echoes_table, retries_table, status_line, steps_table, summary_tables, Table,
    CHAIN_ECHOES_NOTE, UNCERTAINTY_NOTE,
};
use super::plots;
use super::summary::Summary;
use crate::campaign::Manifest;
use crate::campaign::Results;
use std::fmt::Write as _;

const STYLE: &str = "body{font-family:sans-serif;margin:2em;max-width:1100px;color:#222}\
table{border-collapse:collapse;margin:1em 0;font-size:13px}\
th,td{border:1px solid #bbb;padding:3px 7px;text-align:left}th{background:#eee}\
figure{margin:1.5em 0}figure svg{max-width:100%;height:auto;border:1px solid #ddd}\
figcaption{font-size:14px;max-width:800px}\
.links figure{margin:0.5em 0 1.5em 0}\
.warning{background:#fff3cd;border-left:4px solid #d39e00;padding:6px 10px}\
#summary{border:2px solid #888;padding:4px 14px;margin:1em 0}#summary table{font-size:14px}\
.verdict{font-size:18px;font-weight:bold;padding:6px 10px}.pass{background:#d1e7dd;color:#0f5132}\
.fail{background:#f8d7da;color:#842029}.none{background:#eee}\
.alarm,.false-target{background:#f8d7da;color:#842029;font-weight:bold}\
figure img{max-width:100%;height:auto;border:1px solid #ddd}";

/// Text for HTML element content and attribute values.
pub(crate) fn escape(s: &str) -> String {
    let mut out = String::with_capacity(s.len());
    for c in s.chars() {
        match c {
            '&' => out.push_str("&amp;"),
            '<' => out.push_str("&lt;"),
            '>' => out.push_str("&gt;"),
            '"' => out.push_str("&quot;"),
            '\'' => out.push_str("&#39;"),
            c => out.push(c),
        }
    }
    out
}

fn table(out: &mut String, t: &Table) {
    let _ = writeln!(out, "<h2>{}</h2>\n<table>", escape(&t.title));
    let _ = write!(out, "<tr>");
    for h in &t.header {
        let _ = write!(out, "<th>{}</th>", escape(h));
    }
    let _ = writeln!(out, "</tr>");
    for (i, r) in t.rows.iter().enumerate() {
        let _ = write!(out, "<tr>");
        for (j, c) in r.iter().enumerate() {
            if t.marks.contains(&(i, j)) {
                let _ = write!(out, "<td class=\"false-target\">⚠ {}</td>", escape(c));
            } else {
                let _ = write!(out, "<td>{}</td>", escape(c));
            }
        }
        let _ = writeln!(out, "</tr>");
    }
    let _ = writeln!(out, "</table>");
}

/// The summary the page opens with.
fn summary_section(out: &mut String, summary: &Summary) {
    let class = match summary.pass {
        Some(true) => "pass",
        Some(false) => "fail",
        None => "none",
    };
    let _ = writeln!(
        out,
        "<section id=\"summary\">\n<h2>Summary</h2>\n<p class=\"verdict {class}\">{}</p>\n<table>",
        escape(&summary.verdict)
    );
    for f in &summary.facts {
        let (class, sign) = if f.alarm {
            (" class=\"alarm\"", "⚠ ")
        } else {
            ("", "")
        };
        let _ = writeln!(
            out,
            "<tr{class}><th>{}</th><td>{sign}{}</td></tr>",
            escape(f.name),
            escape(&f.text)
        );
    }
    let _ = writeln!(out, "</table>\n</section>");
}

/// Standard base64 (RFC 4648, padded), for a PNG inlined as a `data:` URI.
fn base64(bytes: &[u8]) -> String {
    const ABC: &[u8; 64] = b"ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
    let mut out = String::with_capacity(bytes.len().div_ceil(3) * 4);
    for c in bytes.chunks(3) {
        let n = (u32::from(c[0]) << 16)
            | (u32::from(*c.get(1).unwrap_or(&0)) << 8)
            | u32::from(*c.get(2).unwrap_or(&0));
        for k in 0..4 {
            if k <= c.len() {
                out.push(ABC[(n >> (18 - 6 * k) & 63) as usize] as char);
            } else {
                out.push('=');
            }
        }
    }
    out
}

/// The whole page, the summary first, then the tables, then the figures; `links` is the section
/// of every step's link figure (`super::link`).
pub(crate) fn html(
    manifest: &Manifest,
    results: &Results,
    summary: &Summary,
    figures: &[Figure],
    pngs: &[Option<Vec<u8>>],
    links: &str,
) -> String {
    let plan = &manifest.plan;
    let mut out = String::new();
    let _ = writeln!(
        out,
        "<!DOCTYPE html>\n<html lang=\"en\">\n<head>\n<meta charset=\"utf-8\"/>\n\
         <title>Campaign {}</title>\n<style>{STYLE}</style>\n</head>\n<body>",
        escape(&plan.name)
    );
    let _ = writeln!(out, "<h1>Campaign {}</h1>", escape(&plan.name));
    if let Some(d) = &plan.description {
        let _ = writeln!(out, "<p>{}</p>", escape(d));
    }
    summary_section(&mut out, summary);
    let _ = writeln!(out, "<p>{}</p>", escape(&status_line(manifest)));
    for w in manifest.plan.bench.warnings() {
        let _ = writeln!(
            out,
            "<p class=\"warning\"><strong>Warning:</strong> {}</p>",
            escape(&w)
        );
    }
    let _ = writeln!(out, "<p>{}</p>", escape(UNCERTAINTY_NOTE));
    for t in summary_tables(manifest, results) {
        table(&mut out, &t);
    }
    table(&mut out, &steps_table(results));
    if let Some(t) = chain_echoes_table(results) {
        table(&mut out, &t);
        let _ = writeln!(out, "<p>{}</p>", escape(CHAIN_ECHOES_NOTE));
    }
    if let Some(t) = retries_table(manifest) {
        table(&mut out, &t);
    }
    let done = results.steps.len();
    if done < plan.steps.len() {
        let _ = writeln!(
            out,
            "<p>{} of {} steps measured; <code>radbench campaign resume</code> continues the run.</p>",
            done,
            plan.steps.len()
        );
    }
    for (k, f) in figures.iter().enumerate() {
        // A heat map is a bitmap (thousands of cells); every other plot inline SVG. A plot that
        // cannot be drawn says why; the report (and the run) goes on.
        let (class, body) = if f.chart.heat.is_some() {
            let png = pngs.get(k).and_then(Option::as_ref).ok_or("see the log");
            let body = match png {
                Ok(png) => format!(
                    "<img src=\"data:image/png;base64,{}\" alt=\"{}\" width=\"{}\" height=\"{}\"/>",
                    base64(png),
                    escape(&f.chart.title),
                    plots::SIZE.0,
                    plots::SIZE.1
                ),
                Err(e) => format!("<p>This plot could not be drawn: {}</p>", escape(e)),
            };
            ("heatmap", body)
        } else {
            let body = match plots::svg(&f.chart) {
                Ok(svg) => {
                    // Inline: drop an XML prolog if the backend wrote one.
                    let k = svg.find("<svg").unwrap_or(0);
                    svg[k..].trim().to_string()
                }
                Err(e) => format!("<p>This plot could not be drawn: {}</p>", escape(&e)),
            };
            ("plot", body)
        };
        let _ = writeln!(
            out,
            "<figure id=\"{}\" class=\"{class}\">\n<h2>{}</h2>\n{}\n<figcaption>{}</figcaption>\n</figure>",
            f.id,
            escape(&f.chart.title),
            body,
            escape(&f.caption)
        );
    }
    out.push_str(links);
    let _ = writeln!(
        out,
        "<p>Files: <code>manifest.toml</code> (inputs, plan, identities, hashes), \
         <code>results.json</code> (schema: docs/campaign.md), <code>report.md</code>, \
         <code>figures/</code> (the plots as PNG), one folder per step with its capture (SigMF, \
         .trc) and profiles.</p>\n</body>\n</html>"
    );
    out
}

#[cfg(test)]
mod tests {
    #[test]
    fn base64_is_rfc_4648() {
        assert_eq!(super::base64(b""), "");
        assert_eq!(super::base64(b"f"), "Zg==");
        assert_eq!(super::base64(b"fo"), "Zm8=");
        assert_eq!(super::base64(b"foo"), "Zm9v");
        assert_eq!(super::base64(b"foobar"), "Zm9vYmFy");
    }
}
