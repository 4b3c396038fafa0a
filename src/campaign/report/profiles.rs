//! Every step's range profile in one plot: a waterfall against the steps (one row per step,
//! labelled with its swept value), each profile drawn from its peak down to 40 dB under it,
//! the step's nominal target ranges marked at the height of its peak. It reads for any campaign: the pillar
//! walking toward the radar (accuracy), two peaks merging (resolution), the floor rising with
//! the attenuation (link). Drawn from each step's own `profile.csv` (the first algorithm's
//! column), so `campaign report` draws it again from the run folder.
//!
//! Past [`MAX_STACKED`] steps stacked rows would be a grey block: the profiles are then a heat
//! map instead (range x step, dB under each step's peak, with its colour bar).

use super::figures::Figure;
use super::plots::{Chart, Heat, Point, Series, Style};
use crate::campaign::Results;
use std::path::Path;

/// Depth of each row, dB under the step's peak.
const DEPTH_DB: f64 = 40.0;
/// Margin around the nominal targets, metres.
const MARGIN_M: f64 = 0.6;
/// Points per profile at most (thinned evenly, peaks kept by taking each bin's maximum).
const MAX_POINTS: usize = 600;
/// Steps drawn as stacked profiles at most; more draw a heat map.
pub(crate) const MAX_STACKED: usize = 24;
/// Range cells of the heat map at most (each the maximum of the profile's points in it).
const HEAT_CELLS: usize = 240;

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
    if steps.len() > MAX_STACKED {
        return heat_map(&steps, window);
    }
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

/// The profiles as a heat map: a row per step (y: the step's number), range cells of the
/// window across, each cell the highest point of the profile in it, in dB under the step's peak.
fn heat_map(
    steps: &[(&crate::campaign::StepResult, Vec<(f64, f64)>)],
    window: Option<(f64, f64)>,
) -> Option<Figure> {
    let (lo, hi) = window.or_else(|| {
        let all = steps.iter().flat_map(|(_, p)| p.iter().map(|q| q.0));
        let lo = all.clone().fold(f64::INFINITY, f64::min);
        let hi = all.fold(f64::NEG_INFINITY, f64::max);
        (lo < hi).then_some((lo, hi))
    })?;
    let width = (hi - lo) / HEAT_CELLS as f64;
    let x: Vec<f64> = (0..HEAT_CELLS)
        .map(|k| lo + (k as f64 + 0.5) * width)
        .collect();
    let mut rows = Vec::new();
    let mut nominal = Vec::new();
    for (s, profile) in steps {
        let mut cells = vec![f64::NEG_INFINITY; HEAT_CELLS];
        for &(r, v) in profile {
            let k = ((r - lo) / width).floor();
            if k >= 0.0 && (k as usize) < HEAT_CELLS {
                let c = &mut cells[k as usize];
                *c = c.max(v);
            }
        }
        let peak = cells.iter().copied().fold(f64::NEG_INFINITY, f64::max);
        if !peak.is_finite() {
            continue;
        }
        // A cell no point fell in (a coarse profile) takes its left neighbour's value.
        let mut last = peak - DEPTH_DB;
        for c in cells.iter_mut() {
            if c.is_finite() {
                last = *c;
            } else {
                *c = last;
            }
            *c = (*c - peak).clamp(-DEPTH_DB, 0.0);
        }
        let y = s.index as f64;
        rows.push((y, cells));
        nominal.extend(s.nominal.ranges().into_iter().map(|r| Point {
            x: r,
            y,
            bar: None,
            filled: false,
        }));
    }
    if rows.is_empty() {
        return None;
    }
    let mut chart = Chart::new(
        "Range profile of every step (heat map)",
        "range (m)",
        "step",
    );
    chart.heat = Some(Heat {
        x,
        rows,
        depth: DEPTH_DB,
        label: "dB under the step's peak".into(),
    });
    if !nominal.is_empty() {
        chart.series.push(Series {
            label: "nominal target range".into(),
            points: nominal,
            style: Style::Markers,
        });
    }
    Some(Figure {
        id: "step-heatmap",
        caption: format!(
            "Every step's range profile (the first algorithm's, from its step folder's \
             profile.csv) as a heat map: one row per step, {HEAT_CELLS} range cells within \
             {MARGIN_M} m of the nominal targets, each the highest level in it, coloured from the \
             step's peak (bright) down to {DEPTH_DB} dB under it (dark); hollow markers: the \
             nominal target ranges. More than {MAX_STACKED} steps draw this map instead of \
             stacked profiles."
        ),
        chart,
    })
}
