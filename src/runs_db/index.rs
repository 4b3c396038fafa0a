//! `radbench runs index`: the folders' records written into the catalog, one transaction per
//! folder (a kill leaves every folder either as it was or wholly updated; the next index
//! finishes the rest), skipped when the folder's manifest and results are the ones already
//! indexed.

use super::db;
use super::record::{read_capture, read_run, CaptureRecord, RunRecord};
use super::RunsDbError;
use rayon::prelude::*;
use rusqlite::{params, Connection, OptionalExtension, TransactionBehavior};
use std::collections::HashSet;
use std::os::unix::fs::MetadataExt;
use std::path::{Path, PathBuf};
use std::time::Duration;

/// How deep `runs index` looks for run and capture folders under each folder it is given.
const MAX_DEPTH: usize = 4;

/// Folders read in parallel before their rows are written (one transaction each).
const BATCH: usize = 256;

/// What an index did.
#[derive(Debug, Clone, Default, serde::Serialize)]
pub struct IndexReport {
    pub catalog: PathBuf,
    /// Run folders written (new or changed).
    pub runs_written: usize,
    /// Run folders already indexed as they are.
    pub runs_unchanged: usize,
    pub captures_written: usize,
    pub captures_unchanged: usize,
    /// Rows of folders that no longer exist, removed.
    pub removed: usize,
    /// A damaged catalog set aside before this index rebuilt it.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub set_aside: Option<PathBuf>,
    /// Folders that could not be read (the rest are indexed).
    pub failed: Vec<FailedFolder>,
}

/// A folder `runs index` could not read, and why.
#[derive(Debug, Clone, serde::Serialize)]
pub struct FailedFolder {
    pub path: PathBuf,
    pub reason: String,
}

/// A folder found under an indexed root.
#[derive(Debug, Clone, PartialEq, Eq)]
pub(crate) enum Found {
    Run(PathBuf),
    Capture(PathBuf),
}

/// The capture folders (a `summary.json`) and run folders (a `manifest.toml` without one) under
/// `root`,
/// `root` itself included, in name order. A run folder's steps are the run's (not listed).
pub(crate) fn discover(root: &Path) -> Vec<Found> {
    let mut out = Vec::new();
    walk(root, 0, &mut out);
    out
}

fn walk(dir: &Path, depth: usize, out: &mut Vec<Found>) {
    // A summary first: `radbench process` writes a manifest of its own beside it.
    if dir.join(super::record::SUMMARY_FILE).is_file() {
        out.push(Found::Capture(dir.to_path_buf()));
        return;
    }
    if dir.join(crate::campaign::MANIFEST_FILE).is_file() {
        out.push(Found::Run(dir.to_path_buf()));
        return;
    }
    if depth >= MAX_DEPTH {
        return;
    }
    let Ok(entries) = std::fs::read_dir(dir) else {
        return;
    };
    let mut children: Vec<PathBuf> = entries
        .filter_map(Result::ok)
        .filter(|e| e.file_type().is_ok_and(|t| t.is_dir()))
        .filter(|e| !e.file_name().to_string_lossy().starts_with('.'))
        .map(|e| e.path())
        .collect();
    children.sort();
    for c in children {
        walk(&c, depth + 1, out);
    }
}

/// Indexes every run and capture folder under `roots` into the catalog at `catalog`: rows of
/// changed folders replaced, of folders gone removed. A catalog that is not a database (or is
/// damaged) is set aside and rebuilt.
pub fn index(catalog: &Path, roots: &[PathBuf]) -> Result<IndexReport, RunsDbError> {
    let mut report = IndexReport {
        catalog: catalog.to_path_buf(),
        ..IndexReport::default()
    };
    let mut conn = match db::open(catalog, Duration::from_secs(10)) {
        Ok(c) => c,
        Err(RunsDbError::Sql { source, .. }) if db::is_corrupt(&source) => {
            report.set_aside = Some(db::set_aside(catalog)?);
            db::open(catalog, Duration::from_secs(10))?
        }
        Err(e) => return Err(e),
    };
    for root in roots {
        if !root.is_dir() {
            return Err(RunsDbError::NotAFolder { path: root.clone() });
        }
    }
    let mut seen_runs = HashSet::new();
    let mut seen_captures = HashSet::new();
    let known = known_runs(&conn).map_err(|e| RunsDbError::sql(catalog, e))?;
    for root in roots {
        let found = discover(root);
        for batch in found.chunks(BATCH) {
            let read: Vec<_> = batch
                .par_iter()
                .map(|f| match f {
                    Found::Run(d) => (d, read_run_unless_known(d, &known)),
                    Found::Capture(d) => (d, read_capture(d).map(|c| c.map(Read::Capture))),
                })
                .collect();
            // One transaction per batch: every run in it whole or not at all, so a kill loses
            // at most this batch, which the next index writes (fewer commits: faster).
            let tx = conn
                .transaction_with_behavior(TransactionBehavior::Immediate)
                .map_err(|e| RunsDbError::sql(catalog, e))?;
            let mut captures = Vec::new();
            for (dir, r) in read {
                match r {
                    Ok(Some(Read::Same(run_id))) => {
                        seen_runs.insert(run_id);
                        report.runs_unchanged += 1;
                    }
                    Ok(Some(Read::Run(run))) => {
                        seen_runs.insert(run.run_id.clone());
                        if write_run_in(&tx, &run)? {
                            report.runs_written += 1;
                        } else {
                            report.runs_unchanged += 1;
                        }
                    }
                    Ok(Some(Read::Capture(c))) => {
                        seen_captures.insert(path_text(&c.dir));
                        captures.push(c);
                    }
                    Ok(None) => {}
                    Err(e) => report.failed.push(FailedFolder {
                        path: dir.clone(),
                        reason: e.to_string(),
                    }),
                }
            }
            tx.commit().map_err(|e| RunsDbError::sql(catalog, e))?;
            // Captures in transactions of their own: their files are hashed first.
            for c in captures {
                if write_capture(&mut conn, &c)? {
                    report.captures_written += 1;
                } else {
                    report.captures_unchanged += 1;
                }
            }
        }
        report.removed += prune(
            &mut conn,
            &super::record::absolute(root),
            &seen_runs,
            &seen_captures,
        )?;
    }
    checkpoint(&conn);
    Ok(report)
}

enum Read {
    Run(Box<RunRecord>),
    /// A run indexed already as its files are (its id).
    Same(String),
    Capture(CaptureRecord),
}

/// (manifest SHA-256, results SHA-256, run id) of every indexed run by folder, but those
/// indexed while `running` (whose status may have changed without a byte of the folder).
type Known = std::collections::HashMap<String, (String, Option<String>, String)>;

fn known_runs(conn: &Connection) -> rusqlite::Result<Known> {
    let mut q = conn.prepare(
        "SELECT dir, manifest_sha256, results_sha256, run_id FROM runs WHERE status <> 'running'",
    )?;
    let rows = q.query_map([], |r| Ok((r.get(0)?, (r.get(1)?, r.get(2)?, r.get(3)?))))?;
    rows.collect()
}

/// The run folder `dir`, read and parsed unless its manifest and results hash to what the
/// catalog holds for that folder (then only its id: re-indexing reads, hashes, skips).
fn read_run_unless_known(dir: &Path, known: &Known) -> Result<Option<Read>, RunsDbError> {
    let abs = super::record::absolute(dir);
    if let Some((manifest, results, id)) = known.get(&path_text(&abs)) {
        let hash = |name: &str| {
            std::fs::read(dir.join(name))
                .ok()
                .map(|b| crate::storage::sha256(&b))
        };
        if hash(crate::campaign::MANIFEST_FILE).as_ref() == Some(manifest)
            && hash(super::record::RESULTS_FILE) == *results
        {
            return Ok(Some(Read::Same(id.clone())));
        }
    }
    Ok(read_run(dir)?.map(|r| Read::Run(Box::new(r))))
}

/// Folds the WAL back into the database file (best effort: a reader may hold it).
fn checkpoint(conn: &Connection) {
    let _ = conn.query_row("PRAGMA wal_checkpoint(PASSIVE)", [], |_| Ok(()));
}

/// A path as the catalog stores it.
pub(crate) fn path_text(p: &Path) -> String {
    p.to_string_lossy().into_owned()
}

/// Rows of run folders under `root` not seen by this index (moved or deleted), removed; the
/// same for capture folders. The count removed.
fn prune(
    conn: &mut Connection,
    root: &Path,
    seen_runs: &HashSet<String>,
    seen_captures: &HashSet<String>,
) -> Result<usize, RunsDbError> {
    let root_text = path_text(root);
    let under = format!("{}/", root_text.trim_end_matches('/'));
    let sql = |e| RunsDbError::sql(Path::new("catalog"), e);
    let tx = conn
        .transaction_with_behavior(TransactionBehavior::Immediate)
        .map_err(sql)?;
    let mut removed = 0;
    {
        let stale_runs: Vec<String> = {
            let mut q = tx
                .prepare_cached(
                    "SELECT run_id FROM runs WHERE dir = ?1 OR substr(dir, 1, length(?2)) = ?2",
                )
                .map_err(sql)?;
            let rows = q
                .query_map(params![root_text, under], |r| r.get::<_, String>(0))
                .map_err(sql)?;
            rows.filter_map(Result::ok)
                .filter(|id| !seen_runs.contains(id))
                .collect()
        };
        for id in stale_runs {
            delete_run(&tx, &id).map_err(sql)?;
            removed += 1;
        }
        let stale_captures: Vec<String> = {
            let mut q = tx
                .prepare_cached(
                    "SELECT dir FROM captures WHERE run_id IS NULL
                     AND (dir = ?1 OR substr(dir, 1, length(?2)) = ?2)",
                )
                .map_err(sql)?;
            let rows = q
                .query_map(params![root_text, under], |r| r.get::<_, String>(0))
                .map_err(sql)?;
            rows.filter_map(Result::ok)
                .filter(|d| !seen_captures.contains(d))
                .collect()
        };
        for dir in stale_captures {
            delete_capture(&tx, &dir).map_err(sql)?;
            removed += 1;
        }
    }
    tx.commit().map_err(sql)?;
    Ok(removed)
}

fn delete_run(tx: &Connection, run_id: &str) -> rusqlite::Result<()> {
    for table in ["targets", "instruments", "assets"] {
        tx.prepare_cached(&format!("DELETE FROM {table} WHERE owner = ?1"))?
            .execute([run_id])?;
    }
    // run_metrics, steps and the steps' captures go with it (ON DELETE CASCADE).
    tx.prepare_cached("DELETE FROM runs WHERE run_id = ?1")?
        .execute([run_id])?;
    Ok(())
}

fn delete_capture(tx: &Connection, dir: &str) -> rusqlite::Result<()> {
    for table in ["targets", "instruments", "assets"] {
        tx.execute(&format!("DELETE FROM {table} WHERE owner = ?1"), [dir])?;
    }
    tx.execute("DELETE FROM captures WHERE dir = ?1", [dir])?;
    Ok(())
}

/// Writes one run's rows in one transaction of its own. `false` when the catalog already held
/// this manifest and these results at this folder.
pub(crate) fn write_run(conn: &mut Connection, run: &RunRecord) -> Result<bool, RunsDbError> {
    let tx = conn
        .transaction_with_behavior(TransactionBehavior::Immediate)
        .map_err(|e| RunsDbError::sql(&run.dir, e))?;
    let written = write_run_in(&tx, run)?;
    tx.commit().map_err(|e| RunsDbError::sql(&run.dir, e))?;
    Ok(written)
}

/// Writes one run's rows (replacing the run's earlier rows) in the transaction `tx`.
fn write_run_in(tx: &Connection, run: &RunRecord) -> Result<bool, RunsDbError> {
    let sql = |e| RunsDbError::sql(&run.dir, e);
    let dir = path_text(&run.dir);
    let known: Option<(String, Option<String>, String, String)> = tx
        .prepare_cached(
            "SELECT manifest_sha256, results_sha256, dir, status FROM runs WHERE run_id = ?1",
        )
        .and_then(|mut q| {
            q.query_row([&run.run_id], |r| {
                Ok((r.get(0)?, r.get(1)?, r.get(2)?, r.get(3)?))
            })
            .optional()
        })
        .map_err(sql)?;
    if known.as_ref().is_some_and(|(m, r, d, status)| {
        *m == run.manifest_sha256
            && *r == run.results_sha256
            && *d == dir
            && status == run.manifest.status.name()
    }) {
        return Ok(false);
    }
    delete_run(tx, &run.run_id).map_err(sql)?;
    // A folder replaced by another run of another id: the old run's rows go.
    let replaced: Vec<String> = {
        let mut q = tx
            .prepare_cached("SELECT run_id FROM runs WHERE dir = ?1")
            .map_err(sql)?;
        let rows = q
            .query_map([&dir], |r| r.get::<_, String>(0))
            .map_err(sql)?;
        rows.filter_map(Result::ok).collect()
    };
    for id in replaced {
        delete_run(tx, &id).map_err(sql)?;
    }
    insert_run(tx, run, &dir).map_err(sql)?;
    Ok(true)
}

fn insert_run(tx: &Connection, run: &RunRecord, dir: &str) -> rusqlite::Result<()> {
    let m = &run.manifest;
    let id = run.run_id.as_str();
    let algorithms = run.algorithms();
    let primary = algorithms.first().copied().unwrap_or("");
    let metrics = run.metrics();
    tx.prepare_cached(
        "INSERT INTO runs (run_id, dir, name, sweep, status, reason, created, updated,
           radbench_version, git_commit, simulated, bench_file, waveforms, algorithms, scope_idn,
           awg_idn, calibration_sha256, steps_total, steps_done, manifest_sha256, results_sha256,
           max_abs_error_m)
         VALUES (?1, ?2, ?3, ?4, ?5, ?6, ?7, ?8, ?9, ?10, ?11, ?12, ?13, ?14, ?15, ?16, ?17, ?18,
           ?19, ?20, ?21, ?22)",
    )?
    .execute(params![
        id,
        dir,
        m.plan.name,
        run.sweep(),
        m.status.name(),
        m.reason,
        m.created,
        m.updated,
        m.radbench_version,
        m.git_commit,
        m.plan.bench.simulated,
        m.plan.bench.file.as_deref().map(path_text),
        run.waveforms().join(","),
        algorithms.join(","),
        m.instruments.as_ref().map(|i| i.scope.as_str()),
        m.instruments.as_ref().map(|i| i.awg.as_str()),
        m.calibration.as_ref().map(|c| c.sha256.as_str()),
        m.steps.len() as i64,
        run.steps_done() as i64,
        run.manifest_sha256,
        run.results_sha256,
        metrics.get("max_abs_error_m"),
    ])?;
    {
        let mut q =
            tx.prepare_cached("INSERT INTO run_metrics (run_id, name, value) VALUES (?1, ?2, ?3)")?;
        for (name, value) in metrics {
            q.execute(params![id, name, value])?;
        }
    }
    if let Some(c) = &m.calibration {
        tx.execute(
            "INSERT INTO calibrations (sha256, mode, path, measured_at) VALUES (?1, ?2, ?3, ?4)
             ON CONFLICT (sha256) DO UPDATE SET mode = excluded.mode, path = excluded.path,
               measured_at = excluded.measured_at",
            params![c.sha256, c.mode.name(), path_text(&c.path), c.measured_at],
        )?;
    }
    if let Some(i) = &m.instruments {
        let mut q =
            tx.prepare_cached("INSERT INTO instruments (owner, role, idn) VALUES (?1, ?2, ?3)")?;
        for (role, idn) in [
            ("awg", Some(&i.awg)),
            ("scope", Some(&i.scope)),
            ("tx", i.tx.as_ref()),
            ("rx", i.rx.as_ref()),
        ] {
            if let Some(idn) = idn {
                q.execute(params![id, role, idn])?;
            }
        }
    }
    insert_steps(tx, run, primary)?;
    insert_run_assets(tx, run)?;
    Ok(())
}

fn insert_steps(tx: &Connection, run: &RunRecord, primary: &str) -> rusqlite::Result<()> {
    let m = &run.manifest;
    let id = run.run_id.as_str();
    let mut step_q = tx.prepare_cached(
        "INSERT INTO steps (run_id, step, algorithm, status, dir, measured_at, label, parameter,
           value, bandwidth_hz, waveform, error_m, truth_error_m, snr_db, width_3db_cm,
           sidelobe_db, missed, resolved, ber)
         VALUES (?1, ?2, ?3, ?4, ?5, ?6, ?7, ?8, ?9, ?10, ?11, ?12, ?13, ?14, ?15, ?16, ?17, ?18,
           ?19)",
    )?;
    let mut target_q = tx.prepare_cached(
        "INSERT INTO targets (owner, step, algorithm, idx, range_m, level_db)
         VALUES (?1, ?2, ?3, ?4, ?5, ?6)",
    )?;
    let mut capture_q = tx.prepare_cached(
        "INSERT INTO captures (dir, origin, run_id, step, measured_at, waveform, algorithm,
           scope_idn, simulated, radbench_version, targets, snr_db, summary_sha256)
         VALUES (?1, 'campaign', ?2, ?3, ?4, ?5, ?6, ?7, ?8, ?9, ?10, ?11, ?12)
         ON CONFLICT (dir) DO UPDATE SET origin = excluded.origin, run_id = excluded.run_id,
           step = excluded.step, measured_at = excluded.measured_at,
           waveform = excluded.waveform, algorithm = excluded.algorithm,
           scope_idn = excluded.scope_idn, simulated = excluded.simulated,
           radbench_version = excluded.radbench_version, targets = excluded.targets,
           snr_db = excluded.snr_db, summary_sha256 = excluded.summary_sha256",
    )?;
    for s in &m.steps {
        let plan_step = m.plan.steps.get(s.index.wrapping_sub(1));
        let nominal = plan_step.map(|p| &p.nominal);
        let waveform = plan_step
            .and_then(|p| m.plan.waveforms.get(p.waveform))
            .map(|w| w.name());
        let result = run
            .results
            .as_ref()
            .and_then(|r| r.steps.iter().find(|r| r.index == s.index));
        let status = match s.status {
            crate::campaign::StepStatus::Done => "done",
            crate::campaign::StepStatus::Pending => "pending",
        };
        let step_dir = path_text(&s.dir);
        let algorithms: Vec<(&str, Option<&crate::campaign::AlgorithmResult>)> = match result {
            Some(r) if !r.algorithms.is_empty() => r
                .algorithms
                .iter()
                .map(|(k, v)| (k.as_str(), Some(v)))
                .collect(),
            _ => vec![("", None)],
        };
        for (name, a) in &algorithms {
            step_q.execute(params![
                id,
                s.index as i64,
                name,
                status,
                step_dir,
                s.measured_at,
                nominal.and_then(|n| n.label.clone()),
                nominal.and_then(|n| n.parameter).map(|p| p.name()),
                nominal.and_then(|n| n.value),
                nominal.map(|n| n.bandwidth_hz),
                waveform,
                a.and_then(|a| a.error_m),
                a.and_then(|a| a.truth_error_m),
                a.and_then(|a| a.snr_db),
                a.and_then(|a| a.width_3db_cm),
                a.and_then(|a| a.sidelobe_db),
                a.map(|a| a.missed as i64),
                a.and_then(|a| a.resolved),
                a.and_then(|a| a.payload.as_ref()).map(|p| p.ber),
            ])?;
            for (k, t) in a
                .map(|a| a.targets.as_slice())
                .unwrap_or(&[])
                .iter()
                .enumerate()
            {
                target_q.execute(params![
                    id,
                    s.index as i64,
                    name,
                    k as i64,
                    t.range_m,
                    t.level_db
                ])?;
            }
        }
        if s.status == crate::campaign::StepStatus::Done {
            let primary_result = result.and_then(|r| r.algorithms.get(primary));
            let summary_sha = s
                .files
                .iter()
                .find(|f| f.path.file_name().is_some_and(|n| n == "summary.json"))
                .map(|f| f.sha256.as_str());
            capture_q.execute(params![
                path_text(&run.dir.join(&s.dir)),
                id,
                s.index as i64,
                s.measured_at,
                waveform,
                primary,
                m.instruments.as_ref().map(|i| i.scope.as_str()),
                m.plan.bench.simulated,
                m.radbench_version,
                primary_result.map(|a| a.targets.len() as i64),
                primary_result.and_then(|a| a.snr_db),
                summary_sha,
            ])?;
        }
    }
    Ok(())
}

fn insert_run_assets(tx: &Connection, run: &RunRecord) -> rusqlite::Result<()> {
    let m = &run.manifest;
    let mut q = tx.prepare_cached(
        "INSERT INTO assets (path, owner, bytes, sha256, mtime_ns) VALUES (?1, ?2, ?3, ?4, NULL)
         ON CONFLICT (path) DO UPDATE SET owner = excluded.owner, bytes = excluded.bytes,
           sha256 = excluded.sha256, mtime_ns = NULL",
    )?;
    let mut put = |rel: &Path, bytes: Option<u64>, sha256: &str| -> rusqlite::Result<()> {
        let path = run.dir.join(rel);
        // Inputs' copies carry no size in the manifest: the file's own.
        let bytes = bytes.or_else(|| std::fs::metadata(&path).ok().map(|m| m.len()));
        q.execute(params![
            path_text(&path),
            run.run_id,
            bytes.unwrap_or(0) as i64,
            sha256
        ])?;
        Ok(())
    };
    put(&m.spec.copy, None, &m.spec.sha256)?;
    if let Some(b) = &m.bench_file {
        put(&b.copy, None, &b.sha256)?;
    }
    for b in &m.bench_catalog {
        put(&b.copy, None, &b.sha256)?;
    }
    if let Some(c) = &m.calibration {
        put(&c.copy, None, &c.sha256)?;
    }
    for f in m
        .files
        .iter()
        .chain(m.steps.iter().flat_map(|s| s.files.iter()))
    {
        put(&f.path, Some(f.bytes), &f.sha256)?;
    }
    Ok(())
}

/// Writes one capture folder's rows in one transaction. `false` when already indexed as it is.
pub(crate) fn write_capture(conn: &mut Connection, c: &CaptureRecord) -> Result<bool, RunsDbError> {
    let sql = |e| RunsDbError::sql(&c.dir, e);
    let dir = path_text(&c.dir);
    let known: Option<Option<String>> = conn
        .query_row(
            "SELECT summary_sha256 FROM captures WHERE dir = ?1",
            [&dir],
            |r| r.get(0),
        )
        .optional()
        .map_err(sql)?;
    if known.flatten().as_deref() == Some(c.summary_sha256.as_str()) {
        return Ok(false);
    }
    // Hashed outside the transaction: a big capture must not hold the catalog's write lock.
    let assets = hash_assets(conn, c);
    let tx = conn
        .transaction_with_behavior(TransactionBehavior::Immediate)
        .map_err(sql)?;
    delete_capture(&tx, &dir).map_err(sql)?;
    let instruments = c.instruments();
    let scope = instruments
        .iter()
        .find(|(role, _)| role == "scope")
        .map(|(_, idn)| idn.clone());
    let targets = c.targets();
    let algorithm = c.algorithm().unwrap_or_default();
    tx.execute(
        "INSERT INTO captures (dir, origin, run_id, step, measured_at, waveform, algorithm,
           scope_idn, simulated, radbench_version, targets, snr_db, summary_sha256)
         VALUES (?1, ?2, NULL, NULL, ?3, ?4, ?5, ?6, ?7, ?8, ?9, ?10, ?11)",
        params![
            dir,
            c.origin,
            c.measured_at,
            c.waveform(),
            algorithm,
            scope,
            c.summary["simulated"].as_bool(),
            c.summary["radbench_version"].as_str(),
            targets.len() as i64,
            c.summary["snr_db"].as_f64(),
            c.summary_sha256,
        ],
    )
    .map_err(sql)?;
    for (role, idn) in &instruments {
        tx.execute(
            "INSERT INTO instruments (owner, role, idn) VALUES (?1, ?2, ?3)",
            params![dir, role, idn],
        )
        .map_err(sql)?;
    }
    for (k, (range_m, level_db)) in targets.iter().enumerate() {
        tx.execute(
            "INSERT INTO targets (owner, step, algorithm, idx, range_m, level_db)
             VALUES (?1, 0, ?2, ?3, ?4, ?5)",
            params![dir, algorithm, k as i64, range_m, level_db],
        )
        .map_err(sql)?;
    }
    for (path, bytes, mtime_ns, sha256) in assets {
        tx.execute(
            "INSERT INTO assets (path, owner, bytes, sha256, mtime_ns) VALUES (?1, ?2, ?3, ?4, ?5)
             ON CONFLICT (path) DO UPDATE SET owner = excluded.owner, bytes = excluded.bytes,
               sha256 = excluded.sha256, mtime_ns = excluded.mtime_ns",
            params![path, dir, bytes, sha256, mtime_ns],
        )
        .map_err(sql)?;
    }
    tx.commit().map_err(sql)?;
    Ok(true)
}

/// (path, bytes, mtime_ns, SHA-256) of a capture's files; a file whose size and modification
/// time match its row keeps the hash it has (captures are large: hashed once).
fn hash_assets(conn: &Connection, c: &CaptureRecord) -> Vec<(String, i64, i64, String)> {
    let mut out = Vec::new();
    for path in c.files() {
        let Ok(meta) = std::fs::metadata(&path) else {
            continue;
        };
        let text = path_text(&path);
        let bytes = meta.len() as i64;
        let mtime_ns = meta.mtime() * 1_000_000_000 + meta.mtime_nsec();
        let cached: Option<String> = conn
            .query_row(
                "SELECT sha256 FROM assets WHERE path = ?1 AND bytes = ?2 AND mtime_ns = ?3",
                params![text, bytes, mtime_ns],
                |r| r.get(0),
            )
            .optional()
            .ok()
            .flatten();
        let sha = match cached {
            Some(s) => s,
            None => match crate::storage::sha256_file(&path) {
                Ok(s) => s,
                Err(_) => continue,
            },
        };
        out.push((text, bytes, mtime_ns, sha));
    }
    out
}
