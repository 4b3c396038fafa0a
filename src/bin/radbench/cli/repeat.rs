//! `radbench capture --repeat N|forever`: one bench connection, one upload, N captures (or until
//! a stop), each in a folder of its own; RF on only while capturing, the safe state after each.

use super::capture::{calibration_warnings, journal, not_recorded, report, Args, Repeat};
use super::live::{self as live_cli};
use crate::live::{Event, Live};
use radbench::driver::RfPermit;
use radbench::measure;
use radbench::measure::Bench;
use radbench::measure::Calibration;
use radbench::measure::Interrupt;
use radbench::measure::MeasureError;
use radbench::measure::Provenance;
use radbench::measure::{CaptureRequest, Recorded, Recorder, Rig};
use serde_json::json;
use std::path::Path;

/// The stop received between two captures, as the command's error (the bench is safe: each
/// capture's guard ran the safe state; it runs once more for the report).
pub(crate) async fn stopped_between(
    rig: &Rig,
    interrupt: &Interrupt,
    after: &str,
) -> Option<anyhow::Error> {
    let signal = interrupt.received()?;
    let report = rig.safe_state().engage().await;
    eprintln!(
        "{} received {after}: the bench is safe ({report})",
        signal.name()
    );
    Some(
        MeasureError::Interrupted {
            signal,
            report: report.to_string(),
        }
        .into(),
    )
}

#[allow(clippy::too_many_arguments)]
pub(crate) async fn captures(
    args: &Args,
    global: &super::global::Global,
    repeat: Repeat,
    bench: &Bench,
    request: &CaptureRequest,
    interrupt: &Interrupt,
    permit: &RfPermit,
    out: &Path,
    calibration: Option<&Calibration>,
) -> anyhow::Result<()> {
    let live = args.live.start(interrupt, args.json).await?;
    if let Some(l) = &live {
        l.send(Event::Set("kind", json!("capture")));
        l.send(Event::Set(
            "title",
            json!(format!("capture --repeat into {}", out.display())),
        ));
        if let Some(n) = repeat.0 {
            l.send(Event::Set("of", json!(n)));
        }
        l.send(Event::Set(
            "plot_axes",
            json!({"x": "capture", "y": "strongest target (m)"}),
        ));
    }
    live_cli::bench_warnings(live.as_ref(), bench);
    let result = run(
        args,
        global,
        repeat,
        bench,
        request,
        interrupt,
        permit,
        out,
        calibration,
        live.as_ref(),
    )
    .await;
    live_cli::finish(
        live,
        live_cli::status_of(&result, interrupt),
        result.as_ref().err(),
    )
    .await;
    result
}

#[allow(clippy::too_many_arguments)]
async fn run(
    args: &Args,
    global: &super::global::Global,
    repeat: Repeat,
    bench: &Bench,
    request: &CaptureRequest,
    interrupt: &Interrupt,
    permit: &RfPermit,
    out: &Path,
    calibration: Option<&Calibration>,
    live: Option<&Live>,
) -> anyhow::Result<()> {
    let catalog = bench.file.catalog()?;
    let mut prepared = measure::prepare(bench, &catalog, request).await?;
    let mut rig = Rig::connect(bench, &catalog, journal(global)?).await?;
    let provenance = Provenance {
        bench_file: bench.path.clone(),
        simulated: bench.is_simulated(),
    };
    let of = repeat.0.map_or("?".to_string(), |n| n.to_string());
    let mut k = 0u64;
    while repeat.0.is_none_or(|n| k < n) {
        if let Some(e) = stopped_between(&rig, interrupt, &format!("after {k} captures")).await {
            return Err(e);
        }
        k += 1;
        live_cli::send(
            live,
            Event::Set("current", json!(format!("capture {k}/{of}: capturing"))),
        );
        let taken = rig
            .acquire(bench, &prepared, args.repetitions, permit, interrupt)
            .await?;
        let dir = out.join(format!("capture-{k:04}"));
        let Recorded {
            measurement: m,
            mut summary,
        } = Recorder::new(&dir, &provenance)
            .record(taken, &mut prepared, |m| {
                if let Some(cal) = calibration {
                    let warnings = calibration_warnings(cal, &m.taken.identities);
                    m.processing.processed.warnings.extend(warnings);
                }
            })
            .await
            .map_err(|e| not_recorded(e, &dir))?;
        if let Some(l) = live {
            let p = &m.processing.processed;
            let ranges: Vec<f64> = p.targets.iter().map(|t| t.range_m).collect();
            let strongest = p
                .targets
                .iter()
                .max_by(|a, b| a.level_db.total_cmp(&b.level_db))
                .map(|t| t.range_m);
            l.send(Event::Row(json!({
                "index": k,
                "nominal": format!("capture {k}"),
                "ranges": ranges,
                "error_mm": null,
                "bits": p.payload.as_ref().map(|pl| format!("{} errors in {}", pl.bit_errors, pl.bits)),
                "skipped": false,
                "x": k,
                "y": strongest,
            })));
            l.send(Event::ProfileFile {
                csv: dir.join("profile.csv"),
                detections: p.targets.iter().map(|t| (t.range_m, t.level_db)).collect(),
                truth: truth_ranges(m.taken.ground_truth.as_ref()),
                label: format!("capture {k}"),
            });
            live_cli::capture_warnings(l, bench, k, &p.warnings);
        }
        if args.json {
            summary["capture"] = json!(k);
            summary["dir"] = json!(dir);
            super::terminal::out(&summary.to_string())?;
        } else {
            super::terminal::out(&format!("capture {k}/{of}\n{}", report(&m, &dir)))?;
        }
        if let Some(signal) = interrupt.received() {
            eprintln!(
                "{} received during capture {k}: the bench is safe and its files are written to {}",
                signal.name(),
                dir.display()
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

/// A simulated bench's true target ranges (its ground truth).
pub(crate) fn truth_ranges(truth: Option<&serde_json::Value>) -> Vec<f64> {
    truth
        .and_then(|t| t["targets"].as_array())
        .map(|t| t.iter().filter_map(|x| x["range_m"].as_f64()).collect())
        .unwrap_or_default()
}
