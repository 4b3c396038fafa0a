//! `radbench calibrate`: measure the bench's fixed system delay (cables, horns, marker latency) on a
//! reference target at a known range, and store it in the bench file.

use super::capture::{capture_settings, measure, AwgTransport, BenchInUse, ScopeTransport};
use crate::driver::RfPermit;
use crate::dsp::C0;
use crate::exit::bad_input;
use crate::measure::bench_file::{store_calibration, Calibration};
use crate::measure::process::ProcessOptions;
use crate::measure::transmit::{Transmission, WaveformKind, DEFAULT_BACKOFF_DB};
use crate::processing::Algorithm;
use std::path::PathBuf;

#[derive(Debug, clap::Args)]
pub struct Args {
    /// True range of the reference target (antennas to target), metres.
    #[arg(long, value_name = "METRES")]
    pub reference_range: f64,
    /// Bench file to calibrate (the result is stored in its [calibration] section). Without one,
    /// the built-in mock lab is measured and the result only printed.
    #[arg(long, value_name = "FILE")]
    pub bench: Option<PathBuf>,
    /// Explicit permit to switch on the AWG outputs and the Tx/Rx front ends.
    #[arg(long)]
    pub allow_rf: bool,
    /// Only echoes within this distance of the reference range are taken as the reference, metres
    /// (before calibration ranges are off by the system delay: allow for it).
    #[arg(long, default_value_t = 2.0)]
    pub search: f64,
    /// Print one JSON object.
    #[arg(long)]
    pub json: bool,
}

pub fn run(args: Args, global: &super::Global) -> anyhow::Result<()> {
    if !(args.reference_range.is_finite()
        && args.reference_range > 0.0
        && args.reference_range < 100.0)
    {
        return Err(bad_input(format!(
            "--reference-range {}: give the reference target's range in metres, 0 < R < 100",
            args.reference_range
        )));
    }
    if !args.allow_rf {
        return Err(bad_input(
            "calibration transmits: pass --allow-rf to switch on the AWG outputs and the front ends",
        ));
    }
    super::runtime()?.block_on(async {
        let bench = BenchInUse::open(
            args.bench.as_deref(),
            None,
            AwgTransport::Hislip,
            ScopeTransport::Vicp,
            args.json,
        )
        .await?;
        let options = ProcessOptions {
            algorithm: Algorithm::Correlation,
            system_delay_s: 0.0,
            min_range_m: 0.0,
            max_range_m: args.reference_range + args.search + 150.0,
            ..ProcessOptions::default()
        };
        let tx = Transmission::new(WaveformKind::MskLfm, None, 1, DEFAULT_BACKOFF_DB)?;
        let settings =
            capture_settings(&bench.file, Some(RfPermit::granted_by_user()), false, 10.0);
        let m = measure(&bench, tx, settings, &options, None, global).await?;
        // Uncalibrated ranges are true range + c * delay / 2: the reference is the strongest echo
        // at or beyond its true range, within the search distance of the delay-shifted range.
        let reference = m
            .processed
            .targets
            .iter()
            .filter(|t| {
                t.range_m >= args.reference_range - 0.05
                    && t.range_m <= args.reference_range + args.search + 0.05
            })
            .max_by(|a, b| a.level_db.total_cmp(&b.level_db))
            .ok_or_else(|| {
                anyhow::anyhow!(crate::exit::Classified {
                    class: crate::exit::ExitClass::Processing,
                    message: format!(
                        "no echo between {:.3} m and {:.3} m (uncalibrated): place the reference \
                         target at {} m, check RF is on, or widen --search",
                        args.reference_range,
                        args.reference_range + args.search,
                        args.reference_range
                    ),
                })
            })?;
        let delay = 2.0 * (reference.range_m - args.reference_range) / C0;
        let calibration = Calibration {
            system_delay_s: delay,
            reference_range_m: Some(args.reference_range),
            measured_at: Some(crate::storage::sigmf::utc_now_rfc3339()),
        };
        if let Some(path) = &bench.path {
            store_calibration(path, &calibration)?;
        }
        if args.json {
            println!(
                "{}",
                serde_json::json!({
                    "system_delay_s": delay,
                    "reference_range_m": args.reference_range,
                    "measured_range_m": reference.range_m,
                    "stored_in": bench.path.as_ref().map(|p| p.display().to_string()),
                })
            );
        } else {
            println!(
                "system delay {:.4} ns (reference echo at {:.4} m uncalibrated, true {:.4} m)",
                delay * 1e9,
                reference.range_m,
                args.reference_range
            );
            match &bench.path {
                Some(p) => println!("stored in {} [calibration]", p.display()),
                None => println!("built-in mock lab: not stored (pass --bench FILE to store it)"),
            }
        }
        Ok(())
    })
}
