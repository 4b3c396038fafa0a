//! `radbench process INPUT...`: saved captures through the measurement pipeline again, with the
//! options they were captured with or any others, in parallel on every core.

use super::args::WaveformArgs;
use crate::campaign::manifest::Manifest;
use crate::exit::{Classified, ExitClass};
use crate::measure::options::{
    Algorithm, DetectorName, FftPrecisionName, ProcessOverrides, WindowName,
};
use crate::measure::pipeline::Pipeline;
use crate::measure::record::{self, SourceFile};
use crate::measure::reprocess::{
    self, Loaded, Record, Repetition, Reprocessed, Source, WaveformChoice,
};
use crate::measure::response::CorrectionMode;
use crate::measure::MeasureError;
use crate::storage::atomic::{write_group_open, OpenGroup};
use crate::storage::StorageError;
use crate::waveform::spec::WaveformKind;
use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};
use rayon::prelude::*;
use serde_json::{json, Value};
use std::cell::RefCell;
use std::collections::{BTreeSet, HashMap};
use std::path::{Path, PathBuf};

#[derive(Debug, clap::Args)]
pub struct Args {
    /// Captures: capture folders, run folders (every step), .sigmf-meta files, or .trc pairs
    /// (the I file then the Q file).
    #[arg(value_name = "INPUT", required = true)]
    pub inputs: Vec<PathBuf>,
    /// Output folder (default runs/<UTC time>-process); one sub-folder per capture. Must not
    /// exist yet or be empty.
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
    /// The waveform of captures radbench did not make (overrides what a radbench capture recorded).
    #[arg(long, value_parser = super::args::listed::<WaveformKind>())]
    pub waveform: Option<WaveformKind>,
    #[command(flatten)]
    pub waveform_args: WaveformArgs,
    /// Seed of the transmitted PRBS bits (captures radbench did not make).
    #[arg(long)]
    pub seed: Option<u64>,
    /// The transmitted payload text (captures radbench did not make).
    #[arg(long, value_name = "TEXT")]
    pub payload: Option<String>,
    /// Time from the trigger to the first sample, seconds (default: what the file says, else 0).
    #[arg(long, value_name = "S", allow_hyphen_values = true)]
    pub trigger_offset: Option<f64>,
    /// Subtract this capture (.sigmf-meta) instead of the one the capture recorded.
    #[arg(long, value_name = "FILE", conflicts_with = "no_background")]
    pub background: Option<PathBuf>,
    /// Do not subtract the background the capture recorded.
    #[arg(long)]
    pub no_background: bool,
    #[arg(long, value_parser = super::args::listed::<Algorithm>())]
    pub algorithm: Option<Algorithm>,
    /// MUSIC sub-vector (covariance) length M.
    #[arg(long = "m", value_name = "M")]
    pub music_m: Option<usize>,
    /// Number of targets for MUSIC/root-MUSIC/ESPRIT.
    #[arg(long = "p", value_name = "P")]
    pub music_p: Option<usize>,
    /// Forward smoothing only for MUSIC.
    #[arg(long)]
    pub forward_only: bool,
    #[arg(long, value_name = "K")]
    pub zero_pad: Option<usize>,
    #[arg(long, value_parser = super::args::listed::<WindowName>(), value_name = "NAME")]
    pub window: Option<WindowName>,
    #[arg(long, value_parser = super::args::listed::<FftPrecisionName>(), value_name = "P")]
    pub fft_precision: Option<FftPrecisionName>,
    /// Report the on-grid peak (no sub-sample interpolation).
    #[arg(long)]
    pub no_interpolation: bool,
    #[arg(long, value_parser = super::args::listed::<DetectorName>(), value_name = "NAME")]
    pub detector: Option<DetectorName>,
    #[arg(long, value_name = "P", allow_hyphen_values = true)]
    pub pfa: Option<f64>,
    #[arg(long, value_name = "METRES", allow_hyphen_values = true)]
    pub min_separation: Option<f64>,
    /// The detector's chain floor, dB (see `capture --help`).
    #[arg(long, value_name = "DB", allow_hyphen_values = true)]
    pub chain_floor_db: Option<f64>,
    #[arg(long, value_name = "METRES", allow_hyphen_values = true)]
    pub min_range: Option<f64>,
    #[arg(long, value_name = "METRES", allow_hyphen_values = true)]
    pub max_range: Option<f64>,
    /// The bench's fixed delay, seconds (default: what the capture was processed with).
    #[arg(long, value_name = "S", allow_hyphen_values = true)]
    pub system_delay: Option<f64>,
    /// Receive correction: none, or rx (DC, I/Q imbalance and the chain's response, from a
    /// calibration). Default: what the capture was processed with; rx with --calibration.
    #[arg(long, value_parser = super::args::listed::<CorrectionMode>())]
    pub correction: Option<CorrectionMode>,
    /// A response calibration (`radbench calibrate response` wrote it) to correct with, for
    /// captures made without one; with --reference-range, a capture of one reference pillar
    /// from which the response is measured (written to OUT/reference-response.toml).
    #[arg(long, value_name = "FILE")]
    pub calibration: Option<PathBuf>,
    /// The reference pillar's true range in the --calibration capture, metres.
    #[arg(long, value_name = "METRES", allow_hyphen_values = true)]
    pub reference_range: Option<f64>,
}

impl Args {
    /// The waveform and the processing options asked for (`out`: where a response measured with
    /// `--reference-range` is stored).
    pub(super) fn settings(
        &self,
        out: &Path,
    ) -> anyhow::Result<(WaveformChoice, ProcessOverrides)> {
        let waveform = self.waveform()?;
        let mut overrides = self.overrides();
        overrides.correction = self.correction(out)?;
        overrides.require_correction =
            self.correction == Some(CorrectionMode::Rx) && self.calibration.is_none();
        Ok((waveform, overrides))
    }

    fn overrides(&self) -> ProcessOverrides {
        ProcessOverrides {
            algorithm: self.algorithm,
            music_m: self.music_m,
            music_p: self.music_p.map(Some),
            forward_backward: self.forward_only.then_some(false),
            zero_pad: self.zero_pad,
            window: self.window,
            fft_precision: self.fft_precision,
            interpolate: self.no_interpolation.then_some(false),
            system_delay_s: self.system_delay,
            min_range_m: self.min_range,
            max_range_m: self.max_range,
            detector: self.detector,
            pfa: self.pfa,
            min_separation_m: self.min_separation.map(Some),
            chain_floor_db: self.chain_floor_db,
            awg_amplitude_vpp: None,
            correction: None,
            keep_background: !self.no_background,
            require_correction: false,
        }
    }

    /// The correction asked for: `None` keeps what each capture recorded.
    fn correction(
        &self,
        out: &Path,
    ) -> anyhow::Result<Option<Option<crate::measure::response::CorrectionUsed>>> {
        use crate::measure::response::Calibration;
        if let Some(r) = self.reference_range {
            crate::measure::calibration::check(r, 2.0)?;
            let Some(capture) = &self.calibration else {
                return Err(crate::exit::bad_input(
                    "--reference-range needs --calibration CAPTURE: the capture of one reference \
                     pillar to measure the response from",
                ));
            };
            if self.correction == Some(CorrectionMode::None) {
                return Err(crate::exit::bad_input(
                    "--correction none with --calibration: give one or the other",
                ));
            }
            std::fs::create_dir_all(out)?;
            let cal = crate::measure::response_from_capture::calibrate_from_capture(
                capture,
                r,
                crate::measure::calibration::default_gate_s(r),
                &out.join("reference-response.toml"),
            )?;
            eprintln!(
                "response measured from {} (reference at {r} m): side-lobe {:.2} -> {:.2} dB; \
                 stored in {}",
                capture.display(),
                cal.header.reference.sidelobe_db_before.unwrap_or(f64::NAN),
                cal.header.reference.sidelobe_db_after.unwrap_or(f64::NAN),
                cal.path.display()
            );
            return Ok(Some(Some(cal.used())));
        }
        if matches!(
            self.correction,
            Some(CorrectionMode::Tx | CorrectionMode::Both)
        ) {
            return Err(crate::exit::bad_input(
                "--correction: none or rx (a capture already made cannot be pre-distorted; one \
                 captured with tx or both is processed as it was unless --correction is given)",
            ));
        }
        Ok(match (self.correction, &self.calibration) {
            (Some(CorrectionMode::None), Some(_)) => {
                return Err(crate::exit::bad_input(
                    "--correction none with --calibration: give one or the other",
                ))
            }
            (Some(CorrectionMode::None), None) => Some(None),
            (_, Some(path)) => Some(Some(Calibration::load(path)?.used())),
            // rx without a file: what each capture recorded (checked per capture).
            (_, None) => None,
        })
    }

    fn waveform(&self) -> anyhow::Result<WaveformChoice> {
        let spec = match self.waveform {
            Some(w) => Some(self.waveform_args.spec(w)?),
            None => {
                let given = format!("{:?}", self.waveform_args);
                if given != format!("{:?}", WaveformArgs::default()) {
                    return Err(crate::exit::bad_input(
                        "waveform parameters need --waveform msk-lfm|ofdm to say which waveform \
                         they belong to",
                    ));
                }
                None
            }
        };
        Ok(WaveformChoice {
            spec,
            seed: self.seed,
            payload: self.payload.as_ref().map(|p| p.as_bytes().to_vec()),
        })
    }
}

/// What happened to one capture.
struct Outcome {
    source: String,
    result: Result<(PathBuf, Value), anyhow::Error>,
}

thread_local! {
    /// Pipelines built on this worker, by what they were built for: a batch of captures of one
    /// waveform builds its filters, plans and tables once per thread.
    static PIPELINES: RefCell<Vec<(String, Pipeline)>> = const { RefCell::new(Vec::new()) };
}

/// Most pipelines a worker keeps (a batch rarely mixes more waveforms and options).
const PIPELINES_PER_WORKER: usize = 4;

/// The SHA-256 that run manifests recorded for the captures' data files, by path: the run
/// folder of each capture's folder, where it has a manifest radbench reads. A capture whose data
/// matches its recorded hash is not hashed a second time against the recording's own SHA-512
/// (see `read_sigmf_stored`). A manifest that cannot be read only means no such shortcut.
pub(super) fn recorded_data_hashes(sources: &[&Source]) -> HashMap<PathBuf, String> {
    let runs: BTreeSet<&Path> = sources
        .iter()
        .filter_map(|s| match s {
            Source::Sigmf { data, .. } => data.parent()?.parent(),
            Source::TrcPair { .. } => None,
        })
        .filter(|run| run.join("manifest.toml").is_file())
        .collect();
    let mut hashes = HashMap::new();
    for run in runs {
        let Ok(manifest) = Manifest::load(run) else {
            continue;
        };
        for file in manifest.steps.into_iter().flat_map(|step| step.files) {
            hashes.insert(run.join(&file.path), file.sha256);
        }
    }
    hashes
}

/// The recorded SHA-256 of `source`'s data, if its run recorded one.
pub(super) fn recorded_for<'a>(
    source: &Source,
    recorded: &'a HashMap<PathBuf, String>,
) -> Option<&'a str> {
    match source {
        Source::Sigmf { data, .. } => recorded.get(data).map(String::as_str),
        Source::TrcPair { .. } => None,
    }
}

/// One capture through the pipeline (one of this thread's pipelines when it was built for the
/// same transmission and options): the capture read, the result and its files' hashes.
pub(super) fn compute(
    source: &Source,
    recorded_sha256: Option<&str>,
    waveform: &WaveformChoice,
    overrides: &ProcessOverrides,
    background: Option<&Path>,
    trigger_offset: Option<f64>,
) -> Result<(Loaded<Repetition>, Reprocessed, Vec<SourceFile>), anyhow::Error> {
    let loaded = reprocess::load_for_processing(source, trigger_offset, recorded_sha256)?;
    let resolved = reprocess::resolve(&loaded, waveform, overrides, background)?;
    let hashes = reprocess::source_hashes(source, &loaded.sha256)?;
    let r = on_cached_pipeline(&loaded, resolved)?;
    let sources: Vec<SourceFile> = hashes
        .into_iter()
        .map(|(path, sha256)| SourceFile { path, sha256 })
        .collect();
    Ok((loaded, r, sources))
}

/// `loaded` processed as `resolved` says, on this thread's pipeline for it (built when missing).
pub(super) fn on_cached_pipeline<R: Record>(
    loaded: &Loaded<R>,
    resolved: reprocess::Resolved,
) -> Result<Reprocessed, anyhow::Error> {
    let rate = loaded.repetitions[0].sample_rate_hz();
    let key = serde_json::to_string(&json!({
        "tx": resolved.tx.describe(),
        "options": resolved.options,
        "period": resolved.period,
        "rate": rate,
    }))?;
    let r = PIPELINES.with(|cell| -> Result<_, MeasureError> {
        let mut cache = cell.borrow_mut();
        let index = match cache.iter().position(|(k, _)| *k == key) {
            Some(i) => i,
            None => {
                if cache.len() >= PIPELINES_PER_WORKER {
                    cache.remove(0);
                }
                cache.push((key.clone(), reprocess::pipeline(&resolved, rate)?));
                cache.len() - 1
            }
        };
        reprocess::process(&mut cache[index].1, loaded, resolved)
    })?;
    Ok(r)
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
        args.background.as_deref(),
        args.trigger_offset,
    )?;
    // One write group: each file's writeback starts as it is written; the files are synced,
    // renamed into place and their folder synced once when the group is finished (by a
    // finisher, while this thread goes on with the next capture).
    let ((files, summary), open) =
        write_group_open(|| record::write_reprocessed(out, &sources, &loaded, &r, args.link_png))?;
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

/// Folder names for the sources: their labels, made unique.
pub(super) fn folder_names(sources: &[&Source]) -> Vec<String> {
    let mut names: Vec<String> = Vec::new();
    for s in sources {
        let base = s.label();
        let mut name = base.clone();
        let mut k = 2;
        while names.contains(&name) {
            name = format!("{base}-{k}");
            k += 1;
        }
        names.push(name);
    }
    names
}

pub(crate) fn run(args: Args, _global: &super::Global) -> anyhow::Result<()> {
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
            return Err(crate::exit::bad_input(format!(
                "--out {}: exists already; process writes a new folder and never over what is \
                 there (give a new folder)",
                out.display()
            )));
        }
    }
    let (waveform, overrides) = args.settings(&out)?;
    let discovered = reprocess::discover(&args.inputs);
    let sources: Vec<&Source> = discovered.iter().filter_map(|d| d.as_ref().ok()).collect();
    let names = folder_names(&sources);
    let recorded = recorded_data_hashes(&sources);
    let jobs = args.jobs.unwrap_or(0);
    if args.jobs == Some(0) || jobs > 256 {
        return Err(crate::exit::bad_input(format!(
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
                crate::exit::bad_input(e.reason),
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
    report(&args, &out, &done, &failures, elapsed)?;
    if failures.is_empty() {
        return Ok(());
    }
    // The worst class among the failures decides the exit code: bad input before processing.
    let class = failures
        .iter()
        .map(|(_, e)| super::classify(e))
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
                .map(|(s, e)| format!("{s}: {}", crate::exit::render(e)))
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
                "error": crate::exit::render(e),
                "exit_code": super::classify(e).code(),
            })).collect::<Vec<_>>(),
            "seconds": elapsed_s,
        });
        return super::terminal::out(&doc.to_string());
    }
    let mut text = String::new();
    for (s, dir, summary) in done {
        let targets = target_ranges(&summary["targets"]);
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
        text.push_str(&format!("{s}: FAILED: {}\n", crate::exit::render(e)));
    }
    let n = done.len() + failures.len();
    text.push_str(&format!(
        "{} of {n} captures processed in {elapsed_s:.2} s ({:.1} per second)",
        done.len(),
        done.len() as f64 / elapsed_s.max(1e-9)
    ));
    super::terminal::out(&text)
}

/// The `range_m` of each target in a summary's (or a ground truth's) `targets` list, as text.
pub(super) fn target_ranges(targets: &serde_json::Value) -> Vec<String> {
    targets
        .as_array()
        .map(|t| {
            t.iter()
                .filter_map(|x| x["range_m"].as_f64())
                .map(|r| format!("{r:.4} m"))
                .collect()
        })
        .unwrap_or_default()
}
