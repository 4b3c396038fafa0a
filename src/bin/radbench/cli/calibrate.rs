//! `radbench calibrate`: measure the bench's fixed system delay (cables, horns, marker latency) on a
//! reference target at a known range, and store it in the bench file; `radbench calibrate
//! response`: measure the chain's response on the same reference (`calibrate_response.rs`).

use super::capture::{bench_source, journal, open_bench};
use radbench::measure;
use radbench::measure::CaptureRequest;
use radbench::measure::Interrupt;
use radbench::measure::MeasureError;
use radbench::measure::{check, estimate_delay};
use radbench::measure::{store_calibration, BenchCalibration};
use radbench::measure::{Algorithm, ProcessOptions};
use radbench::measure::{AwgLink, ScopeLink};
use radbench::waveform::WaveformSpec;
use std::path::PathBuf;

#[derive(Debug, clap::Args)]
#[command(args_conflicts_with_subcommands = true, subcommand_negates_reqs = true)]
pub struct Args {
    #[command(subcommand)]
    pub command: Option<CalibrateCommand>,
    #[command(flatten)]
    pub delay: DelayArgs,
}

#[derive(Debug, clap::Subcommand)]
pub enum CalibrateCommand {
    /// Measure the chain's response (ripple, group delay, I/Q imbalance, DC) on the reference
    /// pillar, check that correcting it helps, and store it beside the bench file.
    Response(Box<super::calibrate_response::Args>),
}

#[derive(Debug, clap::Args)]
pub struct DelayArgs {
    /// True range of the reference target (antennas to target), metres.
    #[arg(
        long,
        value_name = "METRES",
        allow_hyphen_values = true,
        required = true
    )]
    pub reference_range: Option<f64>,
    /// Bench file to calibrate (the result is stored in its [calibration] section). Without one,
    /// the built-in mock lab is measured and the result only printed.
    #[arg(long, value_name = "FILE")]
    pub bench: Option<PathBuf>,
    /// Explicit permit to switch on the AWG outputs and the Tx/Rx front ends.
    #[arg(long)]
    pub allow_rf: bool,
    /// Only echoes within this distance of the reference range are taken as the reference, metres
    /// (before calibration ranges are off by the system delay: allow for it).
    #[arg(long, default_value_t = 2.0, allow_hyphen_values = true)]
    pub search: f64,
    /// Print one JSON object.
    #[arg(long)]
    pub json: bool,
    #[command(flatten)]
    pub scope_model: super::scope_model::ScopeModelArgs,
}

pub(crate) fn run(args: Args, global: &super::global::Global) -> anyhow::Result<()> {
    match args.command {
        Some(CalibrateCommand::Response(a)) => super::calibrate_response::run(*a, global),
        None => run_delay(args.delay, global),
    }
}

fn run_delay(args: DelayArgs, global: &super::global::Global) -> anyhow::Result<()> {
    let reference_range = args
        .reference_range
        .ok_or_else(|| radbench::exit::bad_input("--reference-range METRES is needed"))?;
    check(reference_range, args.search)?;
    if !args.allow_rf {
        return Err(MeasureError::NoPermit { run: "calibration" }.into());
    }
    super::global::runtime()?.block_on(async {
        let source = args.scope_model.apply(bench_source(
            args.bench.as_deref(),
            None,
            AwgLink::Hislip,
            ScopeLink::Vicp,
        )?)?;
        let manual = super::manual_front::confirm_file(args.bench.as_deref(), "calibration")?;
        let interrupt = Interrupt::listen()?;
        let bench = open_bench(source, args.json).await?;
        // With the response the bench file names corrected, the delay is the corrected chain's:
        // the one its captures are processed with.
        let correction = super::capture::resolve_correction(None, None, &bench)?;
        let request = CaptureRequest {
            waveform: WaveformSpec::msk_lfm_default(),
            payload: None,
            seed: 1,
            options: ProcessOptions {
                algorithm: Algorithm::Correlation,
                system_delay_s: 0.0,
                min_range_m: 0.0,
                max_range_m: reference_range + args.search + 150.0,
                correction: correction.as_ref().map(|c| c.used()),
                ..ProcessOptions::default()
            },
            tx_off: false,
            wait_s: 10.0,
            background: None,
        };
        let m = measure::measure(
            &bench,
            &request,
            1,
            &manual.permit(),
            journal(global)?,
            &interrupt,
        )
        .await?;
        let estimate = estimate_delay(&m.processing.processed, reference_range, args.search)?;
        let calibration = BenchCalibration {
            system_delay_s: estimate.system_delay_s,
            reference_range_m: Some(reference_range),
            measured_at: Some(radbench::storage::utc_now_rfc3339()),
            // A response measured before is kept (it is relative to the delay it was measured
            // with: measure it again after a new delay).
            response: bench
                .file
                .calibration
                .as_ref()
                .and_then(|c| c.response.clone()),
        };
        if let Some(path) = &bench.path {
            store_calibration(path, &calibration)?;
        }
        if args.json {
            println!(
                "{}",
                serde_json::json!({
                    "system_delay_s": estimate.system_delay_s,
                    "reference_range_m": estimate.reference_range_m,
                    "measured_range_m": estimate.measured_range_m,
                    "stored_in": bench.path.as_ref().map(|p| p.display().to_string()),
                })
            );
        } else {
            println!(
                "system delay {:.4} ns (reference echo at {:.4} m uncalibrated, true {:.4} m)",
                estimate.system_delay_s * 1e9,
                estimate.measured_range_m,
                estimate.reference_range_m
            );
            match &bench.path {
                Some(p) => println!("stored in {} [calibration]", p.display()),
                None => println!("built-in mock lab: not stored (pass --bench FILE to store it)"),
            }
        }
        Ok(())
    })
}
