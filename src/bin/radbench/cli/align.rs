//! `radbench align`: captures again and again and shows the strongest target's range, its level
//! and its distance to `--target-range`, so a pillar can be placed to a millimetre. RF is on only
//! while capturing; the safe state runs after each capture and on every exit.

use super::args::WaveformArgs;
use super::capture::{bench_source, journal, open_bench};
use super::live::{self as live_cli, LiveArgs};
use super::repeat::{stopped_between, truth_ranges};
use crate::live::{Event, Live};
use radbench::driver::RfPermit;
use radbench::exit::bad_input;
use radbench::measure;
use radbench::measure::Bench;
use radbench::measure::Interrupt;
use radbench::measure::MeasureError;
use radbench::measure::{AwgLink, ScopeLink};
use radbench::measure::{CaptureRequest, Rig};
use radbench::measure::{CorrectionMode, ProcessingChoices};
use radbench::waveform::WaveformKind;
use serde_json::json;
use std::path::PathBuf;

#[derive(Debug, clap::Args)]
pub struct Args {
    /// Bench file (TOML); without one, a simulated bench (mock_lab) in-process on 127.0.0.1.
    #[arg(long, value_name = "FILE")]
    pub bench: Option<PathBuf>,
    /// Where the target should stand, metres: each capture prints its distance from here.
    #[arg(long, value_name = "METRES", allow_hyphen_values = true)]
    pub target_range: Option<f64>,
    #[arg(long, value_parser = super::args::listed::<WaveformKind>(), default_value = "msk-lfm")]
    pub waveform: WaveformKind,
    #[command(flatten)]
    pub waveform_args: WaveformArgs,
    #[command(flatten)]
    pub processing: ProcessingChoices,
    /// Explicit permit to switch on the AWG outputs and the Tx/Rx while each capture runs.
    #[arg(long)]
    pub allow_rf: bool,
    /// One JSON object per capture on stdout instead of the text line.
    #[arg(long)]
    pub json: bool,
    /// Stop after N captures (default: until Ctrl-C or the live page's Stop).
    #[arg(long, value_name = "N")]
    pub count: Option<u64>,
    /// Marker-triggered repetitions per capture, averaged coherently.
    #[arg(long, value_name = "N", default_value_t = 1)]
    pub repetitions: usize,
    /// Longest wait for the marker-triggered acquisition, seconds.
    #[arg(long, default_value_t = 10.0, allow_hyphen_values = true)]
    pub wait: f64,
    #[command(flatten)]
    pub timeout: super::args::TimeoutArgs,
    /// Built-in mock lab only: its scene file (see examples/scene.toml).
    #[arg(long, value_name = "FILE")]
    pub scene: Option<PathBuf>,
    /// Built-in mock lab only: transport to the AWG.
    #[arg(long, value_parser = super::args::listed::<AwgLink>(), default_value = "hislip")]
    pub awg_transport: AwgLink,
    /// Built-in mock lab only: transport to the scope.
    #[arg(long, value_parser = super::args::listed::<ScopeLink>(), default_value = "vicp")]
    pub scope_transport: ScopeLink,
    #[command(flatten)]
    pub scope_model: super::scope_model::ScopeModelArgs,
    #[command(flatten)]
    pub live: LiveArgs,
}

pub(crate) fn run(args: Args, global: &super::global::Global) -> anyhow::Result<()> {
    super::global::runtime()?.block_on(run_async(args, global))
}

async fn run_async(args: Args, global: &super::global::Global) -> anyhow::Result<()> {
    let kind = args.waveform;
    let waveform = args.waveform_args.spec(kind)?;
    if let Some(r) = args.target_range {
        if !r.is_finite() || r < 0.0 {
            return Err(bad_input(format!(
                "--target-range {r}: allowed: a distance in metres, 0 or more"
            )));
        }
    }
    if args.count == Some(0) {
        return Err(bad_input("--count 0: allowed: 1 or more captures"));
    }
    if !args.allow_rf {
        return Err(MeasureError::NoPermit { run: "alignment" }.into());
    }
    args.timeout.apply()?;
    let source = args.scope_model.apply(bench_source(
        args.bench.as_deref(),
        args.scene.as_deref(),
        args.awg_transport,
        args.scope_transport,
    )?)?;
    let manual = super::manual_front::confirm_file(args.bench.as_deref(), "alignment")?;
    let interrupt = Interrupt::listen()?;
    let bench = open_bench(source, args.json).await?;
    let mut options = args.processing.options(kind);
    bench.file.processing_of_this_bench(&mut options);
    let processing = &args.processing;
    let calibration = super::capture::resolve_correction(
        processing.correction,
        processing.calibration.as_deref(),
        &bench,
    )?;
    let mode = processing.correction.unwrap_or(CorrectionMode::Rx);
    options.correction = calibration.as_ref().map(|c| c.used_as(mode));
    if let Some(w) = bench.file.uncalibrated_warning() {
        // Once here; --json repeats it in each capture's "warnings".
        eprintln!("warning: {w}");
    }
    let request = CaptureRequest {
        waveform,
        payload: None,
        seed: 1,
        options,
        tx_off: false,
        wait_s: args.wait,
        background: None,
    };
    let live = args.live.start(&interrupt, args.json).await?;
    if let Some(l) = &live {
        l.send(Event::Set("kind", json!("align")));
        l.send(Event::Set("title", json!("align")));
    }
    live_cli::bench_warnings(live.as_ref(), &bench);
    let permit = manual.permit();
    let result = captures(
        &args,
        global,
        &bench,
        &request,
        (&interrupt, &permit),
        live.as_ref(),
    )
    .await;
    live_cli::finish(
        live,
        live_cli::status_of(&result, &interrupt),
        result.as_ref().err(),
    )
    .await;
    result
}

async fn captures(
    args: &Args,
    global: &super::global::Global,
    bench: &Bench,
    request: &CaptureRequest,
    (interrupt, permit): (&Interrupt, &RfPermit),
    live: Option<&Live>,
) -> anyhow::Result<()> {
    let catalog = bench.file.catalog()?;
    let mut prepared = measure::prepare(bench, &catalog, request).await?;
    let mut rig = Rig::connect(bench, &catalog, journal(global)?).await?;
    let mut k = 0u64;
    while args.count.is_none_or(|n| k < n) {
        if let Some(e) = stopped_between(&rig, interrupt, &format!("after {k} captures")).await {
            return Err(e);
        }
        k += 1;
        let m = rig
            .measure(bench, &mut prepared, args.repetitions, permit, interrupt)
            .await?;
        let p = &m.processing.processed;
        let strongest = p
            .targets
            .iter()
            .max_by(|a, b| a.level_db.total_cmp(&b.level_db));
        let range = strongest.map(|t| t.range_m);
        let level = strongest.map(|t| t.level_db);
        let distance = range.zip(args.target_range).map(|(r, want)| r - want);
        let truth = truth_ranges(m.taken.ground_truth.as_ref());
        if let Some(l) = live {
            let (_, table) = radbench::measure::profile_figure(
                String::new(),
                p,
                &m.processing.options,
                truth.clone(),
            );
            let detections: Vec<(f64, f64)> =
                p.targets.iter().map(|t| (t.range_m, t.level_db)).collect();
            l.send(Event::Set(
                "profile",
                crate::live::profile_json(
                    &format!("capture {k}"),
                    &table.range_m,
                    &table.columns,
                    &detections,
                    &truth,
                ),
            ));
            l.send(Event::Set(
                "align",
                json!({
                    "capture": k,
                    "range_m": range,
                    "level_db": level,
                    "target_m": args.target_range,
                    "distance_m": distance,
                }),
            ));
            live_cli::capture_warnings(l, bench, k, &p.warnings);
        }
        let text = if args.json {
            json!({
                "event": "capture",
                "capture": k,
                "range_m": range,
                "level_db": level,
                "target_m": args.target_range,
                "distance_m": distance,
                "targets": p.targets.iter().map(|t| json!({"range_m": t.range_m, "level_db": t.level_db})).collect::<Vec<_>>(),
                "truth_m": if bench.is_simulated() { json!(truth) } else { json!(null) },
                "correction": m.processing.options.correction.as_ref().map(|c| c.mode),
                "sidelobe_db": p.sidelobe_db,
                "warnings": p.warnings,
            })
            .to_string()
        } else {
            line(k, range, level, args.target_range, distance)
        };
        super::terminal::out(&text)?;
        if let Some(signal) = interrupt.received() {
            eprintln!(
                "{} received during capture {k}: the bench is safe ({})",
                signal.name(),
                m.taken.safe_state
            );
            return Err(MeasureError::Interrupted {
                signal,
                report: m.taken.safe_state.to_string(),
            }
            .into());
        }
    }
    Ok(())
}

/// The terminal's line of one capture.
fn line(
    k: u64,
    range: Option<f64>,
    level: Option<f64>,
    target: Option<f64>,
    distance: Option<f64>,
) -> String {
    let (Some(r), Some(l)) = (range, level) else {
        return format!("capture {k}: no target found");
    };
    let mut s = format!("capture {k}: strongest target {r:.4} m at {l:.1} dB");
    if let (Some(t), Some(d)) = (target, distance) {
        let mm = d * 1e3;
        let hint = if mm.abs() < 0.5 {
            "in place".to_string()
        } else if mm > 0.0 {
            format!("move it {:.1} mm closer", mm.abs())
        } else {
            format!("move it {:.1} mm farther", mm.abs())
        };
        s += &format!("; {mm:+.1} mm from {t:.4} m ({hint})");
    }
    s
}
