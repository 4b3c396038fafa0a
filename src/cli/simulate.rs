//! `radbench simulate`: the thesis' chapter-4 scenarios, free-form runs and BER curves.
//!
//! Target syntax for `--targets`: `R[:AMP[:V]]` separated by commas: range in metres, linear
//! amplitude (default 1), radial velocity in m/s (default 0, positive = moving away). Example:
//! `--targets 1.0,1.06:0.8` or `--targets 3:1:-2.5`.

use crate::exit::bad_input;
use crate::simulate::{
    ber, report,
    scene::{parse_targets, CarrierPhase},
    spec::{Algorithm, FftPrecisionName, RunSpec, WaveformSpec, WindowName},
    thesis,
};
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

#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum WaveformName {
    MskLfm,
    Ofdm,
}

#[derive(Debug, clap::Args)]
pub struct RunArgs {
    /// Waveform.
    #[arg(long, value_enum)]
    pub waveform: WaveformName,
    /// Targets: R[:AMP[:V]] separated by commas (metres, linear amplitude, m/s receding).
    #[arg(long, value_name = "R[:AMP[:V]],...", allow_hyphen_values = true)]
    pub targets: String,
    /// Per-sample SNR in dB at the capture rate for a unit-amplitude target (default: noise-free).
    #[arg(long, value_name = "DB", allow_hyphen_values = true)]
    pub snr_db: Option<f64>,
    /// Range processing (default: correlation for MSK-LFM, fourier for OFDM).
    #[arg(long, value_enum)]
    pub algorithm: Option<Algorithm>,
    /// MUSIC covariance size M (sub-vector length of the spatial smoothing).
    #[arg(long = "m", value_name = "M", default_value_t = 64)]
    pub m: usize,
    /// Number of targets for MUSIC/root-MUSIC/ESPRIT (default: estimated with MDL).
    #[arg(long = "p", value_name = "P")]
    pub p: Option<usize>,
    /// Forward smoothing only (no forward-backward averaging) for MUSIC.
    #[arg(long)]
    pub forward_only: bool,
    /// OFDM Fourier zero-padding factor: IFFT length = K x subcarriers.
    #[arg(long, value_name = "K", default_value_t = 10)]
    pub zero_pad: usize,
    /// Window on the subcarriers before the OFDM range IFFT.
    #[arg(long, value_enum, value_name = "NAME", default_value = "rect")]
    pub window: WindowName,
    /// Precision of the OFDM receiver's per-symbol FFT (the rest is double precision).
    #[arg(long, value_enum, value_name = "P", default_value = "single")]
    pub fft_precision: FftPrecisionName,
    /// Echo carrier phase: physical (80 GHz), centred (0 Hz) or thesis (B/2, the thesis' model).
    #[arg(long, value_enum, default_value = "physical")]
    pub carrier_phase: CarrierPhase,
    /// Capture rate in Sa/s: a multiple of the waveform rate runs the lab chain (80e9 -> decimate
    /// by 5 -> 16 GSa/s).
    #[arg(long, value_name = "HZ")]
    pub capture_rate: Option<f64>,
    /// Report the on-grid peak (no sub-sample interpolation).
    #[arg(long)]
    pub no_interpolation: bool,
    /// Seed of the bits and the noise.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Monte-Carlo trials (new noise each trial).
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
    /// Bandwidth in Hz (both waveforms).
    #[arg(long, value_name = "HZ", default_value_t = 1e9)]
    pub bandwidth: f64,
    /// MSK-LFM sample rate in Sa/s (the AWG rate).
    #[arg(long, value_name = "HZ", default_value_t = 16e9)]
    pub sample_rate: f64,
    /// MSK-LFM pulse length in microseconds.
    #[arg(long, value_name = "US", default_value_t = 10.0)]
    pub pulse_us: f64,
    /// MSK-LFM bits per pulse.
    #[arg(long, value_name = "N", default_value_t = 128)]
    pub bits_per_pulse: usize,
    /// OFDM subcarriers.
    #[arg(long, value_name = "N", default_value_t = 128)]
    pub subcarriers: usize,
    /// OFDM oversampling factor (sample rate = bandwidth x factor).
    #[arg(long, value_name = "N", default_value_t = 16)]
    pub oversampling: usize,
    /// OFDM cyclic prefix as a fraction of the useful symbol.
    #[arg(long, value_name = "F", default_value_t = 0.25)]
    pub cp_fraction: f64,
    /// OFDM symbols per frame.
    #[arg(long, value_name = "N", default_value_t = 100)]
    pub symbols: usize,
}

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
}

pub fn run(args: Args, _global: &super::Global) -> anyhow::Result<()> {
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
    let table = thesis::run_all(args.plot.as_deref())?;
    if args.json {
        println!("{}", serde_json::to_string_pretty(&table.to_json())?);
    } else {
        print!("{}", table.to_text());
    }
    Ok(())
}

fn run_free(a: RunArgs) -> anyhow::Result<()> {
    let waveform = match a.waveform {
        WaveformName::MskLfm => WaveformSpec::MskLfm {
            sample_rate_hz: a.sample_rate,
            bandwidth_hz: a.bandwidth,
            pulse_s: a.pulse_us * 1e-6,
            bits_per_pulse: a.bits_per_pulse,
        },
        WaveformName::Ofdm => WaveformSpec::Ofdm {
            bandwidth_hz: a.bandwidth,
            subcarriers: a.subcarriers,
            oversampling: a.oversampling,
            cp_fraction: a.cp_fraction,
            symbols: a.symbols,
        },
    };
    let targets = parse_targets(&a.targets)?;
    let mut spec = RunSpec::new("run", waveform, targets);
    if let Some(alg) = a.algorithm {
        spec.algorithm = alg;
    }
    spec.snr_db = a.snr_db;
    spec.music_m = a.m;
    spec.music_p = a.p;
    spec.forward_backward = !a.forward_only;
    spec.zero_pad = a.zero_pad;
    spec.window = a.window;
    spec.fft_precision = a.fft_precision;
    spec.carrier = a.carrier_phase;
    spec.capture_rate_hz = a.capture_rate;
    spec.interpolate = !a.no_interpolation;
    spec.seed = a.seed;
    spec.trials = a.trials;
    let outcome = crate::simulate::run::simulate(&spec)?;
    if let Some(path) = &a.plot {
        crate::storage::plot::draw(path, &outcome.plot(&spec))?;
    }
    if let Some(path) = &a.profile_out {
        outcome.table().write(path)?;
    }
    if a.json {
        let doc = serde_json::json!({ "scenarios": [outcome.result] });
        println!("{}", serde_json::to_string_pretty(&doc)?);
    } else {
        print!("{}", report::scenario_text(&outcome.result));
    }
    Ok(())
}

fn run_ber(a: BerArgs) -> anyhow::Result<()> {
    if a.bits < 1000 {
        return Err(bad_input("--bits: must be at least 1000 per Eb/N0 point"));
    }
    let curves = ber::run_curves(a.bits, a.seed)?;
    if a.json {
        println!(
            "{}",
            serde_json::to_string_pretty(&serde_json::json!({ "ber": curves }))?
        );
    } else {
        print!("{}", report::ber_text(&curves));
    }
    Ok(())
}
