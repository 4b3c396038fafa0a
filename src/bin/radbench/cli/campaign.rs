//! `radbench campaign`: run a campaign spec, resume an interrupted run, print a spec to start
//! from, write a run's report again, run the thesis' lab chapter. Parses, calls `campaign`, prints.

use radbench::campaign;
use radbench::campaign::Status;
use radbench::campaign::{AlgorithmResult, TargetResult, Truth};
use radbench::campaign::{BenchInfo, Nominal, Step, WaveformCost};
use radbench::campaign::{CampaignError, SpecFile};
use radbench::campaign::{Finished, NewRun, Observer, Retrying, StepDone, Summary};
use radbench::exit::bad_input;
use radbench::measure::Bench;
use radbench::measure::Interrupt;
use radbench::measure::MeasureError;
use serde::Serialize;
use serde_json::json;
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

#[derive(Debug, clap::Args)]
pub struct Args {
    #[command(subcommand)]
    pub command: Command,
}

#[derive(Debug, clap::Subcommand)]
pub enum Command {
    /// Run a campaign spec: every step measured into one run folder (manifest, captures,
    /// results.json, report).
    Run(RunArgs),
    /// Continue an interrupted run: completed steps (files intact) are skipped.
    Resume(ResumeArgs),
    /// Print a commented campaign spec to start from.
    New(NewArgs),
    /// Write a run folder's report.md and report.html again from its manifest and results.json.
    Report(ReportArgs),
    /// Run the thesis' lab chapter (4.4.1-4.5.2) on the built-in mock lab and compare.
    #[command(name = "thesis-lab")]
    ThesisLab(ThesisLabArgs),
}

#[derive(Debug, clap::Args)]
pub struct RunArgs {
    /// The campaign spec (TOML); `radbench campaign new KIND` prints one.
    #[arg(value_name = "SPEC.toml")]
    pub spec: PathBuf,
    /// Bench file (overrides the spec's [bench] file); without either, the built-in mock lab.
    #[arg(long, value_name = "FILE")]
    pub bench: Option<PathBuf>,
    /// Run folder (default runs/<UTC time>-<campaign name>); must be new or empty.
    #[arg(long, value_name = "DIR")]
    pub out: Option<PathBuf>,
    /// Explicit permit to switch on the AWG outputs and the Tx/Rx for each step's capture.
    #[arg(long)]
    pub allow_rf: bool,
    /// Print every step, what will be sent and the estimated duration; touch no instrument.
    #[arg(long)]
    pub dry_run: bool,
    /// JSON Lines on stdout: one "step" event per step and a last "done" event.
    #[arg(long)]
    pub json: bool,
    /// Times a step is measured again after a transient fault (a lost connection, a timeout, a
    /// missing trigger, a Gotmic CRC or identity failure); overrides the spec's `[run] retries`
    /// (default 2).
    #[arg(long, value_name = "N")]
    pub retries: Option<usize>,
    /// A program to run when the run ends (complete, failed or stopped), with RADBENCH_RUN_DIR,
    /// RADBENCH_STATUS and RADBENCH_SUMMARY in its environment; overrides the spec's `[run]
    /// notify`. Bounded by `[run] notify_timeout_s` (default 30 s); never changes the exit code.
    #[arg(long, value_name = "PROGRAM")]
    pub notify: Option<String>,
    #[command(flatten)]
    pub timeout: super::args::TimeoutArgs,
    #[command(flatten)]
    pub live: super::live::LiveArgs,
}

#[derive(Debug, clap::Args)]
pub struct ResumeArgs {
    /// The run folder of an interrupted run.
    #[arg(value_name = "RUN_DIR")]
    pub run_dir: PathBuf,
    /// Explicit permit to switch on the AWG outputs and the Tx/Rx for each step's capture.
    #[arg(long)]
    pub allow_rf: bool,
    /// Continue even when the instruments, the bench's calibration or the response calibration
    /// file differ from the run's (recorded in the manifest; the run keeps its own copy of the
    /// response calibration).
    #[arg(long)]
    pub force: bool,
    /// JSON Lines on stdout, as for `campaign run`.
    #[arg(long)]
    pub json: bool,
    /// Times a step is measured again after a transient fault, from now on (as for `campaign
    /// run`); without it, the run's own (`[run] retries` or the first session's --retries).
    #[arg(long, value_name = "N")]
    pub retries: Option<usize>,
    /// A program to run when the run ends (complete, failed or stopped), with RADBENCH_RUN_DIR,
    /// RADBENCH_STATUS and RADBENCH_SUMMARY in its environment; overrides the spec's `[run]
    /// notify`. Bounded by `[run] notify_timeout_s` (default 30 s); never changes the exit code.
    #[arg(long, value_name = "PROGRAM")]
    pub notify: Option<String>,
    #[command(flatten)]
    pub timeout: super::args::TimeoutArgs,
    #[command(flatten)]
    pub live: super::live::LiveArgs,
}

/// `--retries N`, checked: 0 ..= the most retries of a step.
fn retries(n: Option<usize>) -> anyhow::Result<Option<usize>> {
    match n {
        Some(n) if n > campaign::MAX_RETRIES => Err(bad_input(format!(
            "--retries {n}: allowed 0..={}",
            campaign::MAX_RETRIES
        ))),
        n => Ok(n),
    }
}

#[derive(Debug, clap::Args)]
pub struct NewArgs {
    /// accuracy | resolution | single-target | music | link
    #[arg(value_name = "KIND", value_parser = clap::builder::PossibleValuesParser::new(campaign::kinds()))]
    pub kind: String,
}

#[derive(Debug, clap::Args)]
pub struct ReportArgs {
    #[arg(value_name = "RUN_DIR")]
    pub run_dir: PathBuf,
    /// Render a results.json edited since the run (its SHA-256 no longer the manifest's) and
    /// record the new hashes in the manifest; without it such a file is refused.
    #[arg(long)]
    pub force: bool,
}

#[derive(Debug, clap::Args)]
pub struct ThesisLabArgs {
    /// Folder for the run folders (default runs/<UTC time>-thesis-lab).
    #[arg(long, value_name = "DIR")]
    pub out: Option<PathBuf>,
    /// The mock lab's chain: ideal, thesis-lab (a realistic E-band bench, see
    /// examples/scene.toml) or a scene file whose [chain] and [impairments] are used. Every row is
    /// also run on the ideal chain, for comparison, and (a chain that is not ideal) on this chain
    /// with the receive correction, calibrated in-process on a pillar at 1 m.
    #[arg(
        long,
        value_name = "ideal|thesis-lab|SCENE",
        default_value = "thesis-lab"
    )]
    pub chain: String,
    /// One JSON object instead of the table.
    #[arg(long)]
    pub json: bool,
}

pub(crate) fn run(args: Args, global: &super::global::Global) -> anyhow::Result<()> {
    match args.command {
        Command::New(a) => {
            let text = campaign::template(&a.kind).ok_or_else(|| {
                bad_input(format!(
                    "campaign new {}: allowed: {}",
                    a.kind,
                    campaign::kinds().join(", ")
                ))
            })?;
            print!("{text}");
            Ok(())
        }
        Command::Report(a) => {
            let (path, note) = campaign::rewrite(&a.run_dir, a.force)?;
            if let Some(note) = note {
                eprintln!("note: {note}");
            }
            println!("report: {}", path.display());
            println!("report: {}", a.run_dir.join(campaign::HTML_FILE).display());
            Ok(())
        }
        Command::Run(a) => super::global::runtime()?.block_on(run_spec(a, global)),
        Command::Resume(a) => super::global::runtime()?.block_on(resume(a)),
        Command::ThesisLab(a) => super::global::runtime()?.block_on(thesis_lab(a)),
    }
}

/// Prints step events (JSON Lines or one text line per step) and notes on stderr.
struct Printer {
    json: bool,
}

/// `{"event":"start",...}` before a step is captured.
#[derive(Serialize)]
struct StartEvent<'a> {
    event: &'static str,
    index: usize,
    of: usize,
    nominal: &'a Nominal,
}

/// `{"event":"step",...}` once a step is done.
#[derive(Serialize)]
struct StepEvent<'a> {
    event: &'static str,
    index: usize,
    of: usize,
    nominal: &'a Nominal,
    /// The primary algorithm's targets.
    targets: &'a [TargetResult],
    error_m: Option<f64>,
    primary: &'a str,
    algorithms: &'a BTreeMap<String, AlgorithmResult>,
    #[serde(skip_serializing_if = "Option::is_none")]
    truth: Option<&'a Truth>,
    repetitions: usize,
    skipped: bool,
    dir: &'a Path,
}

/// `{"event":"retry",...}` when a step is about to be measured again after a transient fault.
#[derive(Serialize)]
struct RetryEvent<'a> {
    event: &'static str,
    index: usize,
    of: usize,
    attempt: usize,
    retries: usize,
    instrument: &'a str,
    fault: &'a str,
    at: &'a str,
    safe_state: &'a str,
    wait_s: f64,
}

/// The last line: `{"event":"done","dir","status","summary"}`.
#[derive(Serialize)]
struct DoneEvent<'a> {
    event: &'static str,
    dir: &'a Path,
    status: &'static str,
    summary: &'a Summary,
    /// What the whole run must be read with (the bench is not calibrated).
    warnings: Vec<String>,
}

fn line(v: &impl Serialize) -> String {
    serde_json::to_string(v)
        .unwrap_or_else(|e| format!("{{\"event\":\"error\",\"error\":\"{e}\"}}"))
}

impl Observer for Printer {
    fn step_starting(&mut self, step: &Step, of: usize, _bench: &Bench) {
        if self.json {
            println!(
                "{}",
                line(&StartEvent {
                    event: "start",
                    index: step.index,
                    of,
                    nominal: &step.nominal,
                })
            );
        }
    }

    fn step_done(&mut self, done: &StepDone<'_>) {
        let r = done.result;
        if self.json {
            let primary = r.algorithms.get(done.primary);
            println!(
                "{}",
                line(&StepEvent {
                    event: "step",
                    index: r.index,
                    of: done.of,
                    nominal: &r.nominal,
                    targets: primary.map_or(&[], |a| a.targets.as_slice()),
                    error_m: primary.and_then(|a| a.error_m),
                    primary: done.primary,
                    algorithms: &r.algorithms,
                    truth: r.truth.as_ref(),
                    repetitions: r.repetitions,
                    skipped: done.skipped,
                    dir: &done.dir,
                })
            );
        } else {
            println!("{}", step_line(done));
        }
    }

    fn note(&mut self, text: &str) {
        eprintln!("{text}");
    }

    fn retrying(&mut self, retry: &Retrying<'_>) {
        let r = retry.record;
        if self.json {
            println!(
                "{}",
                line(&RetryEvent {
                    event: "retry",
                    index: r.step,
                    of: retry.of,
                    attempt: r.attempt,
                    retries: retry.retries,
                    instrument: &r.instrument,
                    fault: &r.fault,
                    at: &r.at,
                    safe_state: &r.safe_state,
                    wait_s: r.wait_s,
                })
            );
        }
        eprintln!("{}", retry.text);
    }
}

fn step_line(done: &StepDone<'_>) -> String {
    let r = done.result;
    let mut parts = Vec::new();
    for (name, a) in &r.algorithms {
        let ranges: Vec<String> = a
            .targets
            .iter()
            .map(|t| format!("{:.4}", t.range_m))
            .collect();
        let mut s = format!(
            "{name} {} m",
            if ranges.is_empty() {
                "none".into()
            } else {
                ranges.join(" / ")
            }
        );
        if let Some(e) = a.error_m {
            s += &format!(" (error {:+.3} mm", e * 1e3);
            if let Some(g) = a.error_on_grid_m {
                s += &format!(", on the grid {:+.3} mm", g * 1e3);
            }
            s += ")";
        }
        if a.missed > 0 {
            s += &format!(
                " (MISSED {} of the nominal targets: nothing within a resolution cell)",
                a.missed
            );
        }
        if let Some(res) = a.resolved {
            s += if res { " resolved" } else { " not resolved" };
        }
        if let Some(p) = &a.payload {
            s += &format!(", {} bit errors in {}", p.bit_errors, p.bits);
        }
        parts.push(s);
    }
    format!(
        "step {}/{} {}{}: {}",
        r.index,
        done.of,
        r.nominal.describe(),
        if done.skipped {
            " (measured before, kept)"
        } else {
            ""
        },
        parts.join("; ")
    )
}

/// What a run folder's whole run must be read with, from its manifest (its bench's plan).
fn run_warnings(dir: &Path) -> Vec<String> {
    campaign::Manifest::load(dir)
        .map(|m| m.plan.bench.warnings())
        .unwrap_or_default()
}

/// Prints the end of a run and turns a stop into the command's error.
fn conclude(finished: Finished, json: bool) -> anyhow::Result<()> {
    if json {
        println!(
            "{}",
            line(&DoneEvent {
                event: "done",
                dir: &finished.dir,
                status: finished.status.name(),
                summary: &finished.summary,
                warnings: run_warnings(&finished.dir),
            })
        );
    } else {
        let s = &finished.summary;
        let mm = |v: Option<f64>| v.map_or("-".into(), |x| format!("{:.3} mm", x * 1e3));
        match finished.status {
            Status::Complete => println!(
                "complete: {} steps ({} measured, {} kept from before); largest error {} (vs \
                 ground truth {})",
                s.steps,
                s.measured,
                s.skipped,
                mm(s.max_abs_error_m),
                mm(s.max_abs_truth_error_m)
            ),
            _ => println!(
                "interrupted at step {} of {}: {}\ncontinue with: radbench campaign resume {} \
                 --allow-rf",
                s.stopped_at_step.unwrap_or(s.done + 1),
                s.steps,
                s.reason.as_deref().unwrap_or("?"),
                finished.dir.display()
            ),
        }
        println!("results: {}", s.results.display());
        println!("report: {}", s.report.display());
        println!(
            "report: {}",
            finished.dir.join(campaign::HTML_FILE).display()
        );
        println!("run folder: {}", finished.dir.display());
    }
    match finished.stopped {
        Some(e) => Err(e.into()),
        None => Ok(()),
    }
}

async fn run_spec(a: RunArgs, global: &super::global::Global) -> anyhow::Result<()> {
    let spec = SpecFile::load(&a.spec)?;
    let bench = BenchInfo::load(&spec, a.bench.as_deref())?;
    let catalog = bench.catalog()?;
    let mut plan = campaign::plan(&spec, &bench)?;
    if let Some(n) = retries(a.retries)? {
        plan.retries = n;
    }
    if a.dry_run && a.live.live {
        return Err(bad_input(
            "--live: a dry run measures nothing to show; drop --dry-run or --live",
        ));
    }
    if a.dry_run {
        let prepared = campaign::prepare_all(&plan, &bench, &catalog).await?;
        let costs: Vec<WaveformCost> = prepared.costs();
        if a.json {
            let steps: Vec<_> = (0..plan.steps.len())
                .map(|k| {
                    json!({
                        "index": plan.steps[k].index,
                        "nominal": plan.steps[k].nominal,
                        "waveform": plan.steps[k].waveform,
                        "noise_seed": plan.steps[k].noise_seed,
                        "uploads": plan.uploads_at(k),
                        "estimate_s": plan.estimate_step_s(k, &costs, plan.uploads_at(k)),
                        "estimate_bytes": plan.estimate_step_bytes(k, &costs),
                    })
                })
                .collect();
            let total: f64 = (0..plan.steps.len())
                .map(|k| plan.estimate_step_s(k, &costs, plan.uploads_at(k)))
                .sum();
            println!(
                "{}",
                json!({
                    "event": "plan",
                    "plan": plan,
                    "steps": steps,
                    "estimate_s": total,
                    "estimate_bytes": plan.estimate_bytes_from(0, &costs),
                })
            );
        } else {
            print!("{}", plan.describe(&costs));
            println!("dry run: nothing was sent to any instrument");
        }
        return Ok(());
    }
    if !a.allow_rf {
        return Err(MeasureError::NoPermit {
            run: "campaign's steps",
        }
        .into());
    }
    a.timeout.apply()?;
    let manual = super::manual_front::confirm(bench.file.as_ref().map(|(_, f)| f), "campaign run")?;
    let interrupt = Interrupt::listen()?;
    let out = a.out.clone().unwrap_or_else(|| {
        // The name becomes part of a folder name: nothing but letters, digits, `.`, `_`, `-`,
        // and at most 64 of them (a file name holds 255 bytes).
        let name: String = plan
            .name
            .chars()
            .take(64)
            .map(|c| {
                if c.is_ascii_alphanumeric() || "._-".contains(c) {
                    c
                } else {
                    '-'
                }
            })
            .collect();
        super::capture::default_out(&name)
    });
    if plan.bench.file.is_none() {
        eprintln!(
            "no bench file: running on the built-in mock lab (simulated, in-process on 127.0.0.1)"
        );
    }
    let warnings = plan.bench.warnings();
    for w in &warnings {
        eprintln!("warning: {w}");
    }
    let mut printer = Printer { json: a.json };
    let live = a.live.start(&interrupt, a.json).await?;
    if let Some(l) = &live {
        use crate::live::Event;
        l.send(Event::Set("kind", json!("campaign")));
        l.send(Event::Set(
            "title",
            json!(format!("campaign {}", plan.name)),
        ));
        l.send(Event::Set("of", json!(plan.steps.len())));
        let parameter = plan.steps.first().and_then(|s| s.nominal.parameter);
        l.send(Event::Set(
            "plot_axes",
            super::live::campaign_axes(parameter.map(|p| p.name())),
        ));
        for w in warnings {
            l.send(Event::Log("warning", w));
        }
    }
    let stop = interrupt.clone();
    // The run catalog hears of each step after it is durable, on its own thread.
    let mut registering = super::runs::Registering::new(Some(&mut printer), &out);
    let mut observer = super::live::LiveObserver {
        inner: &mut registering,
        live: live.clone(),
    };
    let notify = notify_of(plan.notify.as_ref(), a.notify.as_deref(), &out);
    let finished = campaign::start(
        NewRun {
            spec,
            bench,
            plan,
            out,
            journal: global.trace_io.clone(),
            permit: manual.permit(),
            interrupt,
            input: None,
        },
        &mut observer,
    )
    .await;
    registering.settle(finished.as_ref().ok().map(|f| f.dir.as_path()));
    live_end(live, finished, &stop, a.json, notify).await
}

/// Who a run tells at its end: `--notify PROGRAM` over the plan's `[run] notify`, and the run
/// folder.
fn notify_of(
    plan: Option<&campaign::notify::NotifyPlan>,
    flag: Option<&str>,
    dir: &Path,
) -> Option<(campaign::notify::NotifyPlan, PathBuf)> {
    let n = match (flag, plan) {
        (Some(p), plan) => campaign::notify::NotifyPlan {
            command: vec![p.to_string()],
            workdir: None,
            timeout_s: plan.map_or(campaign::notify::DEFAULT_NOTIFY_TIMEOUT_S, |n| n.timeout_s),
        },
        (None, Some(n)) if !n.command.is_empty() => n.clone(),
        (None, _) => return None,
    };
    Some((n, dir.to_path_buf()))
}

/// Runs the notify program for how the run ended (its own outcome is logged, never returned).
async fn tell(
    notify: Option<(campaign::notify::NotifyPlan, PathBuf)>,
    finished: &Result<Finished, CampaignError>,
) {
    let Some((n, dir)) = notify else { return };
    let (status, summary) = match finished {
        Ok(f) => {
            let s = &f.summary;
            let status = match (&f.stopped, f.stopped.as_ref().and_then(|e| e.signal())) {
                (None, _) => "complete",
                (Some(_), Some(_)) => "stopped",
                (Some(_), None) => "failed",
            };
            let largest = s.max_abs_error_m.map_or(String::new(), |e| {
                format!(", largest error {:.3} mm", e * 1e3)
            });
            let why = f
                .stopped
                .as_ref()
                .map_or(String::new(), |e| format!(": {e}"));
            (
                status,
                format!(
                    "{}: {} of {} steps done{largest}{why}",
                    s.name, s.done, s.steps
                ),
            )
        }
        Err(e) => (
            if e.signal().is_some() {
                "stopped"
            } else {
                "failed"
            },
            e.to_string(),
        ),
    };
    let summary: String = summary
        .lines()
        .next()
        .unwrap_or("")
        .chars()
        .take(500)
        .collect();
    let line = campaign::notify::notify(&n, &dir, status, &summary).await;
    eprintln!("{line}");
}

/// Tells the live view (and the notify program) how the run ended, then concludes as without
/// them.
async fn live_end(
    live: Option<crate::live::Live>,
    finished: Result<Finished, CampaignError>,
    interrupt: &Interrupt,
    json: bool,
    notify: Option<(campaign::notify::NotifyPlan, PathBuf)>,
) -> anyhow::Result<()> {
    tell(notify, &finished).await;
    let status = match &finished {
        Ok(f) => f.status.name(),
        Err(_) if interrupt.received().is_some() => "interrupted",
        Err(_) => "failed",
    };
    let error = finished.as_ref().err().map(|e| anyhow::anyhow!("{e}"));
    let error = error.or_else(|| {
        finished
            .as_ref()
            .ok()
            .and_then(|f| f.stopped.as_ref())
            .map(|e| anyhow::anyhow!("{e}"))
    });
    super::live::finish(live, status, error.as_ref()).await;
    conclude(finished?, json)
}

async fn resume(a: ResumeArgs) -> anyhow::Result<()> {
    if !a.allow_rf {
        return Err(MeasureError::NoPermit {
            run: "campaign's steps",
        }
        .into());
    }
    a.timeout.apply()?;
    let retries = retries(a.retries)?;
    // The run's bench file, as its manifest names it (a missing manifest is the resume's error).
    let manifest = campaign::Manifest::load(&a.run_dir).ok();
    let notify = notify_of(
        manifest.as_ref().and_then(|m| m.plan.notify.as_ref()),
        a.notify.as_deref(),
        &a.run_dir,
    );
    let bench_file = manifest.and_then(|m| m.plan.bench.file);
    let manual = super::manual_front::confirm_file(bench_file.as_deref(), "campaign resume")?;
    let interrupt = Interrupt::listen()?;
    let mut printer = Printer { json: a.json };
    let live = a.live.start(&interrupt, a.json).await?;
    if let Some(l) = &live {
        use crate::live::Event;
        l.send(Event::Set("kind", json!("campaign")));
        l.send(Event::Set(
            "title",
            json!(format!("campaign resume {}", a.run_dir.display())),
        ));
        l.send(Event::Set("plot_axes", super::live::campaign_axes(None)));
    }
    for w in run_warnings(&a.run_dir) {
        eprintln!("warning: {w}");
        super::live::send(live.as_ref(), crate::live::Event::Log("warning", w));
    }
    let stop = interrupt.clone();
    let mut registering = super::runs::Registering::new(Some(&mut printer), &a.run_dir);
    let mut observer = super::live::LiveObserver {
        inner: &mut registering,
        live: live.clone(),
    };
    let finished = match campaign::resume(
        &a.run_dir,
        manual.permit(),
        a.force,
        retries,
        interrupt,
        None,
        &mut observer,
    )
    .await
    {
        Err(CampaignError::Complete { dir }) => {
            eprintln!(
                "{}: the run is already complete; nothing to do",
                dir.display()
            );
            if a.json {
                // A script reading the events still gets its last one.
                println!(
                    "{}",
                    json!({"event": "done", "dir": dir, "status": "complete", "nothing_to_do": true})
                );
            }
            super::live::finish(live, "complete", None).await;
            return Ok(());
        }
        other => other,
    };
    registering.settle(Some(&a.run_dir));
    live_end(live, finished, &stop, a.json, notify).await
}

async fn thesis_lab(a: ThesisLabArgs) -> anyhow::Result<()> {
    let interrupt = Interrupt::listen()?;
    let out = a
        .out
        .clone()
        .unwrap_or_else(|| super::capture::default_out("thesis-lab"));
    let chain = campaign::LabChain::parse(&a.chain).map_err(bad_input)?;
    let mut quiet = Notes;
    let rows = campaign::thesis_lab(&out, &chain, &interrupt, &mut quiet).await?;
    if a.json {
        println!("{}", json!({"rows": rows, "dir": out}));
    } else {
        print!("{}", campaign::lab_table(&rows));
        println!("run folders: {}", out.display());
        // One run (and report) per section of the lab chapter.
        let mut reports: Vec<_> = std::fs::read_dir(&out)
            .into_iter()
            .flatten()
            .filter_map(Result::ok)
            .flat_map(|chain| std::fs::read_dir(chain.path()).into_iter().flatten())
            .filter_map(Result::ok)
            .map(|e| e.path().join("report.html"))
            .filter(|p| p.is_file())
            .collect();
        reports.sort();
        for report in reports {
            println!("report: {}", report.display());
        }
    }
    Ok(())
}

/// Notes on stderr, nothing else.
struct Notes;

impl Observer for Notes {
    fn note(&mut self, text: &str) {
        eprintln!("{text}");
    }
}
