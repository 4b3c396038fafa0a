//! What a measurement's plot and profile table show, from the processed result: every curve
//! (the primary profile, overlays, the detection threshold), every detection marked with its range
//! and level, the grid-free estimates, over the whole processed range. The table holds every curve
//! the plot shows, on the primary profile's axis.

use crate::dsp::Profile;
use crate::measure::processing::detect::Detection;
use crate::measure::processing::options::ProcessOptions;
use crate::measure::processing::pipeline::Processed;
use crate::storage::profile::ProfileTable;
use crate::storage::{Curve, LineStyle, Marker, ProfilePlot};

fn db(a: f64) -> f64 {
    20.0 * a.max(1e-300).log10()
}

/// The profile's values in dB on the axis `ranges` (linear interpolation of the dB curve; the
/// curve's own end values beyond its axis).
fn resampled_db(p: &Profile, values_db: &[f64], ranges: &[f64]) -> Vec<f64> {
    let n = values_db.len();
    ranges
        .iter()
        .map(|&r| {
            let x = (r - p.axis.start) / p.axis.step;
            if n == 0 {
                return f64::NAN;
            }
            let x = x.clamp(0.0, (n - 1) as f64);
            let i = (x.floor() as usize).min(n - 1);
            let j = (i + 1).min(n - 1);
            let f = x - i as f64;
            values_db[i] * (1.0 - f) + values_db[j] * f
        })
        .collect()
}

/// The highest value of a profile inside `window` (metres).
fn peak_in(p: &Profile, window: (f64, f64)) -> f64 {
    p.amplitude
        .iter()
        .enumerate()
        .filter(|(i, _)| {
            let r = p.axis.at(*i as f64);
            r >= window.0 && r <= window.1
        })
        .map(|(_, a)| *a)
        .fold(0.0, f64::max)
}

/// A profile's curve: level in dB re a unit-gain path, or for MUSIC's pseudo-spectrum
/// `10 log10 P` (it has no level of its own) moved so its value at `anchor` (range, level: the
/// strongest detection) sits at that level.
fn curve_db(p: &Profile, anchor: Option<(f64, f64)>, window: (f64, f64)) -> (String, Vec<f64>) {
    if p.label.starts_with("MUSIC") {
        let raw: Vec<f64> = p.amplitude.iter().map(|a| db(*a)).collect();
        let shift = match anchor {
            Some((range, level)) => {
                let near = (range - 0.01, range + 0.01);
                level - db(peak_in(p, near))
            }
            None => -db(peak_in(p, window)),
        };
        (
            format!(
                "{} pseudo-spectrum, placed at the strongest detection",
                p.label
            ),
            raw.iter().map(|v| v + shift).collect(),
        )
    } else {
        (
            p.label.clone(),
            p.amplitude.iter().map(|a| db(*a)).collect(),
        )
    }
}

fn column_name(label: &str) -> String {
    let base = label
        .split([' ', '('])
        .next()
        .unwrap_or("profile")
        .to_lowercase();
    format!("{base}_db")
}

fn marker(d: &Detection) -> Marker {
    Marker {
        range_m: d.range_m,
        db: d.level_db,
        label: format!("{:.3} m, {:.1} dB", d.range_m, d.level_db),
    }
}

/// The plot and the table of a processed measurement. `truth_m`: a simulated bench's true ranges.
pub fn profile_figure(
    title: String,
    p: &Processed,
    options: &ProcessOptions,
    truth_m: Vec<f64>,
) -> (ProfilePlot, ProfileTable) {
    let primary = &p.profiles[0];
    // The whole processed range is shown.
    let window = (0.0_f64.min(options.min_range_m), options.max_range_m);
    // MUSIC's pseudo-spectrum is placed at the strongest detection's level.
    let anchor = p
        .targets
        .iter()
        .max_by(|a, b| a.level_db.total_cmp(&b.level_db))
        .map(|t| (t.range_m, t.level_db));
    let curves: Vec<(String, Vec<f64>, &Profile)> = p
        .profiles
        .iter()
        .map(|x| {
            let (label, values) = curve_db(x, anchor, (options.min_range_m, options.max_range_m));
            (label, values, x)
        })
        .collect();
    // Overlays first, the primary profile last: drawn on top, its narrow peaks stay visible.
    let mut plot_curves: Vec<Curve> = curves
        .iter()
        .rev()
        .map(|(label, values, x)| Curve::solid(label.clone(), x.ranges(), values.clone()))
        .collect();
    let ranges = primary.ranges();
    let mut columns: Vec<(String, Vec<f64>)> = curves
        .iter()
        .map(|(label, values, x)| {
            let on_primary = if x.axis == primary.axis && values.len() == ranges.len() {
                values.clone()
            } else {
                resampled_db(x, values, &ranges)
            };
            (column_name(label), on_primary)
        })
        .collect();
    if p.detection.residual.len() == ranges.len() {
        let r: Vec<f64> = p.detection.residual.iter().map(|a| db(*a)).collect();
        plot_curves.push(Curve {
            label: "residual: the profile minus every detection".into(),
            range_m: ranges.clone(),
            db: r.clone(),
            style: LineStyle::Solid,
        });
        columns.push(("residual_db".into(), r));
    }
    if p.detection.threshold.len() == ranges.len() {
        let t: Vec<f64> = p.detection.threshold.iter().map(|a| db(*a)).collect();
        plot_curves.push(Curve {
            label: format!(
                "{} threshold on the residual (Pfa {:.0e} per cell)",
                options.detector.name(),
                options.pfa
            ),
            range_m: ranges.clone(),
            db: t.clone(),
            style: LineStyle::Dashed,
        });
        columns.push(("threshold_db".into(), t));
    }
    let grid_free = options.algorithm.is_grid_free();
    let plot = ProfilePlot {
        targets_m: truth_m,
        estimates_m: if grid_free {
            p.targets.iter().map(|t| t.range_m).collect()
        } else {
            Vec::new()
        },
        markers: p.targets.iter().map(marker).collect(),
        window_m: Some(window),
        floor_db: None,
        reference_db: None,
        y_label: "Level (dB re a unit-gain path)".into(),
        ..ProfilePlot::new(title, plot_curves)
    };
    let table = ProfileTable {
        range_m: ranges,
        columns,
    };
    (plot, table)
}

/// The range-Doppler map of an OFDM frame as a heat map over the processed range, the detections
/// marked at their velocity.
pub(crate) fn range_doppler_figure(
    title: String,
    map: &crate::dsp::RangeDopplerMap,
    targets: &[Detection],
    options: &ProcessOptions,
) -> crate::storage::plot::Heatmap {
    crate::storage::plot::Heatmap {
        title,
        x_label: "Range (m)".into(),
        y_label: "Radial velocity (m/s, + receding)".into(),
        x: map.range_m.clone(),
        y: map.velocity_mps.clone(),
        db: map.amplitude.iter().map(|a| db(*a)).collect(),
        x_window: (0.0_f64.min(options.min_range_m), options.max_range_m),
        range_db: 50.0,
        marks: targets
            .iter()
            .filter_map(|t| Some((t.range_m, t.velocity_mps?)))
            .collect(),
    }
}
