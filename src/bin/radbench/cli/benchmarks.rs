//! `radbench bench`: times the DSP kernels on thesis-sized inputs, one thread.
//! `radbench bench io ADDRESS...`: instrument I/O throughput instead (see [`super::benchmarks_io`]).
//!
//! `--write-inputs DIR` also writes the seeded inputs as `.npy` (plus `meta.json`) so
//! `benches/compare_numpy.py` can time numpy/scipy on exactly the same data.

use num_complex::Complex64;
use radbench::exit::bad_input;
use radbench::simulate::{time_all, KernelInputs, Kernels, XCORR_LAGS};
use radbench::storage;
use radbench::storage::write_atomic;
use std::path::{Path, PathBuf};

#[derive(Debug, clap::Args)]
#[command(args_conflicts_with_subcommands = true)]
pub struct Args {
    #[command(subcommand)]
    pub target: Option<Target>,
    /// Print one JSON object {"kernels": [...]} (docs/simulate-json.md).
    #[arg(long)]
    pub json: bool,
    /// Minimum timed runs per kernel.
    #[arg(long, value_name = "N", default_value_t = 9)]
    pub min_runs: usize,
    /// Keep repeating a kernel until this many seconds have passed (at most 200 runs).
    #[arg(long, value_name = "S", default_value_t = 0.5)]
    pub min_time: f64,
    /// Also write the kernels' inputs as .npy files (and meta.json) into this folder.
    #[arg(long, value_name = "DIR")]
    pub write_inputs: Option<PathBuf>,
    /// Seed of the inputs.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
}

/// What else `radbench bench` can time.
#[derive(Debug, clap::Subcommand)]
pub enum Target {
    /// Instrument I/O: a block to and from each address (DATA <block> / DATA?), in MB/s.
    Io(super::benchmarks_io::Args),
}

pub(crate) fn run(args: Args, global: &super::global::Global) -> anyhow::Result<()> {
    if let Some(Target::Io(io)) = args.target {
        return super::benchmarks_io::run(io, global);
    }
    if !(args.min_time.is_finite() && args.min_time >= 0.0) {
        return Err(bad_input(format!(
            "--min-time: {} is not a duration in seconds (>= 0)",
            args.min_time
        )));
    }
    let inputs = KernelInputs::generate(args.seed)?;
    if let Some(dir) = &args.write_inputs {
        write_inputs(dir, &inputs)?;
    }
    let timings = time_all(&inputs, args.min_runs, args.min_time)?;
    if args.json {
        let doc = serde_json::json!({ "kernels": timings });
        println!("{}", serde_json::to_string_pretty(&doc)?);
    } else {
        println!(
            "{:<16} {:>11} {:>10} {:>10} {:>5} {:>14}",
            "kernel", "median ms", "min ms", "max ms", "runs", "Msamples/s"
        );
        for t in &timings {
            println!(
                "{:<16} {:>11.3} {:>10.3} {:>10.3} {:>5} {:>14.1}",
                t.name,
                t.median_ms,
                t.min_ms,
                t.max_ms,
                t.runs,
                t.samples_per_s / 1e6
            );
        }
        println!(
            "one thread; median of repeated runs after one warm-up; inputs seeded ({}).",
            args.seed
        );
    }
    Ok(())
}

fn write_c128(dir: &Path, name: &str, data: &[Complex64]) -> anyhow::Result<()> {
    let bytes = storage::encode_c128(&[data.len()], data).map_err(anyhow::Error::msg)?;
    write_atomic(&dir.join(format!("{name}.npy")), &bytes)?;
    Ok(())
}

fn write_inputs(dir: &Path, inputs: &KernelInputs) -> anyhow::Result<()> {
    std::fs::create_dir_all(dir).map_err(|e| {
        bad_input(format!(
            "--write-inputs: cannot create folder {}: {e}",
            dir.display()
        ))
    })?;
    write_c128(dir, "capture_800k", &inputs.capture_800k)?;
    write_c128(dir, "capture_1280k", &inputs.capture_1280k)?;
    write_c128(dir, "msk_tx", &inputs.msk_tx)?;
    write_c128(dir, "msk_rx", &inputs.msk_rx)?;
    write_c128(dir, "ofdm_tx_symbols", &inputs.ofdm_tx_symbols)?;
    write_c128(dir, "ofdm_rx", &inputs.ofdm_rx)?;
    write_c128(dir, "music_column", &inputs.music_column)?;
    let kernels = Kernels::new(inputs)?;
    let meta = serde_json::json!({
        "decimation_factor": 5,
        "xcorr_lags": XCORR_LAGS,
        // radbench's own FFT length (its correlator may split the work into shorter blocks)...
        "xcorr_fft_len": kernels.xcorr_fft_len(),
        // ...and the shortest single FFT free of circular aliasing on lags 0..lags-1, which the
        // numpy version rounds up to scipy.fft.next_fast_len.
        "xcorr_min_single_fft_len": inputs.msk_rx.len().max(XCORR_LAGS - 1 + inputs.msk_tx.len()),
        "ofdm": {"subcarriers": 128, "oversampling": 16, "cp_len": 512, "fft_len": 2048,
                 "symbols": 100, "zero_pad": 10},
        "music": {"m": 64, "p": 2, "forward_backward": true, "grid_points": 1280},
    });
    write_atomic(
        &dir.join("meta.json"),
        serde_json::to_string_pretty(&meta)?.as_bytes(),
    )?;
    Ok(())
}
