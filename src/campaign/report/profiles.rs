//! Every step's range profile in one plot: a waterfall against the steps (one row per step,
//! labelled with its swept value), each profile drawn from its peak down to 40 dB under it,
//! the step's nominal target ranges marked at the height of its peak. It reads for any campaign: the pillar
//! walking toward the radar (accuracy), two peaks merging (resolution), the floor rising with
//! the attenuation (link). Drawn from each step's own `profile.csv` (the first algorithm's
//! column), so `campaign report` draws it again from the run folder.

use super::figures::Figure;
use super::plots::{Chart, Point, Series, Style};
use crate::campaign::Results;
use std::path::Path;

/// Depth of each row, dB under the step's peak.
const DEPTH_DB: f64 = 40.0;
/// Margin around the nominal targets, metres.
const MARGIN_M: f64 = 0.6;
/// Points per profile at most (thinned evenly, peaks kept by taking each bin's maximum).
const MAX_POINTS: usize = 600;

/// A step's profile: (range, dB) of its first dB column.
fn read_profile(path: &Path) -> Option<Vec<(f64, f64)>> {
    let text = std::fs::read_to_string(path).ok()?;
    let mut lines = text.lines();
    let header: Vec<&str> = lines.next()?.split(',').collect();
    if header.first() != Some(&"range_m") || header.len() < 2 {
        return None;
    }
    let rows: Vec<(f64, f64)> = lines
        .filter_map(|l| {
            let mut f = l.split(',');
            let r: f64 = f.next()?.parse().ok()?;
            let v: f64 = f.next()?.parse().ok()?;
            (r.is_finite() && v.is_finite()).then_some((r, v))
        })
        .collect();
    (!rows.is_empty()).then_some(rows)
}

/// At most `MAX_POINTS` points: each of as many bins keeps its highest point.
fn thin(rows: &[(f64, f64)]) -> Vec<(f64, f64)> {
    let per = rows.len().div_ceil(MAX_POINTS).max(1);
    rows.chunks(per)
        .filter_map(|c| c.iter().copied().max_by(|a, b| a.1.total_cmp(&b.1)))
        .collect()
}

/// The waterfall of every step's profile in `dir` (a run folder); `None` when no step has one.
pub fn step_profiles(dir: &Path, results: &Results) -> Option<Figure> {
    let steps: Vec<_> = results
        .steps
        .iter()
        .filter_map(|s| {
            read_profile(&dir.join(format!("step-{:03}", s.index)).join("profile.csv"))
                .map(|p| (s, p))
        })
        .collect();
    if steps.is_empty() {
        return None;
    }
    let targets: Vec<f64> = steps.iter().flat_map(|(s, _)| s.nominal.ranges()).collect();
    let window = match (
        targets.iter().copied().reduce(f64::min),
        targets.iter().copied().reduce(f64::max),
    ) {
        (Some(lo), Some(hi)) => Some((lo - MARGIN_M, hi + MARGIN_M)),
        _ => None,
    };
    let mut chart = Chart::new(
        "Range profile of every step",
        "range (m)",
        "step (swept value)",
    );
    let mut labels = Vec::new();
    let mut nominal = Vec::new();
    for (row, (s, profile)) in steps.iter().enumerate() {
        let inside: Vec<(f64, f64)> = profile
            .iter()
            .copied()
            .filter(|(r, _)| window.is_none_or(|(lo, hi)| (lo..=hi).contains(r)))
            .collect();
        let peak = inside.iter().map(|p| p.1).fold(f64::NEG_INFINITY, f64::max);
        if !peak.is_finite() {
            labels.push(format!("step {}", s.index));
            continue;
        }
        let base = row as f64 - 0.45;
        let points = thin(&inside)
            .into_iter()
            .map(|(r, v)| {
                let depth = (v - peak).clamp(-DEPTH_DB, 0.0);
                Point::new(r, base + 0.9 * (depth + DEPTH_DB) / DEPTH_DB)
            })
            .collect();
        chart.series.push(Series {
            label: if row == 0 {
                format!("each step's profile, its peak to {DEPTH_DB} dB under it")
            } else {
                String::new()
            },
            points,
            style: Style::Trace,
        });
        nominal.extend(s.nominal.ranges().into_iter().map(|r| Point {
            x: r,
            y: base + 0.9,
            bar: None,
            filled: false,
        }));
        let value = match (&s.nominal.parameter, s.nominal.value) {
            (Some(p), Some(v)) => format!("{p} {}", (v * 1e6).round() / 1e6),
            _ => s.nominal.describe(),
        };
        labels.push(format!("{}: {value}", s.index));
    }
    if chart.series.is_empty() {
        return None;
    }
    if !nominal.is_empty() {
        chart.series.push(Series {
            label: "nominal target range".into(),
            points: nominal,
            style: Style::Markers,
        });
    }
    chart.y_categories = Some(labels);
    Some(Figure {
        id: "step-profiles",
        caption: format!(
            "Every step's range profile (the first algorithm's, from its step folder's \
             profile.csv), one row per step from its peak (top of the row) down to {DEPTH_DB} \
             dB under it (bottom), within {MARGIN_M} m of the nominal targets (hollow markers \
             at the height of the row's peak: a peak under its marker is on target)."
        ),
        chart,
    })
}
