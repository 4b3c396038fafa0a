//! `report.md`, and the tables both reports share.

use super::figures::{is_accuracy, thesis_widths, waveform_of, wilson95, Figure};
use super::run_figures::is_single;
use super::summary::Summary;
use crate::campaign::Manifest;
use crate::campaign::{AlgorithmResult, Results};
use crate::physics::C0;
use std::fmt::Write as _;

/// A table: header and rows of cells (plain text).
pub(crate) struct Table {
    pub title: String,
    pub header: Vec<String>,
    pub rows: Vec<Vec<String>>,
    /// Cells (row, column) that are bad news (a false target): drawn marked.
    pub marks: Vec<(usize, usize)>,
}

impl Table {
    fn new(title: impl Into<String>, header: &[&str], rows: Vec<Vec<String>>) -> Self {
        Table {
            title: title.into(),
            header: header.iter().map(|h| h.to_string()).collect(),
            rows,
            marks: Vec::new(),
        }
    }
}

/// The header's facts, one line.
pub(crate) fn status_line(manifest: &Manifest) -> String {
    let plan = &manifest.plan;
    format!(
        "Status: {}{}. Bench: {}. Correction: {}. radbench {}{}.",
        manifest.status.name(),
        manifest
            .reason
            .as_ref()
            .map(|r| format!(" ({r})"))
            .unwrap_or_default(),
        plan.bench.describe(),
        match &manifest.calibration {
            Some(c) => format!(
                "{} with the response calibration {} (measured {}; copy in {})",
                c.mode,
                c.path.display(),
                c.measured_at,
                c.copy.display()
            ),
            None => "none".into(),
        },
        manifest.radbench_version,
        manifest
            .git_commit
            .as_ref()
            .map(|c| format!(" ({c})"))
            .unwrap_or_default()
    )
}

/// One line on what the numbers mean.
pub(crate) const UNCERTAINTY_NOTE: &str =
    "Ranges and errors are those of the coherent average of a \
    step's repetitions, ± the standard deviation of the repetitions' own ranges; width, side-lobe \
    level and SNR are the mean ± standard deviation of the repetitions processed one by one (one \
    repetition: its value alone). BER counts every repetition's bits, with its 95 % Wilson \
    interval.";

fn mm(v: Option<f64>, std: Option<f64>) -> String {
    match v {
        Some(x) => match std {
            Some(s) => format!("{:+.3} ± {:.3}", x * 1e3, s * 1e3),
            None => format!("{:+.3}", x * 1e3),
        },
        None => "-".into(),
    }
}

/// An error cell that says when nominal targets were missed (nothing found within a resolution
/// cell of them): a missed target has no error, and "-" would hide it.
fn with_missed(cell: String, missed: usize) -> String {
    match (missed, cell.as_str()) {
        (0, _) => cell,
        (m, "-") => format!("missed {m}"),
        (m, _) => format!("{cell}, missed {m}"),
    }
}

fn strongest_std(a: &AlgorithmResult) -> Option<f64> {
    a.targets
        .iter()
        .max_by(|x, y| x.level_db.total_cmp(&y.level_db))
        .and_then(|t| t.range_std_m)
}

fn figure(value: Option<f64>, spread: Option<crate::campaign::MeanStd>, digits: usize) -> String {
    match (spread, value) {
        (Some(m), _) => format!("{} (n={})", pm(m.mean, Some(m.std), digits), m.n),
        (None, Some(v)) => pm(v, None, digits),
        (None, None) => "-".into(),
    }
}

fn ber(a: &AlgorithmResult) -> String {
    match &a.payload {
        Some(p) if p.bits > 0 => {
            let (lo, hi) = wilson95(p.bit_errors, p.bits);
            format!(
                "{}/{} = {} [{}, {:.1e}]",
                p.bit_errors,
                p.bits,
                crate::measure::rate(p.ber),
                if lo == 0.0 {
                    "0".into()
                } else {
                    format!("{lo:.1e}")
                },
                hi
            )
        }
        Some(p) => p.error.clone().unwrap_or_else(|| "no bits".into()),
        None => "-".into(),
    }
}

/// EVM rms and 95th percentile, and MER, of the step's data symbols.
fn evm(a: &AlgorithmResult) -> (String, String) {
    match &a.payload {
        Some(p) => (
            match (p.evm_rms_pct, p.evm_p95_pct) {
                (Some(r), Some(q)) => format!("{r:.2} / {q:.2}"),
                _ => "-".into(),
            },
            p.mer_db.map_or("-".into(), |m| format!("{m:.1}")),
        ),
        None => ("-".into(), "-".into()),
    }
}

/// Every step and algorithm.
pub(crate) fn steps_table(results: &Results) -> Table {
    let header = [
        "step",
        "nominal",
        "algorithm",
        "targets (m)",
        "false targets (m)",
        "error (mm)",
        "on grid (mm)",
        "vs truth (mm)",
        "resolved",
        "-3 dB width (cm)",
        "PSL (dB)",
        "SNR (dB)",
        "BER [95 %]",
        "EVM rms / 95 % (%)",
        "MER (dB)",
    ];
    let mut rows = Vec::new();
    let mut marks = Vec::new();
    for s in &results.steps {
        for (name, a) in &s.algorithms {
            let false_ones = crate::campaign::results::false_targets(s, a);
            if !false_ones.is_empty() {
                marks.push((rows.len(), FALSE_TARGETS_COLUMN));
            }
            let targets: Vec<String> = a
                .targets
                .iter()
                .map(|t| match t.range_std_m {
                    Some(sd) => format!("{:.4} ± {:.4}", t.range_m, sd),
                    None => format!("{:.4}", t.range_m),
                })
                .collect();
            let sp = a.spread.as_ref();
            rows.push(vec![
                s.index.to_string(),
                s.nominal.describe(),
                name.clone(),
                if targets.is_empty() {
                    "none".into()
                } else {
                    targets.join(", ")
                },
                if false_ones.is_empty() {
                    "-".into()
                } else {
                    let r: Vec<String> = false_ones.iter().map(|r| format!("{r:.4}")).collect();
                    format!("FALSE TARGET {}", r.join(", "))
                },
                with_missed(mm(a.error_m, strongest_std(a)), a.missed),
                with_missed(mm(a.error_on_grid_m, None), a.missed),
                mm(a.truth_error_m, None),
                a.resolved
                    .map_or("-", |r| if r { "yes" } else { "no" })
                    .into(),
                figure(a.width_3db_cm, sp.and_then(|f| f.width_3db_cm), 2),
                figure(a.sidelobe_db, sp.and_then(|f| f.sidelobe_db), 2),
                figure(a.snr_db, sp.and_then(|f| f.snr_db), 1),
                ber(a),
                evm(a).0,
                evm(a).1,
            ]);
        }
    }
    let mut t = Table::new("Steps", &header, rows);
    t.marks = marks;
    t
}

/// The steps table's column of false targets (marked where a step has one).
const FALSE_TARGETS_COLUMN: usize = 4;

/// The summary tables of the run's kinds (accuracy bounds, the thesis' widths beside).
pub(crate) fn summary_tables(manifest: &Manifest, results: &Results) -> Vec<Table> {
    let mut out = Vec::new();
    let acc: Vec<_> = results.steps.iter().filter(|s| is_accuracy(s)).collect();
    if let Some(fs) = acc
        .first()
        .and_then(|s| waveform_of(manifest, s))
        .map(|w| w.sample_rate_hz())
    {
        let mut names: Vec<&String> = acc.iter().flat_map(|s| s.algorithms.keys()).collect();
        names.dedup();
        let mut rows = Vec::new();
        for name in names {
            let worst = |f: fn(&AlgorithmResult) -> Option<f64>| {
                acc.iter()
                    .filter_map(|s| s.algorithms.get(name).and_then(f))
                    .map(f64::abs)
                    .reduce(f64::max)
            };
            let within = |w: Option<f64>, b: f64| match w {
                Some(w) if w <= b => "yes",
                Some(_) => "no",
                None => "-",
            };
            let (i, g) = (worst(|a| a.error_m), worst(|a| a.error_on_grid_m));
            let half = C0 / (2.0 * fs);
            let quarter = C0 / (4.0 * fs);
            // A step that missed its target is not within any bound.
            let missed: usize = acc
                .iter()
                .filter_map(|s| s.algorithms.get(name))
                .map(|a| a.missed)
                .sum();
            let within = |w: Option<f64>, b: f64| {
                if missed > 0 {
                    format!("no (missed {missed})")
                } else {
                    within(w, b).to_string()
                }
            };
            rows.push(vec![
                name.clone(),
                with_missed(i.map_or("-".into(), |v| format!("{:.3}", v * 1e3)), missed),
                with_missed(g.map_or("-".into(), |v| format!("{:.3}", v * 1e3)), missed),
                format!("{:.3}", half * 1e3),
                within(g, half),
                format!("{:.3}", quarter * 1e3),
                within(g, quarter),
            ]);
        }
        out.push(Table {
            marks: Vec::new(),
            title: "Accuracy: largest |error| over the steps (thesis 4.4.2, Fig. 4.13)".into(),
            header: [
                "algorithm",
                "interpolated (mm)",
                "on the grid (mm)",
                "c0/(2 fs) (mm)",
                "grid within",
                "c0/(4 fs) (mm)",
                "grid within",
            ]
            .iter()
            .map(|h| h.to_string())
            .collect(),
            rows,
        });
    }
    let single: Vec<_> = results.steps.iter().filter(|s| is_single(s)).collect();
    if !single.is_empty() {
        let mut rows = Vec::new();
        for s in &single {
            let thesis = waveform_of(manifest, s)
                .filter(|_| s.nominal.bandwidth_hz == 1e9)
                .and_then(|w| thesis_widths(w.kind()));
            for (name, a) in &s.algorithms {
                if a.width_3db_cm.is_none() && a.sidelobe_db.is_none() {
                    continue;
                }
                let sp = a.spread.as_ref();
                let t = |f: fn(&super::figures::ThesisWidths) -> String| {
                    thesis.as_ref().map_or("-".into(), f)
                };
                rows.push(vec![
                    s.index.to_string(),
                    name.clone(),
                    figure(a.width_3db_cm, sp.and_then(|f| f.width_3db_cm), 2),
                    t(|t| format!("{} ({})", t.simulation.0, t.simulation.2)),
                    t(|t| format!("{} ({})", t.lab.0, t.lab.2)),
                    figure(a.sidelobe_db, sp.and_then(|f| f.sidelobe_db), 2),
                    t(|t| format!("{} ({})", t.simulation.1, t.simulation.2)),
                    t(|t| format!("{} ({})", t.lab.1, t.lab.2)),
                ]);
            }
        }
        out.push(Table {
            marks: Vec::new(),
            title: "One target: -3 dB width and peak side-lobe level beside the thesis".into(),
            header: [
                "step",
                "algorithm",
                "width (cm)",
                "thesis simulation",
                "thesis lab",
                "PSL (dB)",
                "thesis simulation",
                "thesis lab",
            ]
            .iter()
            .map(|h| h.to_string())
            .collect(),
            rows,
        });
    }
    out
}

/// Under the chain echoes' table.
pub(crate) const CHAIN_ECHOES_NOTE: &str = "Each of these detections lies where the response \
calibration measured an echo behind every path (an IF cable's, a connector's), behind a stronger \
target and no stronger than that echo: it is taken for the chain's, listed here and not among \
the targets (each step's summary.json lists it in `chain_echoes`). A real target there would be \
stronger than the echo; check the scene if one is expected.";

/// Every detection a step's processing took for the chain's echo of a stronger target (none:
/// no table): the calibration's warning, kept where the run's reader looks.
pub(crate) fn chain_echoes_table(results: &Results) -> Option<Table> {
    let rows: Vec<Vec<String>> = results
        .steps
        .iter()
        .flat_map(|s| {
            s.algorithms.iter().flat_map(move |(name, a)| {
                a.chain_echoes.iter().map(move |e| {
                    vec![
                        s.index.to_string(),
                        name.clone(),
                        format!("{:.4}", e.range_m),
                        format!("{:.1}", e.level_db),
                        format!("{:.4}", e.of_range_m),
                        format!("{:.1} ns, {:.1} dB", e.echo_delay_ns, e.echo_level_db),
                    ]
                })
            })
        })
        .collect();
    if rows.is_empty() {
        return None;
    }
    Some(Table {
        marks: Vec::new(),
        title: "Chain echoes (not targets)".into(),
        header: [
            "step",
            "algorithm",
            "echo at (m)",
            "level (dB)",
            "behind the target at (m)",
            "the calibration's chain echo",
        ]
        .iter()
        .map(|h| h.to_string())
        .collect(),
        rows,
    })
}

/// Every retry of a step after a transient fault (none: no table).
pub(crate) fn retries_table(manifest: &Manifest) -> Option<Table> {
    if manifest.retries.is_empty() {
        return None;
    }
    Some(Table {
        marks: Vec::new(),
        title: "Retries".into(),
        header: ["step", "retry", "instrument", "fault", "at", "wait (s)"]
            .iter()
            .map(|h| h.to_string())
            .collect(),
        rows: manifest
            .retries
            .iter()
            .map(|r| {
                vec![
                    r.step.to_string(),
                    r.attempt.to_string(),
                    r.instrument.clone(),
                    r.fault.replace('|', "\\|").replace('\n', " "),
                    r.at.clone(),
                    format!("{:.1}", r.wait_s),
                ]
            })
            .collect(),
    })
}

fn md_table(out: &mut String, t: &Table) {
    let _ = writeln!(out, "## {}\n", t.title);
    let _ = writeln!(out, "| {} |", t.header.join(" | "));
    let _ = writeln!(out, "|{}", "---|".repeat(t.header.len()));
    for (i, r) in t.rows.iter().enumerate() {
        let cells: Vec<String> = r
            .iter()
            .enumerate()
            .map(|(j, c)| {
                if t.marks.contains(&(i, j)) {
                    format!("**⚠ {c}**")
                } else {
                    c.clone()
                }
            })
            .collect();
        let _ = writeln!(out, "| {} |", cells.join(" | "));
    }
    let _ = writeln!(out);
}

/// The summary the report opens with.
fn md_summary(out: &mut String, summary: &Summary) {
    let _ = writeln!(out, "## Summary\n");
    let _ = writeln!(out, "**{}**\n", summary.verdict);
    let _ = writeln!(out, "| | |\n|---|---|");
    for f in &summary.facts {
        let text = f.text.replace('|', "\\|").replace('\n', " ");
        if f.alarm {
            let _ = writeln!(out, "| **{}** | **⚠ {text}** |", f.name);
        } else {
            let _ = writeln!(out, "| {} | {text} |", f.name);
        }
    }
    let _ = writeln!(out);
}

/// The whole `report.md`: the summary, the tables, then the figures (`images[k]`: figure k's
/// PNG relative to the run folder, `None` when it could not be drawn).
pub(crate) fn markdown(
    manifest: &Manifest,
    results: &Results,
    summary: &Summary,
    figures: &[Figure],
    images: &[Option<String>],
) -> String {
    let plan = &manifest.plan;
    let mut out = String::new();
    let _ = writeln!(out, "# Campaign {}\n", plan.name);
    if let Some(d) = &plan.description {
        let _ = writeln!(out, "{d}\n");
    }
    md_summary(&mut out, summary);
    let _ = writeln!(out, "{}\n", status_line(manifest));
    for w in plan.bench.warnings() {
        let _ = writeln!(out, "**Warning:** {w}\n");
    }
    let _ = writeln!(out, "{UNCERTAINTY_NOTE}\n");
    for t in summary_tables(manifest, results) {
        md_table(&mut out, &t);
    }
    md_table(&mut out, &steps_table(results));
    if let Some(t) = chain_echoes_table(results) {
        md_table(&mut out, &t);
        let _ = writeln!(out, "{CHAIN_ECHOES_NOTE}\n");
    }
    if let Some(t) = retries_table(manifest) {
        md_table(&mut out, &t);
    }
    let done = results.steps.len();
    if done < plan.steps.len() {
        let _ = writeln!(
            out,
            "{} of {} steps measured; `radbench campaign resume` continues the run.\n",
            done,
            plan.steps.len()
        );
    }
    if !figures.is_empty() {
        let _ = writeln!(out, "## Figures\n");
        for (k, f) in figures.iter().enumerate() {
            let _ = writeln!(out, "### {}\n", f.chart.title);
            match images.get(k).and_then(Option::as_ref) {
                Some(path) => {
                    let _ = writeln!(
                        out,
                        "![{}]({path})\n",
                        f.chart.title.replace(['[', ']'], "")
                    );
                }
                None => {
                    let _ = writeln!(out, "(This plot could not be drawn.)\n");
                }
            }
            let _ = writeln!(out, "{}\n", f.caption);
        }
    }
    let _ = writeln!(
        out,
        "Files: `manifest.toml` (inputs, plan, identities, hashes), `results.json`, \
         `report.html` (this report, its plots inline), `figures/` (these plots as PNG), one \
         folder per step with its capture (SigMF, .trc) and profiles."
    );
    out
}

/// `x ± s` with `digits` decimals at least, more (up to 6) so the deviation shows two significant
/// digits; or the value alone.
pub(crate) fn pm(mean: f64, std: Option<f64>, digits: usize) -> String {
    match std {
        Some(s) => {
            let d = if s > 0.0 && s.is_finite() {
                ((1.0 - s.log10().floor()).max(0.0) as usize).clamp(digits, 6)
            } else {
                digits
            };
            format!("{mean:.d$} ± {s:.d$}")
        }
        None => format!("{mean:.digits$}"),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A step whose processing took a detection for the chain's echo: the report lists it, with
    /// the target it follows and the calibration's echo; a run without any has no such table.
    #[test]
    fn the_chain_echoes_a_step_flagged_are_in_their_own_table() {
        let step = |echoes: serde_json::Value| {
            serde_json::json!({
                "index": 2,
                "nominal": {"targets": [{"range_m": 2.0}], "bandwidth_hz": 1e9},
                "repetitions": 1,
                "algorithms": {"correlation": {
                    "targets": [{"range_m": 2.0001, "range_std_m": null, "level_db": -6.0}],
                    "width_3db_cm": 13.3, "sidelobe_db": -13.3, "snr_db": null,
                    "error_m": 1e-4, "error_on_grid_m": null, "truth_error_m": null,
                    "truth_error_on_grid_m": null, "missed": 0, "resolved": null,
                    "payload": null, "chain_echoes": echoes}}
            })
        };
        let results = |echoes| -> Results {
            serde_json::from_value(serde_json::json!({"steps": [step(echoes)]})).unwrap()
        };
        let flagged = results(serde_json::json!([{"range_m": 4.2487, "level_db": -36.5,
            "of_range_m": 2.0001, "echo_delay_ns": 15.0, "echo_level_db": -30.2}]));
        let t = chain_echoes_table(&flagged).expect("a table");
        assert_eq!(
            t.rows,
            vec![vec![
                "2".to_string(),
                "correlation".into(),
                "4.2487".into(),
                "-36.5".into(),
                "2.0001".into(),
                "15.0 ns, -30.2 dB".into(),
            ]]
        );
        assert!(chain_echoes_table(&results(serde_json::json!([]))).is_none());
        // Written before chain echoes were recorded: read as none.
        let mut old = step(serde_json::json!([]));
        old["algorithms"]["correlation"]
            .as_object_mut()
            .unwrap()
            .remove("chain_echoes");
        let old: Results = serde_json::from_value(serde_json::json!({"steps": [old]})).unwrap();
        assert!(old.steps[0].algorithms["correlation"]
            .chain_echoes
            .is_empty());
    }
}
