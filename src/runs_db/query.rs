//! Reading the catalog: runs and captures by filters, one run in full, a metric's trend. Every
//! user value reaches SQL as a bound parameter; the `--where` clause is parsed here into
//! (metric, operator, number) terms, and only operators from a fixed list are written into the
//! statement.

use super::db;
use super::RunsDbError;
use rusqlite::types::Value as SqlValue;
use rusqlite::Connection;
use serde::Serialize;
use std::path::Path;

/// What `runs list` and `runs query` select runs by (every field optional, all must hold).
#[derive(Debug, Clone, Default)]
pub struct RunFilter {
    /// Created at or after (as [`parse_time`] gives it).
    pub since: Option<String>,
    /// Created before (as [`parse_time`] gives it: a day means its start, so it is excluded).
    pub until: Option<String>,
    /// The campaign's name (`accuracy`, ...) or its sweep's parameter (`position`, ...).
    pub kind: Option<String>,
    /// A waveform the run used (`msk-lfm`, `ofdm`).
    pub waveform: Option<String>,
    /// Text in the scope's `*IDN?` (case-insensitive).
    pub scope: Option<String>,
    /// The response calibration's SHA-256 (a prefix will do), or `none` for uncorrected runs.
    pub calibration: Option<String>,
    /// `complete`, `interrupted` or `running`.
    pub status: Option<String>,
    /// Terms over the run's metrics, all of which must hold.
    pub conditions: Vec<Condition>,
    /// Captures only: made by `capture`, `process` or `campaign` (a run's step).
    pub origin: Option<String>,
    /// Most rows (newest first); `None`: all.
    pub limit: Option<usize>,
}

/// One term of `--where`: `metric OP number`.
#[derive(Debug, Clone, PartialEq)]
pub struct Condition {
    pub metric: String,
    pub op: Op,
    pub value: f64,
}

/// A comparison `--where` allows.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Op {
    Lt,
    Le,
    Gt,
    Ge,
    Eq,
    Ne,
}

impl Op {
    const ALL: [(&'static str, Op); 7] = [
        ("<=", Op::Le),
        (">=", Op::Ge),
        ("!=", Op::Ne),
        ("==", Op::Eq),
        ("<", Op::Lt),
        (">", Op::Gt),
        ("=", Op::Eq),
    ];

    /// The operator as SQL writes it (from this fixed list, never from the user's text).
    fn sql(self) -> &'static str {
        match self {
            Op::Lt => "<",
            Op::Le => "<=",
            Op::Gt => ">",
            Op::Ge => ">=",
            Op::Eq => "=",
            Op::Ne => "<>",
        }
    }
}

/// Parses `--where`: terms `metric OP number` joined by `and` (`max_abs_error_m < 1e-3 and
/// missed = 0`). A metric is letters, digits, `_` and `.` (`music.max_abs_error_m`).
pub fn parse_where(text: &str) -> Result<Vec<Condition>, RunsDbError> {
    let bad = |reason: String| RunsDbError::BadInput {
        field: "--where".into(),
        reason,
    };
    let mut out = Vec::new();
    for term in split_and(text) {
        let term = term.trim();
        if term.is_empty() {
            return Err(bad(format!(
                "`{text}`: an empty term; write terms `METRIC OP NUMBER` joined by `and`, e.g. \
                 `max_abs_error_m < 1e-3 and missed = 0`"
            )));
        }
        let Some((at, sym, op)) = Op::ALL
            .iter()
            .filter_map(|(sym, op)| term.find(sym).map(|at| (at, *sym, *op)))
            .min_by_key(|(at, sym, _)| (*at, std::cmp::Reverse(sym.len())))
        else {
            return Err(bad(format!(
                "`{term}` has no comparison: allowed operators are <, <=, >, >=, =, !="
            )));
        };
        let metric = term[..at].trim();
        let number = term[at + sym.len()..].trim();
        let valid_metric = !metric.is_empty()
            && metric
                .chars()
                .all(|c| c.is_ascii_alphanumeric() || c == '_' || c == '.' || c == '-');
        if !valid_metric {
            return Err(bad(format!(
                "`{metric}` is not a metric name (letters, digits, `_`, `-` and `.`; e.g. {})",
                super::METRIC_NAMES.join(", ")
            )));
        }
        let value: f64 = number
            .parse()
            .ok()
            .filter(|v: &f64| v.is_finite())
            .ok_or_else(|| {
                bad(format!(
                    "`{number}` in `{term}` is not a finite number (e.g. 1e-3, 0.5, 12)"
                ))
            })?;
        out.push(Condition {
            metric: metric.to_string(),
            op,
            value,
        });
    }
    Ok(out)
}

/// Splits on the word `and` (any case) between terms.
fn split_and(text: &str) -> Vec<&str> {
    let mut parts = Vec::new();
    let mut start = 0;
    let lower = text.to_ascii_lowercase();
    let bytes = lower.as_bytes();
    let mut i = 0;
    while let Some(found) = lower[i..].find("and") {
        let at = i + found;
        let before = at == 0 || bytes[at - 1].is_ascii_whitespace();
        let after = at + 3 >= bytes.len() || bytes[at + 3].is_ascii_whitespace();
        if before && after {
            parts.push(&text[start..at]);
            start = at + 3;
        }
        i = at + 3;
    }
    parts.push(&text[start..]);
    parts
}

/// `--since`/`--until`: RFC 3339 (`2026-12-05T10:00:00Z`) or a day (`2026-12-05`, its start).
pub fn parse_time(field: &str, text: &str) -> Result<String, RunsDbError> {
    let b = text.as_bytes();
    let digits = |r: std::ops::Range<usize>| b[r].iter().all(u8::is_ascii_digit);
    let day = b.len() >= 10
        && digits(0..4)
        && b[4] == b'-'
        && digits(5..7)
        && b[7] == b'-'
        && digits(8..10);
    let ok = day
        && (b.len() == 10
            || (b.len() >= 19
                && b[10] == b'T'
                && digits(11..13)
                && b[13] == b':'
                && digits(14..16)
                && b[16] == b':'
                && digits(17..19)));
    if !ok {
        return Err(RunsDbError::BadInput {
            field: field.into(),
            reason: format!(
                "`{text}` is not a UTC date or time: give YYYY-MM-DD or YYYY-MM-DDTHH:MM:SSZ"
            ),
        });
    }
    Ok(if b.len() == 10 {
        format!("{text}T00:00:00")
    } else {
        text.trim_end_matches('Z').to_string()
    })
}

/// A run as `list` and `query` show it.
#[derive(Debug, Clone, Serialize, PartialEq)]
pub struct RunRow {
    pub run_id: String,
    pub created: String,
    pub name: String,
    pub sweep: Option<String>,
    pub status: String,
    pub steps_done: i64,
    pub steps_total: i64,
    pub waveforms: String,
    pub algorithms: String,
    pub scope_idn: Option<String>,
    pub calibration_sha256: Option<String>,
    pub max_abs_error_m: Option<f64>,
    pub dir: String,
}

/// The runs `filter` selects, newest first.
pub fn runs(catalog: &Path, filter: &RunFilter) -> Result<Vec<RunRow>, RunsDbError> {
    let conn = db::open_existing(catalog)?;
    query_runs(&conn, filter).map_err(|e| RunsDbError::sql(catalog, e))
}

fn query_runs(conn: &Connection, f: &RunFilter) -> rusqlite::Result<Vec<RunRow>> {
    let mut sql = String::from(
        "SELECT r.run_id, r.created, r.name, r.sweep, r.status, r.steps_done, r.steps_total,
           r.waveforms, r.algorithms, r.scope_idn, r.calibration_sha256, r.max_abs_error_m, r.dir
         FROM runs r
         WHERE 1",
    );
    let mut args: Vec<SqlValue> = Vec::new();
    let mut bind = |sql: &mut String, clause: &str, v: SqlValue| {
        args.push(v);
        sql.push_str(&clause.replace('?', &format!("?{}", args.len())));
    };
    if let Some(s) = &f.since {
        bind(&mut sql, " AND r.created >= ?", SqlValue::Text(s.clone()));
    }
    if let Some(u) = &f.until {
        bind(&mut sql, " AND r.created < ?", SqlValue::Text(u.clone()));
    }
    if let Some(k) = &f.kind {
        args.push(SqlValue::Text(k.clone()));
        let n = args.len();
        sql.push_str(&format!(" AND (r.name = ?{n} OR r.sweep = ?{n})"));
    }
    if let Some(w) = &f.waveform {
        args.push(SqlValue::Text(w.clone()));
        let n = args.len();
        sql.push_str(&format!(
            " AND instr(',' || r.waveforms || ',', ',' || ?{n} || ',') > 0"
        ));
    }
    if let Some(s) = &f.scope {
        args.push(SqlValue::Text(s.to_lowercase()));
        let n = args.len();
        sql.push_str(&format!(
            " AND instr(lower(coalesce(r.scope_idn, '')), ?{n}) > 0"
        ));
    }
    match f.calibration.as_deref() {
        None => {}
        Some("none") => sql.push_str(" AND r.calibration_sha256 IS NULL"),
        Some(c) => {
            args.push(SqlValue::Text(c.to_lowercase()));
            let n = args.len();
            sql.push_str(&format!(
                " AND substr(r.calibration_sha256, 1, length(?{n})) = ?{n}"
            ));
        }
    }
    if let Some(s) = &f.status {
        args.push(SqlValue::Text(s.clone()));
        sql.push_str(&format!(" AND r.status = ?{}", args.len()));
    }
    for c in &f.conditions {
        args.push(SqlValue::Text(c.metric.clone()));
        let name = args.len();
        args.push(SqlValue::Real(c.value));
        let value = args.len();
        sql.push_str(&format!(
            " AND EXISTS (SELECT 1 FROM run_metrics m WHERE m.run_id = r.run_id \
             AND m.name = ?{name} AND m.value {} ?{value})",
            c.op.sql()
        ));
    }
    sql.push_str(" ORDER BY r.created DESC, r.run_id");
    if let Some(l) = f.limit {
        args.push(SqlValue::Integer(l as i64));
        sql.push_str(&format!(" LIMIT ?{}", args.len()));
    }
    let mut q = conn.prepare(&sql)?;
    let rows = q.query_map(rusqlite::params_from_iter(args), |r| {
        Ok(RunRow {
            run_id: r.get(0)?,
            created: r.get(1)?,
            name: r.get(2)?,
            sweep: r.get(3)?,
            status: r.get(4)?,
            steps_done: r.get(5)?,
            steps_total: r.get(6)?,
            waveforms: r.get(7)?,
            algorithms: r.get(8)?,
            scope_idn: r.get(9)?,
            calibration_sha256: r.get(10)?,
            max_abs_error_m: r.get(11)?,
            dir: r.get(12)?,
        })
    })?;
    rows.collect()
}

/// One run in full: its row, metrics, steps, instruments and files.
#[derive(Debug, Clone, Serialize)]
pub struct RunDetail {
    pub run: RunRow,
    pub reason: Option<String>,
    pub radbench_version: String,
    pub git_commit: Option<String>,
    pub simulated: bool,
    pub bench_file: Option<String>,
    pub metrics: Vec<(String, f64)>,
    pub instruments: Vec<(String, String)>,
    pub steps: Vec<StepRow>,
    pub assets: Vec<AssetRow>,
}

/// A step of a run, for one algorithm.
#[derive(Debug, Clone, Serialize)]
pub struct StepRow {
    pub step: i64,
    pub algorithm: String,
    pub status: String,
    pub label: Option<String>,
    pub value: Option<f64>,
    pub error_m: Option<f64>,
    pub snr_db: Option<f64>,
}

/// A file and its SHA-256.
#[derive(Debug, Clone, Serialize)]
pub struct AssetRow {
    pub path: String,
    pub bytes: i64,
    pub sha256: String,
}

/// The run `id` (its id, a prefix of it, or its folder).
pub fn run_detail(catalog: &Path, id: &str) -> Result<RunDetail, RunsDbError> {
    let conn = db::open_existing(catalog)?;
    let sql = |e| RunsDbError::sql(catalog, e);
    let dir = super::record::absolute(Path::new(id));
    let ids: Vec<String> = {
        let mut q = conn
            .prepare("SELECT run_id FROM runs WHERE substr(run_id, 1, length(?1)) = ?1 OR dir = ?2")
            .map_err(sql)?;
        let rows = q
            .query_map(rusqlite::params![id, super::index::path_text(&dir)], |r| {
                r.get::<_, String>(0)
            })
            .map_err(sql)?;
        rows.collect::<Result<_, _>>().map_err(sql)?
    };
    let run_id = match ids.as_slice() {
        [one] => one.clone(),
        [] => {
            return Err(RunsDbError::BadInput {
                field: "RUN".into(),
                reason: format!(
                    "`{id}` names no run in {} (give a run id as `runs list` shows it, or a run \
                     folder; `radbench runs index` adds new folders)",
                    catalog.display()
                ),
            })
        }
        many => {
            return Err(RunsDbError::BadInput {
                field: "RUN".into(),
                reason: format!(
                    "`{id}` names {} runs ({}): give more of the id",
                    many.len(),
                    many.join(", ")
                ),
            })
        }
    };
    let filter = RunFilter::default();
    let run = query_runs(&conn, &filter)
        .map_err(sql)?
        .into_iter()
        .find(|r| r.run_id == run_id)
        .ok_or_else(|| RunsDbError::Missing {
            path: catalog.to_path_buf(),
        })?;
    let (reason, radbench_version, git_commit, simulated, bench_file) = conn
        .query_row(
            "SELECT reason, radbench_version, git_commit, simulated, bench_file FROM runs
             WHERE run_id = ?1",
            [&run_id],
            |r| Ok((r.get(0)?, r.get(1)?, r.get(2)?, r.get(3)?, r.get(4)?)),
        )
        .map_err(sql)?;
    let pairs = |text: &str| -> Result<Vec<(String, String)>, RunsDbError> {
        let mut q = conn.prepare(text).map_err(sql)?;
        let rows = q
            .query_map([&run_id], |r| Ok((r.get(0)?, r.get(1)?)))
            .map_err(sql)?;
        rows.collect::<Result<_, _>>().map_err(sql)
    };
    let instruments = pairs("SELECT role, idn FROM instruments WHERE owner = ?1 ORDER BY role")?;
    let metrics = {
        let mut q = conn
            .prepare("SELECT name, value FROM run_metrics WHERE run_id = ?1 ORDER BY name")
            .map_err(sql)?;
        let rows = q
            .query_map([&run_id], |r| Ok((r.get(0)?, r.get(1)?)))
            .map_err(sql)?;
        rows.collect::<Result<_, _>>().map_err(sql)?
    };
    let steps = {
        let mut q = conn
            .prepare(
                "SELECT step, algorithm, status, label, value, error_m, snr_db FROM steps
                 WHERE run_id = ?1 ORDER BY step, algorithm",
            )
            .map_err(sql)?;
        let rows = q
            .query_map([&run_id], |r| {
                Ok(StepRow {
                    step: r.get(0)?,
                    algorithm: r.get(1)?,
                    status: r.get(2)?,
                    label: r.get(3)?,
                    value: r.get(4)?,
                    error_m: r.get(5)?,
                    snr_db: r.get(6)?,
                })
            })
            .map_err(sql)?;
        rows.collect::<Result<_, _>>().map_err(sql)?
    };
    let assets = {
        let mut q = conn
            .prepare("SELECT path, bytes, sha256 FROM assets WHERE owner = ?1 ORDER BY path")
            .map_err(sql)?;
        let rows = q
            .query_map([&run_id], |r| {
                Ok(AssetRow {
                    path: r.get(0)?,
                    bytes: r.get(1)?,
                    sha256: r.get(2)?,
                })
            })
            .map_err(sql)?;
        rows.collect::<Result<_, _>>().map_err(sql)?
    };
    Ok(RunDetail {
        run,
        reason,
        radbench_version,
        git_commit,
        simulated,
        bench_file,
        metrics,
        instruments,
        steps,
        assets,
    })
}

/// One point of a trend: a run's metric.
#[derive(Debug, Clone, Serialize, PartialEq)]
pub struct TrendPoint {
    pub created: String,
    pub run_id: String,
    pub value: f64,
}

/// `metric` of every run of `kind` (its name or sweep), oldest first, within `filter`'s dates.
pub fn trend(
    catalog: &Path,
    kind: &str,
    metric: &str,
    filter: &RunFilter,
) -> Result<Vec<TrendPoint>, RunsDbError> {
    let conn = db::open_existing(catalog)?;
    let sql = |e| RunsDbError::sql(catalog, e);
    let mut q = conn
        .prepare(
            "SELECT r.created, r.run_id, m.value FROM runs r
             JOIN run_metrics m ON m.run_id = r.run_id AND m.name = ?3
             WHERE (r.name = ?1 OR r.sweep = ?1)
               AND (?2 IS NULL OR r.created >= ?2) AND (?4 IS NULL OR r.created < ?4)
             ORDER BY r.created, r.run_id",
        )
        .map_err(sql)?;
    let rows = q
        .query_map(
            rusqlite::params![kind, filter.since, metric, filter.until],
            |r| {
                Ok(TrendPoint {
                    created: r.get(0)?,
                    run_id: r.get(1)?,
                    value: r.get(2)?,
                })
            },
        )
        .map_err(sql)?;
    rows.collect::<Result<_, _>>().map_err(sql)
}

/// A capture as `runs captures` shows it.
#[derive(Debug, Clone, Serialize, PartialEq)]
pub struct CaptureRow {
    pub dir: String,
    pub origin: String,
    pub run_id: Option<String>,
    pub step: Option<i64>,
    pub measured_at: Option<String>,
    pub waveform: Option<String>,
    pub algorithm: Option<String>,
    pub scope_idn: Option<String>,
    pub targets: Option<i64>,
    pub snr_db: Option<f64>,
}

/// The captures `filter` selects, newest first: dates on `measured_at`, the waveform and scope
/// of the capture, its origin; the run filters (kind, calibration, status, `--where`) through
/// the run a campaign step belongs to (a capture of no run has none to match).
pub fn captures(catalog: &Path, filter: &RunFilter) -> Result<Vec<CaptureRow>, RunsDbError> {
    let conn = db::open_existing(catalog)?;
    query_captures(&conn, filter).map_err(|e| RunsDbError::sql(catalog, e))
}

fn query_captures(conn: &Connection, f: &RunFilter) -> rusqlite::Result<Vec<CaptureRow>> {
    let mut sql = String::from(
        "SELECT c.dir, c.origin, c.run_id, c.step, c.measured_at, c.waveform, c.algorithm,
           c.scope_idn, c.targets, c.snr_db
         FROM captures c LEFT JOIN runs r ON r.run_id = c.run_id
         WHERE 1",
    );
    let mut args: Vec<SqlValue> = Vec::new();
    let mut bind = |sql: &mut String, clause: &str, v: SqlValue| {
        args.push(v);
        sql.push_str(&clause.replace('?', &format!("?{}", args.len())));
    };
    let text = |s: &String| SqlValue::Text(s.clone());
    if let Some(s) = &f.since {
        bind(&mut sql, " AND c.measured_at >= ?", text(s));
    }
    if let Some(u) = &f.until {
        bind(&mut sql, " AND c.measured_at < ?", text(u));
    }
    if let Some(k) = &f.kind {
        bind(&mut sql, " AND (r.name = ? OR r.sweep = ?)", text(k));
    }
    if let Some(w) = &f.waveform {
        bind(&mut sql, " AND c.waveform = ?", text(w));
    }
    if let Some(s) = &f.scope {
        bind(
            &mut sql,
            " AND instr(lower(coalesce(c.scope_idn, '')), ?) > 0",
            SqlValue::Text(s.to_lowercase()),
        );
    }
    match f.calibration.as_deref() {
        None => {}
        Some("none") => sql.push_str(" AND r.run_id IS NOT NULL AND r.calibration_sha256 IS NULL"),
        Some(c) => {
            bind(
                &mut sql,
                " AND substr(r.calibration_sha256, 1, length(?)) = ?",
                SqlValue::Text(c.to_lowercase()),
            );
        }
    }
    if let Some(s) = &f.status {
        bind(&mut sql, " AND r.status = ?", text(s));
    }
    if let Some(o) = &f.origin {
        bind(&mut sql, " AND c.origin = ?", text(o));
    }
    for c in &f.conditions {
        bind(
            &mut sql,
            " AND EXISTS (SELECT 1 FROM run_metrics m WHERE m.run_id = r.run_id AND m.name = ?",
            text(&c.metric),
        );
        // The operator from Op's fixed list, never from the user's text.
        bind(
            &mut sql,
            &format!(" AND m.value {} ?)", c.op.sql()),
            SqlValue::Real(c.value),
        );
    }
    sql.push_str(" ORDER BY c.measured_at DESC, c.dir");
    if let Some(l) = f.limit {
        bind(&mut sql, " LIMIT ?", SqlValue::Integer(l as i64));
    }
    let mut q = conn.prepare(&sql)?;
    let rows = q.query_map(rusqlite::params_from_iter(args), |r| {
        Ok(CaptureRow {
            dir: r.get(0)?,
            origin: r.get(1)?,
            run_id: r.get(2)?,
            step: r.get(3)?,
            measured_at: r.get(4)?,
            waveform: r.get(5)?,
            algorithm: r.get(6)?,
            scope_idn: r.get(7)?,
            targets: r.get(8)?,
            snr_db: r.get(9)?,
        })
    })?;
    rows.collect()
}

/// The statuses a run can have (`--status`, `status=`).
pub(crate) const STATUSES: [&str; 3] = ["complete", "interrupted", "running"];

/// The origins a capture can have (`origin=`).
const ORIGINS: [&str; 3] = ["capture", "process", "campaign"];

/// The names a query's `NAME = VALUE` terms may use (the others are metric terms).
const QUERY_FIELDS: [&str; 8] = [
    "since",
    "until",
    "kind",
    "waveform",
    "scope",
    "calibration",
    "status",
    "origin",
];

/// A query in one line, as `radbench process --from-catalog` and the Python package's Dask path
/// take it: the filters of `radbench runs captures` as `NAME = VALUE` terms (`since`, `until`,
/// `kind`, `waveform`, `scope`, `calibration`, `status`, `origin`) and the metric terms of
/// `--where`, joined by `and`; e.g. `waveform = msk-lfm and since = 2026-12-01 and
/// max_abs_error_m < 1e-3`. Empty (or `all`): every capture. An error names the term at fault.
pub(crate) fn parse_query(text: &str) -> Result<RunFilter, RunsDbError> {
    let bad = |reason: String| RunsDbError::BadInput {
        field: "query".into(),
        reason,
    };
    let mut f = RunFilter::default();
    let trimmed = text.trim();
    if trimmed.is_empty() || trimmed.eq_ignore_ascii_case("all") {
        return Ok(f);
    }
    let mut metric_terms = Vec::new();
    for term in split_and(text) {
        let term = term.trim();
        let field = term
            .split(['=', '<', '>', '!'])
            .next()
            .unwrap_or("")
            .trim()
            .to_ascii_lowercase();
        if !QUERY_FIELDS.contains(&field.as_str()) {
            // A metric term compares with a number: anything else names a filter that is not.
            let value = term.rsplit(['=', '<', '>']).next().unwrap_or("").trim();
            if term.contains(['=', '<', '>']) && value.parse::<f64>().is_err() {
                return Err(bad(format!(
                    "`{term}`: `{field}` is not a filter (give one of {}) and `{value}` is not a \
                     number to compare a metric with",
                    QUERY_FIELDS.join(", ")
                )));
            }
            metric_terms.push(term);
            continue;
        }
        let rest = term[term.find(['=', '<', '>', '!']).unwrap_or(term.len())..].trim_start();
        let Some(value) = rest.strip_prefix("==").or_else(|| rest.strip_prefix('=')) else {
            return Err(bad(format!(
                "`{term}`: {field} takes `{field} = VALUE` (only `=`; dates as `since = DATE` \
                 and `until = DATE`)"
            )));
        };
        let value = value.trim().trim_matches(['"', '\'']).to_string();
        if value.is_empty() {
            return Err(bad(format!("`{term}`: no value after `=`")));
        }
        let allowed = |list: &[&str]| -> Result<(), RunsDbError> {
            if list.contains(&value.as_str()) {
                Ok(())
            } else {
                Err(bad(format!(
                    "`{term}`: {field} `{value}` is not one of {}",
                    list.join(", ")
                )))
            }
        };
        let slot = match field.as_str() {
            "since" => {
                f.since = Some(parse_time("query: since", &value)?);
                continue;
            }
            "until" => {
                f.until = Some(parse_time("query: until", &value)?);
                continue;
            }
            "kind" => &mut f.kind,
            "waveform" => &mut f.waveform,
            "scope" => &mut f.scope,
            "calibration" => &mut f.calibration,
            "status" => {
                allowed(&STATUSES)?;
                &mut f.status
            }
            _ => {
                allowed(&ORIGINS)?;
                &mut f.origin
            }
        };
        if slot.is_some() {
            return Err(bad(format!("`{term}`: {field} is given twice")));
        }
        *slot = Some(value);
    }
    if !metric_terms.is_empty() {
        f.conditions = parse_where(&metric_terms.join(" and ")).map_err(|e| match e {
            RunsDbError::BadInput { reason, .. } => bad(format!(
                "{reason} (a term is `NAME = VALUE` for {} or `METRIC OP NUMBER`)",
                QUERY_FIELDS.join(", ")
            )),
            other => other,
        })?;
    }
    Ok(f)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn where_clauses_parse_into_terms() {
        let c = parse_where("max_abs_error_m < 1e-3 AND missed = 0 and music.snr_db>=20").unwrap();
        assert_eq!(c.len(), 3);
        assert_eq!(c[0].metric, "max_abs_error_m");
        assert_eq!(c[0].op, Op::Lt);
        assert_eq!(c[0].value, 1e-3);
        assert_eq!((c[1].op, c[1].value), (Op::Eq, 0.0));
        assert_eq!((c[2].metric.as_str(), c[2].op), ("music.snr_db", Op::Ge));
    }

    #[test]
    fn hostile_or_broken_where_clauses_are_refused_by_name() {
        for bad in [
            "x < 1; DROP TABLE runs",
            "max_abs_error_m < 1 or 1=1",
            "a' < 1",
            "max_abs_error_m",
            "max_abs_error_m < nan",
            "and",
        ] {
            let err = parse_where(bad).unwrap_err().to_string();
            assert!(err.contains("--where"), "{bad}: {err}");
        }
    }

    #[test]
    fn queries_are_filters_and_metric_terms_and_name_what_is_wrong() {
        let f = parse_query("waveform = msk-lfm and since = 2026-12-01 and max_abs_error_m < 1e-3")
            .unwrap();
        assert_eq!(f.waveform.as_deref(), Some("msk-lfm"));
        assert_eq!(f.since.as_deref(), Some("2026-12-01T00:00:00"));
        assert_eq!(f.conditions.len(), 1);
        assert!(parse_query("all").unwrap().conditions.is_empty());
        for (bad, names) in [
            ("wavefrm = ofdm", "wavefrm"),
            ("status = done", "done"),
            ("since = yesterday", "yesterday"),
            ("kind < accuracy", "kind"),
            ("origin = capture and origin = process", "twice"),
        ] {
            let err = parse_query(bad).unwrap_err().to_string();
            assert!(err.contains("query") && err.contains(names), "{bad}: {err}");
        }
    }

    #[test]
    fn dates_are_days_or_rfc3339() {
        assert_eq!(
            parse_time("--since", "2026-12-05").unwrap(),
            "2026-12-05T00:00:00"
        );
        assert_eq!(
            parse_time("--since", "2026-12-05T10:11:12Z").unwrap(),
            "2026-12-05T10:11:12"
        );
        let err = parse_time("--until", "yesterday").unwrap_err().to_string();
        assert!(
            err.contains("--until") && err.contains("YYYY-MM-DD"),
            "{err}"
        );
    }
}
