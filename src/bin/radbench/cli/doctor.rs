//! `radbench doctor`: checks a bench without radiating and prints a checklist with what to fix
//! for each failure (`measure::doctor::examine` does the checks). Exit 0 only when no check
//! fails.

use super::capture::{bench_source, journal, open_bench};
use radbench::exit::{Classified, ExitClass};
use radbench::measure::doctor::{self, Report, Status};
use radbench::measure::Interrupt;
use radbench::measure::{AwgLink, ScopeLink};
use std::path::PathBuf;

#[derive(Debug, clap::Args)]
pub struct Args {
    /// The bench file to check. Without one, the built-in mock lab is started and checked.
    #[arg(long, value_name = "FILE")]
    pub bench: Option<PathBuf>,
    /// Print one JSON object: {"bench", "ok", "checks": [{"id", "status", "detail", "fix"}]}.
    #[arg(long)]
    pub json: bool,
    #[command(flatten)]
    pub timeout: super::args::TimeoutArgs,
    #[command(flatten)]
    pub scope_model: super::scope_model::ScopeModelArgs,
    /// Instead of the checklist: ask each instrument for the values the catalog only infers
    /// (identity, `*OPT?`, ...) and print per value: confirmed, differs (with the instrument's
    /// answer) or cannot be queried (and why).
    #[arg(long)]
    pub verify_catalog: bool,
    /// With --verify-catalog: write the values that differ, as the instruments answered them,
    /// into one overrides file FILE (kept values merged; then write
    /// `catalog_overrides = "FILE"` in the bench file).
    #[arg(long, value_name = "FILE", requires = "verify_catalog")]
    pub write_overrides: Option<PathBuf>,
}

pub(crate) fn run(args: Args, global: &super::global::Global) -> anyhow::Result<()> {
    args.timeout.apply()?;
    if args.verify_catalog {
        let request = super::verify_catalog::Request {
            bench: args.bench.as_deref(),
            scope_model: &args.scope_model,
            json: args.json,
            write_overrides: args.write_overrides.as_deref(),
        };
        return super::verify_catalog::run(request, global);
    }
    let runtime = super::global::runtime()?;
    runtime.block_on(async {
        let interrupt = Interrupt::listen()?;
        let source = args.scope_model.apply(bench_source(
            args.bench.as_deref(),
            None,
            AwgLink::Hislip,
            ScopeLink::Vicp,
        )?)?;
        let bench = open_bench(source, args.json).await?;
        let report = doctor::examine(&bench, journal(global)?, &interrupt).await?;
        // A stop signal during a check that does not switch anything on: that check finished
        // (each is bounded), no further one radiated (the marker check is skipped once a signal
        // came), and the doctor ends with the signal's code.
        if let Some(signal) = interrupt.received() {
            return Err(doctor::stopped(signal).into());
        }
        if args.json {
            super::terminal::out(&serde_json::to_string(&report)?)?;
        } else {
            super::terminal::out(&text(&report))?;
        }
        if report.ok {
            Ok(())
        } else {
            let failed: Vec<&str> = report
                .checks
                .iter()
                .filter(|c| c.status == Status::Fail)
                .map(|c| c.id.as_str())
                .collect();
            Err(anyhow::Error::new(Classified {
                class: ExitClass::Instrument,
                message: format!(
                    "the bench doctor found {} problem(s): {}",
                    failed.len(),
                    failed.join(", ")
                ),
            }))
        }
    })
}

/// The checklist as text: one line per check, its fix indented under a failure or warning.
fn text(report: &Report) -> String {
    let mut out = format!("bench doctor: {}\n", report.bench);
    for c in &report.checks {
        out += &format!("[{:>4}] {:<24} {}\n", c.status.mark(), c.id, c.detail);
        if let Some(fix) = &c.fix {
            out += &format!("       {:<24} fix: {fix}\n", "");
        }
    }
    let failed = report
        .checks
        .iter()
        .filter(|c| c.status == Status::Fail)
        .count();
    let warned = report
        .checks
        .iter()
        .filter(|c| c.status == Status::Warn)
        .count();
    out += &if failed == 0 {
        format!(
            "all checks hold ({} checks, {warned} warning(s)); nothing was switched on",
            report.checks.len()
        )
    } else {
        format!("{failed} check(s) failed, {warned} warning(s); nothing was switched on")
    };
    out
}
