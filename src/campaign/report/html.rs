//! `report.html`: one file, no script, no external resource (plots are inline SVG, the style
//! sheet is inline), well-formed (every element closed) so it opens from disk anywhere.

use super::figures::Figure;
use super::markdown::{
    chain_echoes_table, retries_table, status_line, steps_table, summary_tables, Table,
    CHAIN_ECHOES_NOTE, UNCERTAINTY_NOTE,
};
use super::plots;
use crate::campaign::Manifest;
use crate::campaign::Results;
use std::fmt::Write as _;

const STYLE: &str = "body{font-family:sans-serif;margin:2em;max-width:1100px;color:#222}\
table{border-collapse:collapse;margin:1em 0;font-size:13px}\
th,td{border:1px solid #bbb;padding:3px 7px;text-align:left}th{background:#eee}\
figure{margin:1.5em 0}figure svg{max-width:100%;height:auto;border:1px solid #ddd}\
figcaption{font-size:14px;max-width:800px}\
.links{display:grid;grid-template-columns:1fr 1fr;gap:0 12px}.links figure{margin:0.5em 0}\
.links figcaption{font-size:12px}\
.warning{background:#fff3cd;border-left:4px solid #d39e00;padding:6px 10px}";

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
    for r in &t.rows {
        let _ = write!(out, "<tr>");
        for c in r {
            let _ = write!(out, "<td>{}</td>", escape(c));
        }
        let _ = writeln!(out, "</tr>");
    }
    let _ = writeln!(out, "</table>");
}

/// The whole page; `links` is the section of every step's link figure (`super::link`).
pub(crate) fn html(
    manifest: &Manifest,
    results: &Results,
    figures: &[Figure],
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
    let _ = writeln!(out, "<p>{}</p>", escape(&status_line(manifest)));
    for w in manifest.plan.bench.warnings() {
        let _ = writeln!(
            out,
            "<p class=\"warning\"><strong>Warning:</strong> {}</p>",
            escape(&w)
        );
    }
    let _ = writeln!(out, "<p>{}</p>", escape(UNCERTAINTY_NOTE));
    for f in figures {
        // A plot that cannot be drawn says why; the report (and the run) goes on.
        let body = match plots::svg(&f.chart) {
            Ok(svg) => {
                // Inline: drop an XML prolog if the backend wrote one.
                let k = svg.find("<svg").unwrap_or(0);
                svg[k..].trim().to_string()
            }
            Err(e) => format!("<p>This plot could not be drawn: {}</p>", escape(&e)),
        };
        let _ = writeln!(
            out,
            "<figure id=\"{}\" class=\"plot\">\n<h2>{}</h2>\n{}\n<figcaption>{}</figcaption>\n</figure>",
            f.id,
            escape(&f.chart.title),
            body,
            escape(&f.caption)
        );
    }
    out.push_str(links);
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
    let _ = writeln!(
        out,
        "<p>Files: <code>manifest.toml</code> (inputs, plan, identities, hashes), \
         <code>results.json</code> (schema: docs/campaign.md), <code>report.md</code>, one folder \
         per step with its capture (SigMF, .trc) and profiles.</p>\n</body>\n</html>"
    );
    out
}
