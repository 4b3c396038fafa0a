//! `radbench process --from-catalog QUERY`: the captures the run catalog selects, processed on
//! `--jobs` threads into folders addressed by content (`radbench::archive`), a rerun skipping
//! what is done; the outputs registered back in the catalog.

use radbench::archive::{self, ArchiveSettings, UnitDone, UnitStatus};
use radbench::runs_db;
use rayon::prelude::*;
use serde_json::json;
use std::path::{Path, PathBuf};

/// What `radbench process --from-catalog` was given.
pub(crate) struct Request<'a> {
    pub(crate) query: &'a str,
    pub(crate) catalog: Option<PathBuf>,
    pub(crate) out: Option<PathBuf>,
    pub(crate) jobs: Option<usize>,
    pub(crate) json: bool,
    pub(crate) link_png: bool,
    pub(crate) options: &'a radbench::in_memory::ProcessArgs,
}

pub(crate) fn run(args: &Request<'_>) -> anyhow::Result<()> {
    let query = args.query;
    let catalog = args
        .catalog
        .clone()
        .unwrap_or_else(runs_db::default_catalog);
    let out = args
        .out
        .clone()
        .unwrap_or_else(|| catalog.parent().unwrap_or(Path::new(".")).join("processed"));
    let jobs = args.jobs.unwrap_or(0);
    if args.jobs == Some(0) || jobs > 256 {
        return Err(radbench::exit::bad_input(format!(
            "--jobs {jobs}: give 1 to 256 worker threads"
        )));
    }
    let settings = ArchiveSettings::from_args(args.options, args.link_png)?;
    let units = archive::units(&catalog, query)?;
    std::fs::create_dir_all(&out)?;
    let started = std::time::Instant::now();
    let pool = rayon::ThreadPoolBuilder::new().num_threads(jobs).build()?;
    let outcomes: Vec<anyhow::Result<UnitDone>> = pool.install(|| {
        units
            .par_iter()
            .with_max_len(1)
            .map(|u| archive::process_unit(u, &out, &settings, None))
            .collect()
    });
    let elapsed = started.elapsed().as_secs_f64();
    archive::sweep_partials(&out);
    let mut done = Vec::new();
    let mut failed = Vec::new();
    for o in outcomes {
        match o {
            Ok(d) => done.push(d),
            Err(e) => failed.push(e),
        }
    }
    // Registered back, bounded: a catalog that cannot take them costs a warning, never the
    // results (the folders are the truth).
    let rows: Vec<_> = done.iter().map(|d| d.row(&settings)).collect();
    if let Err(e) = runs_db::record_processed(&catalog, &rows) {
        eprintln!(
            "warning: the outputs were not registered in {} ({e}); they are complete in {}",
            catalog.display(),
            out.display()
        );
    }
    report(args, &out, &settings, &done, &failed, elapsed)?;
    if failed.is_empty() {
        return Ok(());
    }
    let class = failed
        .iter()
        .map(radbench::classify)
        .min_by_key(|c| c.code())
        .unwrap_or(radbench::exit::ExitClass::Processing);
    Err(anyhow::Error::new(radbench::exit::Classified {
        class,
        message: format!(
            "{} of {} captures failed: {}",
            failed.len(),
            failed.len() + done.len(),
            failed
                .iter()
                .map(radbench::exit::render)
                .collect::<Vec<_>>()
                .join("; ")
        ),
    }))
}

fn count(done: &[UnitDone], status: UnitStatus) -> usize {
    done.iter().filter(|d| d.status == status).count()
}

fn report(
    args: &Request<'_>,
    out: &Path,
    settings: &ArchiveSettings,
    done: &[UnitDone],
    failed: &[anyhow::Error],
    elapsed_s: f64,
) -> anyhow::Result<()> {
    let written = count(done, UnitStatus::Written);
    let skipped = count(done, UnitStatus::Skipped);
    if args.json {
        let doc = json!({
            "out": out,
            "options_sha256": settings.options_sha256(),
            "radbench_version": archive::VERSION,
            "written": written,
            "skipped": skipped,
            "failed": failed.iter().map(radbench::exit::render).collect::<Vec<_>>(),
            "units": done,
            "seconds": elapsed_s,
        });
        return super::terminal::out(&doc.to_string());
    }
    let mut text = String::new();
    for d in done.iter().filter(|d| d.status == UnitStatus::Written) {
        text.push_str(&format!(
            "{} -> {}\n",
            d.unit.input_dir.display(),
            d.out_dir.display()
        ));
    }
    for e in failed {
        text.push_str(&format!("FAILED: {}\n", radbench::exit::render(e)));
    }
    text.push_str(&format!(
        "{} captures: processed {written}, skipped {skipped} (done already), failed {} in \
         {elapsed_s:.2} s ({:.1} per second) -> {}",
        done.len() + failed.len(),
        failed.len(),
        written as f64 / elapsed_s.max(1e-9),
        out.display()
    ));
    super::terminal::out(&text)
}
