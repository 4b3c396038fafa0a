//! `radbench process INPUT...`: saved captures through the measurement pipeline again, with the
//! options they were captured with or any others, in parallel on every core.

use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};
use radbench::exit::{Classified, ExitClass};
use radbench::in_memory::{compute, folder_names, recorded_data_hashes, recorded_for, ProcessArgs};
use radbench::measure;

use radbench::measure::ProcessOverrides;
use radbench::measure::{Source, WaveformChoice};
use radbench::storage::StorageError;
use radbench::storage::{write_group_open, OpenGroup};
use rayon::prelude::*;
use serde_json::{json, Value};
use std::collections::HashMap;
use std::path::{Path, PathBuf};

#[derive(Debug, clap::Args)]
pub struct Args {
    /// Captures: capture folders, run folders (every step), .sigmf-meta files, or .trc pairs
    /// (the I file then the Q file).
    #[arg(
        value_name = "INPUT",
        required_unless_present = "from_catalog",
        conflicts_with = "from_catalog"
    )]
    pub inputs: Vec<PathBuf>,
    /// Process the captures the run catalog selects instead of INPUTs: terms joined by `and`,
    /// `NAME = VALUE` for since, until, kind, waveform, scope, calibration, status, origin, or
    /// `METRIC OP NUMBER` (e.g. "waveform = msk-lfm and since = 2026-12-01"; "all": every
    /// capture). Outputs are addressed by content in --out (default: processed/ beside the
    /// catalog): a rerun skips what is done. docs/catalog.md.
    #[arg(long, value_name = "QUERY")]
    pub from_catalog: Option<String>,
    /// The catalog --from-catalog reads and registers its outputs in (default
    /// runs/catalog.sqlite).
    #[arg(long, value_name = "FILE", requires = "from_catalog")]
    pub catalog: Option<PathBuf>,
    /// Output folder (default runs/<UTC time>-process); one sub-folder per capture. Must not
    /// exist yet or be empty (with --from-catalog: a store that grows, one folder per input,
    /// options and version).
    #[arg(long, value_name = "DIR")]
    pub out: Option<PathBuf>,
    /// Print one JSON object instead of the text report.
    #[arg(long)]
    pub json: bool,
    /// Worker threads (default: every core).
    #[arg(long, value_name = "N")]
    pub jobs: Option<usize>,
    /// Also write each capture's link figure as `link.png` (`link.svg` is always written). Off by
    /// default: rendering and compressing that bitmap is about an eighth of re-processing.
    #[arg(long)]
    pub link_png: bool,
    /// The processing options (the library's: the Python package parses them too).
    #[command(flatten)]
    pub options: ProcessArgs,
}

/// What happened to one capture.
struct Outcome {
    source: String,
    result: Result<(PathBuf, Value), anyhow::Error>,
}

fn process_one(
    source: &Source,
    recorded: &HashMap<PathBuf, String>,
    out: &Path,
    waveform: &WaveformChoice,
    overrides: &ProcessOverrides,
    args: &Args,
) -> Result<(PathBuf, Value, OpenGroup), anyhow::Error> {
    let (loaded, r, sources) = compute(
        source,
        recorded_for(source, recorded),
        waveform,
        overrides,
        args.options.background.as_deref(),
        args.options.trigger_offset,
    )?;
    // One write group: each file's writeback starts as it is written; the files are synced,
    // renamed into place and their folder synced once when the group is finished (by a
    // finisher, while this thread goes on with the next capture).
    let ((files, summary), open) =
        write_group_open(|| measure::write_reprocessed(out, &sources, &loaded, &r, args.link_png))?;
    Ok((files.dir, summary, open))
}

/// Threads that finish the captures' write groups (sync, rename, folder sync): they only wait
/// for the disk, so the workers' cores go on computing. A few, so that syncs of several
/// captures can be in flight together when the disk is slow.
struct Finishers {
    groups: Option<std::sync::mpsc::SyncSender<(usize, OpenGroup)>>,
    threads: Vec<std::thread::JoinHandle<Vec<(usize, StorageError)>>>,
}

/// Finisher threads.
const FINISHERS: usize = 4;

/// Groups waiting for a finisher before a worker waits too (and its open files with them).
const GROUPS_QUEUED: usize = 16;

impl Finishers {
    fn start() -> Finishers {
        let (groups, queue) = std::sync::mpsc::sync_channel::<(usize, OpenGroup)>(GROUPS_QUEUED);
        let queue = std::sync::Arc::new(std::sync::Mutex::new(queue));
        let threads = (0..FINISHERS)
            .map(|_| {
                let queue = queue.clone();
                std::thread::spawn(move || {
                    let mut failed = Vec::new();
                    loop {
                        let next = queue.lock().unwrap_or_else(|p| p.into_inner()).recv();
                        let Ok((index, group)) = next else {
                            return failed;
                        };
                        if let Err(e) = group.finish() {
                            failed.push((index, e));
                        }
                    }
                })
            })
            .collect();
        Finishers {
            groups: Some(groups),
            threads,
        }
    }

    /// Hands capture `index`'s group to a finisher (finishes it here should none be left).
    fn finish(&self, index: usize, group: OpenGroup) -> Result<(), StorageError> {
        let rejected = match &self.groups {
            Some(groups) => match groups.send((index, group)) {
                Ok(()) => return Ok(()),
                Err(std::sync::mpsc::SendError((_, group))) => group,
            },
            None => group,
        };
        rejected.finish().map(drop)
    }

    /// Waits until every group handed over is finished; the captures whose files failed.
    fn join(mut self) -> Vec<(usize, StorageError)> {
        self.groups.take();
        self.threads
            .drain(..)
            .flat_map(|t| t.join().unwrap_or_default())
            .collect()
    }
}

pub(crate) fn run(args: Args, _global: &super::global::Global) -> anyhow::Result<()> {
    if let Some(query) = &args.from_catalog {
        return super::process_catalog::run(&super::process_catalog::Request {
            query,
            catalog: args.catalog.clone(),
            out: args.out.clone(),
            jobs: args.jobs,
            json: args.json,
            link_png: args.link_png,
            options: &args.options,
        });
    }
    let out = args
        .out
        .clone()
        .unwrap_or_else(|| super::capture::default_out("process"));
    if out.exists() {
        let empty = out.is_dir()
            && std::fs::read_dir(&out)
                .map(|mut d| d.next().is_none())
                .unwrap_or(false);
        if !empty {
            return Err(radbench::exit::bad_input(format!(
                "--out {}: exists already; process writes a new folder and never over what is \
                 there (give a new folder)",
                out.display()
            )));
        }
    }
    let measured = args.options.measure_reference(&out)?;
    let (waveform, overrides) = args.options.settings(measured)?;
    let discovered = measure::discover(&args.inputs);
    let sources: Vec<&Source> = discovered.iter().filter_map(|d| d.as_ref().ok()).collect();
    let names = folder_names(&sources);
    let recorded = recorded_data_hashes(&sources);
    let jobs = args.jobs.unwrap_or(0);
    if args.jobs == Some(0) || jobs > 256 {
        return Err(radbench::exit::bad_input(format!(
            "--jobs {jobs}: give 1 to 256 worker threads"
        )));
    }
    let pool = rayon::ThreadPoolBuilder::new().num_threads(jobs).build()?;
    let bar = if std::io::IsTerminal::is_terminal(&std::io::stderr()) && !args.json {
        ProgressBar::with_draw_target(Some(sources.len() as u64), ProgressDrawTarget::stderr())
    } else {
        ProgressBar::hidden()
    };
    bar.set_style(
        ProgressStyle::with_template("{bar:30} {pos}/{len} captures, {per_sec}, eta {eta}")
            .unwrap_or_else(|_| ProgressStyle::default_bar()),
    );
    let started = std::time::Instant::now();
    let finishers = Finishers::start();
    let mut outcomes: Vec<Outcome> = pool.install(|| {
        sources
            .par_iter()
            .zip(names.par_iter())
            .enumerate()
            .with_max_len(1)
            .map(|(index, (source, name))| {
                let result = process_one(
                    source,
                    &recorded,
                    &out.join(name),
                    &waveform,
                    &overrides,
                    &args,
                )
                .and_then(|(dir, summary, group)| {
                    finishers.finish(index, group)?;
                    Ok((dir, summary))
                });
                bar.inc(1);
                Outcome {
                    source: source.label(),
                    result,
                }
            })
            .collect()
    });
    // A capture is done when its files are durable and in place.
    for (index, e) in finishers.join() {
        outcomes[index].result = Err(e.into());
    }
    bar.finish_and_clear();
    let elapsed = started.elapsed().as_secs_f64();
    let mut failures: Vec<(String, anyhow::Error)> = discovered
        .into_iter()
        .filter_map(Result::err)
        .map(|e| {
            (
                e.path.display().to_string(),
                radbench::exit::bad_input(e.reason),
            )
        })
        .collect();
    let mut done = Vec::new();
    for o in outcomes {
        match o.result {
            Ok((dir, summary)) => done.push((o.source, dir, summary)),
            Err(e) => failures.push((o.source, e)),
        }
    }
    // Every output is durable and in place: into the run catalog (bounded; never the error).
    if !done.is_empty() {
        super::runs::register_now(&out);
    }
    report(&args, &out, &done, &failures, elapsed)?;
    if failures.is_empty() {
        return Ok(());
    }
    // The worst class among the failures decides the exit code: bad input before processing.
    let class = failures
        .iter()
        .map(|(_, e)| radbench::classify(e))
        .min_by_key(|c| c.code())
        .unwrap_or(ExitClass::Processing);
    Err(anyhow::Error::new(Classified {
        class,
        message: format!(
            "{} of {} inputs failed ({}): {}",
            failures.len(),
            failures.len() + done.len(),
            if done.is_empty() {
                "nothing was written".to_string()
            } else {
                format!("the others' results are in {}", out.display())
            },
            failures
                .iter()
                .map(|(s, e)| format!("{s}: {}", radbench::exit::render(e)))
                .collect::<Vec<_>>()
                .join("; ")
        ),
    }))
}

fn report(
    args: &Args,
    out: &Path,
    done: &[(String, PathBuf, Value)],
    failures: &[(String, anyhow::Error)],
    elapsed_s: f64,
) -> anyhow::Result<()> {
    if args.json {
        let doc = json!({
            "out": out,
            "processed": done.iter().map(|(s, dir, summary)| json!({
                "source": s,
                "dir": dir,
                "summary": summary,
            })).collect::<Vec<_>>(),
            "failed": failures.iter().map(|(s, e)| json!({
                "source": s,
                "error": radbench::exit::render(e),
                "exit_code": radbench::classify(e).code(),
            })).collect::<Vec<_>>(),
            "seconds": elapsed_s,
        });
        return super::terminal::out(&doc.to_string());
    }
    let mut text = String::new();
    for (s, dir, summary) in done {
        let targets = super::capture::target_ranges(&summary["targets"]);
        text.push_str(&format!(
            "{s}: {} {}: targets {} -> {}\n",
            summary["waveform"].as_str().unwrap_or("?"),
            summary["algorithm"].as_str().unwrap_or("?"),
            if targets.is_empty() {
                "none".into()
            } else {
                targets.join(", ")
            },
            dir.display()
        ));
        for w in summary["warnings"].as_array().into_iter().flatten() {
            if let Some(w) = w.as_str() {
                text.push_str(&format!("{s}: warning: {w}\n"));
            }
        }
    }
    for (s, e) in failures {
        text.push_str(&format!("{s}: FAILED: {}\n", radbench::exit::render(e)));
    }
    let n = done.len() + failures.len();
    text.push_str(&format!(
        "{} of {n} captures processed in {elapsed_s:.2} s ({:.1} per second)",
        done.len(),
        done.len() as f64 / elapsed_s.max(1e-9)
    ));
    super::terminal::out(&text)
}
