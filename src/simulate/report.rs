//! Plain-text reports for the terminal: one scenario, the thesis table, BER curves.

use super::ber::BerCurvePoint;
use super::spec::ScenarioResult;
use std::fmt::Write as _;

fn list_m(values: &[f64]) -> String {
    if values.is_empty() {
        return "none".into();
    }
    values
        .iter()
        .map(|v| format!("{v:.4}"))
        .collect::<Vec<_>>()
        .join(", ")
}

/// A human-readable summary of one scenario.
pub fn scenario_text(r: &ScenarioResult) -> String {
    let mut out = String::new();
    let _ = writeln!(
        out,
        "{} | {} | {} | carrier phase {} | SNR {} | capture {:.3} GSa/s | seed {}",
        r.id,
        r.waveform,
        r.algorithm,
        r.carrier_phase,
        r.snr_db
            .map(|s| format!("{s} dB/sample"))
            .unwrap_or_else(|| "noise-free".into()),
        r.capture_rate_hz / 1e9,
        r.seed
    );
    let _ = writeln!(out, "  targets (m):   {}", list_m(&r.targets_m));
    let _ = writeln!(out, "  peaks (m):     {}", list_m(&r.peaks_m));
    let errors: Vec<String> = r
        .errors_cm
        .iter()
        .map(|e| {
            e.map(|v| format!("{v:+.3}"))
                .unwrap_or_else(|| "missed".into())
        })
        .collect();
    let _ = writeln!(out, "  errors (cm):   {}", errors.join(", "));
    if let Some(w) = r.width_3db_cm {
        let _ = writeln!(out, "  -3 dB width:   {w:.2} cm");
    }
    if let Some(s) = r.sidelobe_db {
        let _ = writeln!(out, "  peak side-lobe: {s:.2} dB");
    }
    let _ = writeln!(
        out,
        "  resolved:      {}",
        if r.resolved { "yes" } else { "no" }
    );
    if let Some(rate) = r.resolved_rate {
        let _ = writeln!(
            out,
            "  resolved rate: {:.1} % of {} trials",
            100.0 * rate,
            r.trials
        );
    }
    for (k, v) in &r.extra {
        match (k.as_str(), v) {
            // A scene run (`--scene`): the capture's detections, its warnings and clipping; the
            // scene itself is in the JSON.
            ("scene", _) => Ok(()),
            ("targets", serde_json::Value::Array(targets)) => scene_targets_text(&mut out, targets),
            ("warnings", serde_json::Value::Array(warnings)) => warnings
                .iter()
                .try_for_each(|w| writeln!(out, "  warning: {}", w.as_str().unwrap_or_default())),
            ("clipped_samples", c) if c.is_object() => writeln!(
                out,
                "  clipped samples: {} (I), {} (Q) of {}",
                c["i"], c["q"], c["samples"]
            ),
            _ => match v.as_str() {
                Some(text) => writeln!(out, "  {k}: {text}"),
                None => writeln!(out, "  {k}: {v}"),
            },
        }
        .ok();
    }
    out
}

/// The detections of a scene run, as `capture` prints them: range and level.
fn scene_targets_text(out: &mut String, targets: &[serde_json::Value]) -> std::fmt::Result {
    if targets.is_empty() {
        return writeln!(out, "  detections:    none");
    }
    writeln!(out, "  detections:")?;
    for t in targets {
        writeln!(
            out,
            "    {:>9.4} m   {:>6.1} dB",
            t["range_m"].as_f64().unwrap_or(f64::NAN),
            t["level_db"].as_f64().unwrap_or(f64::NAN)
        )?;
    }
    Ok(())
}

/// BER curves as a table: measured, theory, 95 % interval, verdict.
pub fn ber_text(points: &[BerCurvePoint]) -> String {
    let mut out = String::new();
    let _ = writeln!(
        out,
        "{:<8} {:>6} {:>10} {:>8} {:>11} {:>11} {:>23}  within  {:>6}",
        "waveform", "Eb/N0", "bits", "errors", "BER", "theory", "95 % interval", "dev"
    );
    // Nothing counted reads `0`, not `0.000e0`.
    let sci = |x: f64| {
        if x == 0.0 {
            "0".to_string()
        } else {
            format!("{x:.3e}")
        }
    };
    for p in points {
        let _ = writeln!(
            out,
            "{:<8} {:>5.1}  {:>10} {:>8} {:>11} {:>11} [{:>9}, {:>9}]  {:<6}  {:>+5.1}σ",
            p.waveform,
            p.eb_n0_db,
            p.bits,
            p.bit_errors,
            sci(p.ber),
            sci(p.ber_theory),
            sci(p.ci95_low),
            sci(p.ci95_high),
            if p.theory_within_ci95 { "yes" } else { "no" },
            p.deviation_sigma
        );
    }
    let inside = points.iter().filter(|p| p.theory_within_ci95).count();
    let worst = points
        .iter()
        .map(|p| p.deviation_sigma.abs())
        .fold(0.0, f64::max);
    let _ = writeln!(
        out,
        "{inside} of {} points hold theory in their 95 % interval (Wilson score on the bit count, \
         bits independent); by chance about {:.1} are expected outside. Largest deviation {worst:.1} \
         standard deviations{}.",
        points.len(),
        0.05 * points.len() as f64,
        if worst <= 3.5 {
            ": consistent with theory"
        } else {
            ": more than chance explains, check the receiver"
        }
    );
    out
}
