//! `radbench runs`: the run catalog (docs/catalog.md): index folders into it, list, show, query,
//! captures, and a metric's trend over time (table and plot).

use radbench::runs_db::{self, RunFilter};
use serde::Serialize;
use std::path::{Path, PathBuf};

#[derive(Debug, clap::Args)]
pub struct Args {
    /// The catalog file (default runs/catalog.sqlite, the folder radbench writes runs in).
    #[arg(long, global = true, value_name = "FILE")]
    pub catalog: Option<PathBuf>,
    #[command(subcommand)]
    pub command: Command,
}

#[derive(Debug, clap::Subcommand)]
pub enum Command {
    /// Build or update the catalog from run and capture folders (idempotent; safe to stop at
    /// any time: the next index finishes the rest). A damaged catalog is set aside and rebuilt.
    Index(IndexArgs),
    /// The newest runs.
    List(ListArgs),
    /// One run in full: its figures, steps, instruments and files (RUN: an id, a prefix of
    /// one, or the run folder).
    Show(ShowArgs),
    /// The runs that match every filter given.
    Query(QueryArgs),
    /// The captures (capture, process and campaign-step folders) that match the filters.
    Captures(QueryArgs),
    /// A metric of every run of one kind over time: a table, and a plot with --plot.
    Trend(TrendArgs),
}

#[derive(Debug, clap::Args)]
pub struct IndexArgs {
    /// Folders holding run folders and capture folders (default: runs).
    #[arg(value_name = "DIR")]
    pub dirs: Vec<PathBuf>,
    /// Print one JSON object instead of the text report.
    #[arg(long)]
    pub json: bool,
}

/// How to print rows.
#[derive(Debug, clap::Args)]
pub struct Output {
    /// Print JSON (an array of objects, or one object for `show`).
    #[arg(long, conflicts_with = "csv")]
    pub json: bool,
    /// Print CSV with a header line.
    #[arg(long)]
    pub csv: bool,
}

#[derive(Debug, clap::Args)]
pub struct ListArgs {
    /// Most runs shown, newest first.
    #[arg(long, default_value_t = 20, value_name = "N")]
    pub limit: usize,
    #[command(flatten)]
    pub output: Output,
}

#[derive(Debug, clap::Args)]
pub struct ShowArgs {
    #[arg(value_name = "RUN")]
    pub run: String,
    #[command(flatten)]
    pub output: Output,
}

#[derive(Debug, clap::Args)]
pub struct Filters {
    /// Created at or after this UTC date or time (YYYY-MM-DD or YYYY-MM-DDTHH:MM:SSZ).
    #[arg(long, value_name = "DATE")]
    pub since: Option<String>,
    /// Created before this UTC date or time.
    #[arg(long, value_name = "DATE")]
    pub until: Option<String>,
    /// The campaign's name (accuracy, resolution, ...) or its sweep (position, bandwidth, ...).
    #[arg(long)]
    pub kind: Option<String>,
    /// A waveform the run used (msk-lfm, ofdm).
    #[arg(long)]
    pub waveform: Option<String>,
    /// Text in the scope's *IDN? (case-insensitive), e.g. UXR or LabMaster.
    #[arg(long)]
    pub scope: Option<String>,
    /// The response calibration's SHA-256 (or a prefix), or `none` for uncorrected runs.
    #[arg(long, value_name = "SHA256")]
    pub calibration: Option<String>,
    /// complete, interrupted or running.
    #[arg(long)]
    pub status: Option<String>,
    /// Terms over the run's figures joined by `and`, e.g. "max_abs_error_m < 1e-3 and missed = 0"
    /// (metrics in docs/catalog.md).
    #[arg(long = "where", value_name = "TERMS")]
    pub where_: Option<String>,
}

#[derive(Debug, clap::Args)]
pub struct QueryArgs {
    #[command(flatten)]
    pub filters: Filters,
    /// Most rows, newest first.
    #[arg(long, value_name = "N")]
    pub limit: Option<usize>,
    #[command(flatten)]
    pub output: Output,
}

#[derive(Debug, clap::Args)]
pub struct TrendArgs {
    /// The campaign's name or sweep (as --kind).
    #[arg(value_name = "KIND")]
    pub kind: String,
    /// The metric (max_abs_error_m, mean_snr_db, ...; docs/catalog.md).
    #[arg(value_name = "METRIC")]
    pub metric: String,
    /// Created at or after this UTC date or time.
    #[arg(long, value_name = "DATE")]
    pub since: Option<String>,
    /// Created before this UTC date or time.
    #[arg(long, value_name = "DATE")]
    pub until: Option<String>,
    /// Also draw it: FILE.svg or FILE.png.
    #[arg(long, value_name = "FILE")]
    pub plot: Option<PathBuf>,
    #[command(flatten)]
    pub output: Output,
}

pub(crate) fn run(args: Args) -> anyhow::Result<()> {
    let catalog = args.catalog.unwrap_or_else(runs_db::default_catalog);
    match args.command {
        Command::Index(a) => index(&catalog, a),
        Command::List(a) => {
            let filter = RunFilter {
                limit: Some(a.limit),
                ..RunFilter::default()
            };
            print_rows(&runs_db::runs(&catalog, &filter)?, &a.output, run_line)
        }
        Command::Show(a) => show(&catalog, a),
        Command::Query(a) => {
            let filter = filter(&a.filters, a.limit)?;
            print_rows(&runs_db::runs(&catalog, &filter)?, &a.output, run_line)
        }
        Command::Captures(a) => {
            let filter = filter(&a.filters, a.limit)?;
            let mut rows = runs_db::captures(&catalog, &filter)?;
            if let Some(l) = a.limit {
                rows.truncate(l);
            }
            print_rows(&rows, &a.output, |c| {
                format!(
                    "{:<24}  {:<8}  {:<7}  {:<12}  {:>3} targets  {}",
                    c.measured_at.as_deref().unwrap_or("-"),
                    c.origin,
                    c.waveform.as_deref().unwrap_or("-"),
                    c.algorithm.as_deref().unwrap_or("-"),
                    c.targets.unwrap_or(0),
                    c.dir
                )
            })
        }
        Command::Trend(a) => trend(&catalog, a),
    }
}

fn filter(f: &Filters, limit: Option<usize>) -> anyhow::Result<RunFilter> {
    if let Some(s) = f.status.as_deref() {
        if !["complete", "interrupted", "running"].contains(&s) {
            return Err(radbench::exit::bad_input(format!(
                "--status {s}: allowed: complete, interrupted, running"
            )));
        }
    }
    Ok(RunFilter {
        since: f
            .since
            .as_deref()
            .map(|s| runs_db::parse_time("--since", s))
            .transpose()?,
        until: f
            .until
            .as_deref()
            .map(|s| runs_db::parse_time("--until", s))
            .transpose()?,
        kind: f.kind.clone(),
        waveform: f.waveform.clone(),
        scope: f.scope.clone(),
        calibration: f.calibration.clone(),
        status: f.status.clone(),
        origin: None,
        conditions: match &f.where_ {
            Some(w) => runs_db::parse_where(w)?,
            None => Vec::new(),
        },
        limit,
    })
}

fn index(catalog: &Path, a: IndexArgs) -> anyhow::Result<()> {
    let dirs = if a.dirs.is_empty() {
        vec![PathBuf::from("runs")]
    } else {
        a.dirs
    };
    let report = runs_db::index(catalog, &dirs)?;
    if a.json {
        println!("{}", serde_json::to_string(&report)?);
    } else {
        if let Some(aside) = &report.set_aside {
            eprintln!(
                "warning: {} was damaged: set aside as {} and rebuilt from the folders",
                catalog.display(),
                aside.display()
            );
        }
        println!(
            "{}: {} runs indexed ({} unchanged), {} captures indexed ({} unchanged), {} removed",
            catalog.display(),
            report.runs_written,
            report.runs_unchanged,
            report.captures_written,
            report.captures_unchanged,
            report.removed
        );
        for f in &report.failed {
            eprintln!("warning: {} not indexed: {}", f.path.display(), f.reason);
        }
    }
    Ok(())
}

fn run_line(r: &runs_db::RunRow) -> String {
    format!(
        "{}  {:<24}  {:<14}  {:<11}  {:>3}/{:<3} steps  max |error| {:<12}  {}",
        r.run_id,
        r.created,
        r.name,
        r.status,
        r.steps_done,
        r.steps_total,
        r.max_abs_error_m
            .map_or("-".into(), |e| format!("{:.3} mm", e * 1e3)),
        r.dir
    )
}

fn show(catalog: &Path, a: ShowArgs) -> anyhow::Result<()> {
    let d = runs_db::run_detail(catalog, &a.run)?;
    if a.output.json {
        println!("{}", serde_json::to_string_pretty(&d)?);
        return Ok(());
    }
    if a.output.csv {
        return print_rows(&d.steps, &a.output, |_| String::new());
    }
    println!("run {} ({})", d.run.run_id, d.run.dir);
    println!(
        "  {} ({}), {}, created {}, {}/{} steps, radbench {}{}",
        d.run.name,
        d.run.sweep.as_deref().unwrap_or("no sweep"),
        d.run.status,
        d.run.created,
        d.run.steps_done,
        d.run.steps_total,
        d.radbench_version,
        if d.simulated { ", simulated bench" } else { "" }
    );
    if let Some(r) = &d.reason {
        println!("  stopped: {r}");
    }
    for (role, idn) in &d.instruments {
        println!("  {role}: {idn}");
    }
    if let Some(c) = &d.run.calibration_sha256 {
        println!("  calibration: {c}");
    }
    println!("figures:");
    for (name, value) in d.metrics.iter().filter(|(n, _)| !n.contains('.')) {
        println!("  {name:<26} {value}");
    }
    println!("steps:");
    for s in &d.steps {
        println!(
            "  {:>3}  {:<11}  {:<8}  {:<16}  error {:<12}  SNR {}",
            s.step,
            s.algorithm,
            s.status,
            s.label.as_deref().unwrap_or("-"),
            s.error_m
                .map_or("-".into(), |e| format!("{:.3} mm", e * 1e3)),
            s.snr_db.map_or("-".into(), |v| format!("{v:.1} dB"))
        );
    }
    println!("files: {} (SHA-256 in `--json`)", d.assets.len());
    Ok(())
}

fn trend(catalog: &Path, a: TrendArgs) -> anyhow::Result<()> {
    let filter = RunFilter {
        since: a
            .since
            .as_deref()
            .map(|s| runs_db::parse_time("--since", s))
            .transpose()?,
        until: a
            .until
            .as_deref()
            .map(|s| runs_db::parse_time("--until", s))
            .transpose()?,
        ..RunFilter::default()
    };
    let points = runs_db::trend(catalog, &a.kind, &a.metric, &filter)?;
    if points.is_empty() {
        return Err(radbench::exit::bad_input(format!(
            "no run of kind `{}` has the metric `{}` in {} (kinds are campaign names or sweeps; \
             metrics: {}, or ALGORITHM.METRIC)",
            a.kind,
            a.metric,
            catalog.display(),
            runs_db::METRIC_NAMES.join(", ")
        )));
    }
    if let Some(path) = &a.plot {
        plot_trend(path, &a.kind, &a.metric, &points)?;
    }
    print_rows(&points, &a.output, |p| {
        format!("{}  {}  {}", p.created, p.run_id, p.value)
    })?;
    if let Some(path) = &a.plot {
        if !a.output.json && !a.output.csv {
            println!("plot: {}", path.display());
        }
    }
    Ok(())
}

/// The trend as a line over days since the first run (SVG or PNG by the file's extension).
fn plot_trend(
    path: &Path,
    kind: &str,
    metric: &str,
    points: &[runs_db::TrendPoint],
) -> anyhow::Result<()> {
    use radbench::storage::{Curve, ProfilePlot};
    let days: Vec<f64> = points
        .iter()
        .map(|p| days_since(&points[0].created, &p.created))
        .collect();
    let values: Vec<f64> = points.iter().map(|p| p.value).collect();
    let mut plot = ProfilePlot::new(
        format!("{kind}: {metric} over {} runs", points.len()),
        vec![Curve::solid(metric, days, values)],
    );
    plot.x_label = format!("days since {}", &points[0].created);
    plot.y_label = metric.to_string();
    radbench::storage::draw(path, &plot)?;
    Ok(())
}

/// Days from `a` to `b` (RFC 3339 UTC texts as radbench writes them).
fn days_since(a: &str, b: &str) -> f64 {
    (seconds(b) - seconds(a)) / 86_400.0
}

/// Seconds since 1970 of `YYYY-MM-DDTHH:MM:SS[.fff]Z` (0 for anything else).
fn seconds(t: &str) -> f64 {
    let num = |r: std::ops::Range<usize>| t.get(r).and_then(|s| s.parse::<i64>().ok());
    let (Some(y), Some(m), Some(d)) = (num(0..4), num(5..7), num(8..10)) else {
        return 0.0;
    };
    // Days from civil (H. Hinnant).
    let y = if m <= 2 { y - 1 } else { y };
    let era = y.div_euclid(400);
    let yoe = y - era * 400;
    let mp = (m + 9) % 12;
    let doy = (153 * mp + 2) / 5 + d - 1;
    let doe = yoe * 365 + yoe / 4 - yoe / 100 + doy;
    let days = era * 146_097 + doe - 719_468;
    let hms =
        num(11..13).unwrap_or(0) * 3600 + num(14..16).unwrap_or(0) * 60 + num(17..19).unwrap_or(0);
    let frac: f64 = t
        .get(19..)
        .and_then(|s| s.trim_end_matches('Z').parse::<f64>().ok())
        .unwrap_or(0.0);
    (days * 86_400 + hms) as f64 + frac
}

/// Prints rows as a table (one `line` each), JSON or CSV.
fn print_rows<T: Serialize>(
    rows: &[T],
    output: &Output,
    line: impl Fn(&T) -> String,
) -> anyhow::Result<()> {
    if output.json {
        super::terminal::out_json(rows)?;
    } else if output.csv {
        print!("{}", to_csv(rows)?);
    } else if rows.is_empty() {
        println!("(none)");
    } else {
        for r in rows {
            println!("{}", line(r));
        }
    }
    Ok(())
}

/// Rows as CSV: the fields of the first row as the header, nulls empty, quoted where needed.
fn to_csv<T: Serialize>(rows: &[T]) -> anyhow::Result<String> {
    let values: Vec<serde_json::Value> = rows
        .iter()
        .map(serde_json::to_value)
        .collect::<Result<_, _>>()?;
    let Some(first) = values.first().and_then(|v| v.as_object()) else {
        return Ok(String::new());
    };
    let header: Vec<&String> = first.keys().collect();
    let mut out = header
        .iter()
        .map(|h| csv_field(h))
        .collect::<Vec<_>>()
        .join(",");
    out.push('\n');
    for v in &values {
        let line: Vec<String> = header
            .iter()
            .map(|h| match &v[h.as_str()] {
                serde_json::Value::Null => String::new(),
                serde_json::Value::String(s) => csv_field(s),
                other => csv_field(&other.to_string()),
            })
            .collect();
        out.push_str(&line.join(","));
        out.push('\n');
    }
    Ok(out)
}

fn csv_field(s: &str) -> String {
    if s.contains([',', '"', '\n', '\r']) {
        format!("\"{}\"", s.replace('"', "\"\""))
    } else {
        s.to_string()
    }
}

/// How long a command waits at its end for its registrations (they take milliseconds; a locked
/// catalog gives up after its busy timeout): never longer.
const SETTLE: std::time::Duration = std::time::Duration::from_secs(1);

/// Registers `dir` (a capture's or process's output, made durable) in its catalog now, bounded;
/// a failure is a warning, never the command's error.
pub(crate) fn register_now(dir: &Path) {
    let registering = Registering::new(None, dir);
    registering.settle(Some(dir));
}

/// An observer that registers the run folder in the catalog after each step, on the catalog's
/// own thread, and tells `inner` everything.
pub(crate) struct Registering<'a> {
    inner: Option<&'a mut dyn radbench::campaign::Observer>,
    registrar: Option<runs_db::Registrar>,
}

impl<'a> Registering<'a> {
    /// Registers into the catalog of the run folder `dir` (`RADBENCH_CATALOG`, or the runs
    /// folder's `catalog.sqlite`).
    pub(crate) fn new(
        inner: Option<&'a mut dyn radbench::campaign::Observer>,
        dir: &Path,
    ) -> Registering<'a> {
        Registering {
            inner,
            registrar: runs_db::catalog_for(dir).map(runs_db::Registrar::start),
        }
    }

    /// Registers `dir` (when the command ended with one) and waits, bounded, for the catalog;
    /// prints what did not reach it as warnings.
    pub(crate) fn settle(mut self, dir: Option<&Path>) {
        let Some(registrar) = self.registrar.take() else {
            return;
        };
        if let Some(d) = dir {
            registrar.register(d);
        }
        for w in registrar.finish(SETTLE) {
            eprintln!("warning: {w}");
        }
    }
}

impl radbench::campaign::Observer for Registering<'_> {
    fn step_starting(
        &mut self,
        step: &radbench::campaign::Step,
        of: usize,
        bench: &radbench::measure::Bench,
    ) {
        if let Some(i) = self.inner.as_mut() {
            i.step_starting(step, of, bench);
        }
    }

    fn step_done(&mut self, done: &radbench::campaign::StepDone<'_>) {
        if let Some(i) = self.inner.as_mut() {
            i.step_done(done);
        }
        if let (Some(r), Some(run)) = (&self.registrar, done.dir.parent()) {
            r.register(run);
        }
    }

    fn note(&mut self, text: &str) {
        if let Some(i) = self.inner.as_mut() {
            i.note(text);
        }
    }

    fn retrying(&mut self, retry: &radbench::campaign::Retrying<'_>) {
        if let Some(i) = self.inner.as_mut() {
            i.retrying(retry);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn times_convert_to_days() {
        assert_eq!(seconds("1970-01-01T00:00:00Z"), 0.0);
        assert_eq!(seconds("1970-01-02T00:00:01.5Z"), 86_401.5);
        let d = days_since("2026-12-01T00:00:00.000Z", "2026-12-05T12:00:00.000Z");
        assert!((d - 4.5).abs() < 1e-9, "{d}");
    }

    #[test]
    fn csv_quotes_what_needs_it() {
        assert_eq!(csv_field("a,b"), "\"a,b\"");
        assert_eq!(csv_field("say \"x\""), "\"say \"\"x\"\"\"");
        assert_eq!(csv_field("plain"), "plain");
    }
}
