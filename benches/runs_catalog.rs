//! The run catalog at archive scale (docs/catalog.md): 10 000 generated run folders indexed from
//! scratch, indexed again (nothing changed), then the 95th percentile of `runs query` over them
//! (each query opens the catalog, as a command does). The archive is deleted at the end.
//!
//! With `RADBENCH_BIN=path/to/radbench` it also times `radbench runs query` end to end, a fresh
//! process per query printing JSON (as a user or a script runs it). `KEEP_CATALOG=FILE` keeps a
//! copy of the catalog.
//!
//! Run: `cargo bench --bench runs_catalog` (`RUNS=N` for another archive size; `--profile dev`
//! reuses the test build).

#[path = "../tests/support/runs_archive.rs"]
mod runs_archive;

use radbench::runs_db::{self, RunFilter};
use std::time::Instant;

fn main() {
    let n: u64 = std::env::var("RUNS")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(10_000);
    // Beside the build, not in /tmp (a shared disk); removed when this ends, even on a panic.
    let base = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("target");
    let tmp = tempfile::Builder::new()
        .prefix("runs-catalog-bench")
        .tempdir_in(&base)
        .expect("a scratch folder");
    let archive = tmp.path().join("archive");
    let t = Instant::now();
    runs_archive::write_archive(&archive, n, 1);
    println!(
        "generated {n} run folders in {:.1} s",
        t.elapsed().as_secs_f64()
    );

    let catalog = tmp.path().join("catalog.sqlite");
    let t = Instant::now();
    let report = runs_db::index(&catalog, std::slice::from_ref(&archive)).expect("index");
    let full = t.elapsed().as_secs_f64();
    assert_eq!(report.runs_written as u64, n);
    println!("full index: {full:.2} s ({:.0} runs/s)", n as f64 / full);

    let t = Instant::now();
    let again = runs_db::index(&catalog, std::slice::from_ref(&archive)).expect("index again");
    assert_eq!(again.runs_unchanged as u64, n);
    println!(
        "index again (unchanged): {:.2} s",
        t.elapsed().as_secs_f64()
    );

    let filters = [
        RunFilter::default(),
        RunFilter {
            kind: Some("accuracy".into()),
            ..RunFilter::default()
        },
        RunFilter {
            conditions: runs_db::parse_where("max_abs_error_m < 1e-3").unwrap(),
            ..RunFilter::default()
        },
        RunFilter {
            kind: Some("accuracy".into()),
            scope: Some("uxr".into()),
            since: Some(runs_db::parse_time("--since", "2026-03-01").unwrap()),
            conditions: runs_db::parse_where("max_abs_error_m < 1e-3 and steps = 4").unwrap(),
            ..RunFilter::default()
        },
        RunFilter {
            calibration: Some("aa11".into()),
            limit: Some(20),
            ..RunFilter::default()
        },
    ];
    let names = [
        "every run",
        "--kind accuracy",
        "--where max_abs_error_m < 1e-3",
        "--kind --scope --since --where (2 terms)",
        "--calibration aa11 --limit 20",
    ];
    let mut all = Vec::new();
    for (f, name) in filters.iter().zip(names) {
        let mut times = Vec::new();
        let mut rows = 0;
        for _ in 0..40 {
            let t = Instant::now();
            rows = runs_db::runs(&catalog, f).expect("query").len();
            times.push(t.elapsed().as_secs_f64() * 1e3);
        }
        all.extend_from_slice(&times);
        let (p50, p95) = percentiles(&mut times);
        println!("query {name:<42} {rows:>6} rows: p50 {p50:.1} ms, p95 {p95:.1} ms");
    }
    let (p50, p95) = percentiles(&mut all);
    println!("query, all 200 over {n} runs: p50 {p50:.1} ms, p95 {p95:.1} ms");
    if let Some(bin) = std::env::var_os("RADBENCH_BIN") {
        command_queries(std::path::Path::new(&bin), &catalog);
    }
    // `KEEP_CATALOG=FILE`: the catalog copied out, to profile queries on (the folders go).
    if let Some(keep) = std::env::var_os("KEEP_CATALOG") {
        std::fs::copy(&catalog, keep).expect("the catalog copied");
    }
    let t = Instant::now();
    let points = runs_db::trend(
        &catalog,
        "accuracy",
        "max_abs_error_m",
        &RunFilter::default(),
    )
    .expect("trend");
    println!(
        "trend accuracy max_abs_error_m: {} points in {:.1} ms",
        points.len(),
        t.elapsed().as_secs_f64() * 1e3
    );
}

/// `radbench runs query` with each filter's flags, 40 fresh processes each, their output
/// (`--json`) read whole: p50 and p95 of the wall time.
fn command_queries(bin: &std::path::Path, catalog: &std::path::Path) {
    let queries: [&[&str]; 5] = [
        &[],
        &["--kind", "accuracy"],
        &["--where", "max_abs_error_m < 1e-3"],
        &[
            "--kind",
            "accuracy",
            "--scope",
            "uxr",
            "--since",
            "2026-03-01",
            "--where",
            "max_abs_error_m < 1e-3 and steps = 4",
        ],
        &["--calibration", "aa11", "--limit", "20"],
    ];
    let mut all = Vec::new();
    for flags in queries {
        let mut times = Vec::new();
        let mut bytes = 0;
        for _ in 0..40 {
            let t = Instant::now();
            let out = std::process::Command::new(bin)
                .args(["runs", "query", "--json", "--catalog"])
                .arg(catalog)
                .args(flags)
                .output()
                .expect("radbench runs");
            assert!(out.status.success(), "{flags:?}: {out:?}");
            bytes = out.stdout.len();
            times.push(t.elapsed().as_secs_f64() * 1e3);
        }
        all.extend_from_slice(&times);
        let (p50, p95) = percentiles(&mut times);
        let name = format!("radbench runs query {}", flags.join(" "));
        println!("{name:<60} {bytes:>8} B: p50 {p50:.1} ms, p95 {p95:.1} ms");
    }
    let (p50, p95) = percentiles(&mut all);
    println!("radbench runs query, all 200 (fresh processes): p50 {p50:.1} ms, p95 {p95:.1} ms");
}

/// (p50, p95) of `times`, ms.
fn percentiles(times: &mut [f64]) -> (f64, f64) {
    times.sort_by(f64::total_cmp);
    let p = |q: f64| times[((times.len() - 1) as f64 * q).round() as usize];
    (p(0.5), p(0.95))
}
