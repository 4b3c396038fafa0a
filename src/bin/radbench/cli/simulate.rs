//! `radbench simulate`: the thesis' chapter-4 scenarios, free-form runs and BER curves.
//!
//! `simulate run --scene FILE` simulates the built-in mock lab's capture of a scene file
//! in-process (`radbench::simulate::scene_bench`): the same synthesis, scope and pipeline as
//! `capture --allow-rf --scene FILE`, so the same detections for the same scene and `--seed`.
//!
//! Target syntax for `--targets`: `R[:AMP[:V]]` separated by commas: range in metres, linear
//! amplitude (default 1), radial velocity in m/s (default 0, positive = moving away). Example:
//! `--targets 1.0,1.06:0.8` or `--targets 3:1:-2.5`.

use super::args::WaveformArgs;
use radbench::exit::bad_input;
use radbench::measure::ProcessingChoices;
use radbench::simulate;
use radbench::simulate::CarrierPhase;
use radbench::simulate::{parse_targets, RunSpec};
use radbench::simulate::{simulate_scene, SceneSpec};
use radbench::waveform::WaveformKind;
use std::path::PathBuf;

#[derive(Debug, clap::Args)]
pub struct Args {
    #[command(subcommand)]
    pub command: SimCommand,
}

#[derive(Debug, clap::Subcommand)]
pub enum SimCommand {
    /// Rerun every chapter-4 simulation of the thesis and print one comparison table.
    Thesis(ThesisArgs),
    /// A free-form simulation: waveform, targets, noise, processing.
    Run(Box<RunArgs>),
    /// Bit-error rate against Eb/N0 (0..10 dB) for both waveforms, next to theory.
    Ber(BerArgs),
}

#[derive(Debug, clap::Args)]
pub struct ThesisArgs {
    /// Print one JSON object {"scenarios": [...]} instead of the table (docs/simulate-json.md).
    #[arg(long)]
    pub json: bool,
    /// Draw every scenario's range profile into this folder (SVG; created if missing).
    #[arg(long, value_name = "DIR")]
    pub plot: Option<PathBuf>,
}

#[derive(Debug, clap::Args)]
pub struct RunArgs {
    /// Waveform.
    #[arg(long, value_parser = super::args::listed::<WaveformKind>())]
    pub waveform: WaveformKind,
    #[command(flatten)]
    pub waveform_args: WaveformArgs,
    /// Targets: R[:AMP[:V]] separated by commas (metres, linear amplitude, m/s receding).
    #[arg(
        long,
        value_name = "R[:AMP[:V]],...",
        allow_hyphen_values = true,
        required_unless_present = "scene"
    )]
    pub targets: Option<String>,
    /// A mock-lab scene file (examples/scene.toml): simulate the built-in mock lab's capture of
    /// it in-process (targets, clutter, leakage, impairments, [chain], SNR and noise seed from
    /// the file), with the same detections as `capture --allow-rf --scene FILE`.
    #[arg(
        long,
        value_name = "FILE",
        conflicts_with_all = ["targets", "snr_db", "capture_rate", "carrier_phase"]
    )]
    pub scene: Option<PathBuf>,
    /// With --scene: text to send in the waveform (default: PRBS bits from --seed).
    #[arg(long, value_name = "TEXT")]
    pub payload: Option<String>,
    /// Per-sample SNR in dB at the capture rate for a unit-amplitude target (default: noise-free).
    #[arg(long, value_name = "DB", allow_hyphen_values = true)]
    pub snr_db: Option<f64>,
    #[command(flatten)]
    pub processing: ProcessingChoices,
    /// Echo carrier phase: physical (80 GHz), centred (0 Hz) or thesis (B/2, the thesis' model).
    #[arg(long, value_parser = super::args::listed::<CarrierPhase>(), default_value = "physical")]
    pub carrier_phase: CarrierPhase,
    /// Capture rate in Sa/s: a multiple of the waveform rate runs the lab chain (80e9 -> decimate
    /// by 5 -> 16 GSa/s).
    #[arg(long, value_name = "HZ", allow_hyphen_values = true)]
    pub capture_rate: Option<f64>,
    /// Seed of the bits and the noise (with --scene: of the bits, as `capture --seed`; the noise
    /// comes from the scene's `seed`).
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Monte-Carlo trials (new noise each trial; with --scene, trial k is the lab's k-th capture).
    #[arg(long, default_value_t = 1)]
    pub trials: usize,
    /// Print one JSON object {"scenarios": [...]} (docs/simulate-json.md).
    #[arg(long)]
    pub json: bool,
    /// Draw the range profile(s) to FILE.svg or FILE.png.
    #[arg(long, value_name = "FILE")]
    pub plot: Option<PathBuf>,
    /// Write the range profile(s) to FILE.csv or FILE.npy (columns: range_m then dB per curve).
    #[arg(long, value_name = "FILE")]
    pub profile_out: Option<PathBuf>,
}

/// `capture`'s default range window (`--min-range`, `--max-range`), metres.

#[derive(Debug, clap::Args)]
pub struct BerArgs {
    /// Print one JSON object {"ber": [...]} (docs/simulate-json.md).
    #[arg(long)]
    pub json: bool,
    /// Minimum bits per Eb/N0 point (more bits: tighter confidence intervals, longer run).
    #[arg(long, value_name = "N", default_value_t = 20_000)]
    pub bits: usize,
    /// Seed of the bits and the noise.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Draw BER against Eb/N0 with theory to FILE.svg or FILE.png.
    #[arg(long, value_name = "FILE")]
    pub plot: Option<PathBuf>,
}

/// Most bits one Eb/N0 point may ask for: 100 million take about a minute per point on one core.
const MAX_BER_BITS: usize = 100_000_000;

pub(crate) fn run(args: Args, _global: &super::global::Global) -> anyhow::Result<()> {
    match args.command {
        SimCommand::Thesis(a) => run_thesis(a),
        SimCommand::Run(a) => run_free(*a),
        SimCommand::Ber(a) => run_ber(a),
    }
}

fn run_thesis(args: ThesisArgs) -> anyhow::Result<()> {
    if let Some(dir) = &args.plot {
        std::fs::create_dir_all(dir).map_err(|e| {
            bad_input(format!(
                "--plot: cannot create folder {}: {e}",
                dir.display()
            ))
        })?;
    }
    let table = simulate::run_all(args.plot.as_deref())?;
    if args.json {
        println!("{}", serde_json::to_string_pretty(&table.to_json())?);
    } else {
        print!("{}", table.to_text());
    }
    Ok(())
}

fn run_free(a: RunArgs) -> anyhow::Result<()> {
    let kind = a.waveform;
    if a.processing.correction.is_some() || a.processing.calibration.is_some() {
        return Err(bad_input(
            "--correction and --calibration apply to a bench's captures (capture, align, \
             process); a simulation has no measured chain to correct",
        ));
    }
    let waveform = a.waveform_args.spec(kind)?;
    let (outcome, spec) = match &a.scene {
        Some(path) => {
            let options = a.processing.options(kind);
            let scene = SceneSpec {
                scene: super::mock_lab::load_scene(path)?,
                waveform,
                payload: a.payload.as_ref().map(|p| p.as_bytes().to_vec()),
                seed: a.seed,
                options,
                trials: a.trials,
            };
            let done = simulate_scene(&scene)?;
            (done.outcome, done.spec)
        }
        None => {
            for (given, option) in [
                (a.processing.min_range_m.is_some(), "--min-range"),
                (a.processing.max_range_m.is_some(), "--max-range"),
                (a.payload.is_some(), "--payload"),
            ] {
                if given {
                    return Err(bad_input(format!(
                        "{option} applies to --scene runs only (the capture's range window and \
                         payload); a --targets run simulates the whole range its waveform holds"
                    )));
                }
            }
            let Some(text) = &a.targets else {
                return Err(bad_input(
                    "--targets: give the targets (e.g. --targets 3,3.132:0.5) or --scene FILE",
                ));
            };
            let mut spec = RunSpec::new("run", waveform, parse_targets(text)?);
            spec.processing = a.processing.options(kind);
            spec.snr_db = a.snr_db;
            spec.carrier = a.carrier_phase;
            spec.capture_rate_hz = a.capture_rate;
            spec.seed = a.seed;
            spec.trials = a.trials;
            (radbench::simulate::simulate(&spec)?, spec)
        }
    };
    if let Some(path) = &a.plot {
        radbench::storage::draw(path, &outcome.plot(&spec))?;
    }
    if let Some(path) = &a.profile_out {
        outcome.table().write(path)?;
    }
    if a.json {
        let doc = serde_json::json!({ "scenarios": [outcome.result] });
        println!("{}", serde_json::to_string_pretty(&doc)?);
    } else {
        print!("{}", simulate::scenario_text(&outcome.result));
    }
    Ok(())
}

fn run_ber(a: BerArgs) -> anyhow::Result<()> {
    if !(1000..=MAX_BER_BITS).contains(&a.bits) {
        return Err(bad_input(format!(
            "--bits {}: allowed 1000 ..= {MAX_BER_BITS} bits per Eb/N0 point (100 million take \
             about a minute per point on one core)",
            a.bits
        )));
    }
    let bar = if std::io::IsTerminal::is_terminal(&std::io::stderr()) && !a.json {
        indicatif::ProgressBar::with_draw_target(None, indicatif::ProgressDrawTarget::stderr())
    } else {
        indicatif::ProgressBar::hidden()
    };
    bar.set_style(
        indicatif::ProgressStyle::with_template("{bar:30} {pos}/{len} Eb/N0 points, eta {eta}")
            .unwrap_or_else(|_| indicatif::ProgressStyle::default_bar()),
    );
    let curves = simulate::run_curves(a.bits, a.seed, &|done, total| {
        bar.set_length(total as u64);
        bar.set_position(done as u64);
    })?;
    bar.finish_and_clear();
    if let Some(path) = &a.plot {
        radbench::storage::draw_ber(
            path,
            "Bit-error rate against Eb/N0 (AWGN), measured and theory",
            &simulate::plot_series(&curves),
        )?;
    }
    if a.json {
        println!(
            "{}",
            serde_json::to_string_pretty(&serde_json::json!({ "ber": curves }))?
        );
    } else {
        print!("{}", simulate::ber_text(&curves));
    }
    Ok(())
}
