//! The figures of a sweep over any settings (campaign/kind.rs (`SETTINGS`)): one figure per metric against
//! the inner (last) axis, one line per combination of the outer axes' values (and per algorithm
//! when the steps apply several). Every plotted number is a number of `results.json`.

use super::figures::Figure;
use super::plots::{Chart, Point, Series, Style};
use crate::campaign::axis::AxisValue;
use crate::campaign::kind::Setting;
use crate::campaign::{AlgorithmResult, StepResult};

/// A metric of `results.json`'s algorithm results: figure id, title, y label, how it reads.
type Metric = (
    &'static str,
    &'static str,
    &'static str,
    fn(&AlgorithmResult) -> Option<f64>,
);

const METRICS: [Metric; 5] = [
    ("sweep-error", "Range error", "error (m)", |a| a.error_m),
    ("sweep-width", "-3 dB width", "width (cm)", |a| {
        a.width_3db_cm
    }),
    ("sweep-psl", "Peak side-lobe level", "PSL (dB)", |a| {
        a.sidelobe_db
    }),
    (
        "sweep-snr",
        "SNR of the strongest target",
        "SNR (dB)",
        |a| a.snr_db,
    ),
    ("sweep-ber", "Bit-error rate", "BER", |a| {
        a.payload.as_ref().map(|p| p.ber)
    }),
];

/// The sweep figures of these steps (none when no step names its axes).
pub(crate) fn sweep_figures(steps: &[StepResult]) -> Vec<Figure> {
    let swept: Vec<&StepResult> = steps
        .iter()
        .filter(|s| !s.nominal.axes.is_empty())
        .collect();
    let Some(inner) = swept.first().and_then(|s| s.nominal.axes.last()) else {
        return Vec::new();
    };
    let inner_name = inner.name.clone();
    let label = Setting::named(&inner_name).map_or(inner_name.clone(), |s| s.label());
    // Names on a categorical axis, in the order of first use.
    let mut categories: Vec<String> = Vec::new();
    let named = matches!(inner.value, AxisValue::Name(_));
    for s in &swept {
        if let Some(AxisValue::Name(n)) = s.nominal.axes.last().map(|a| &a.value) {
            if !categories.contains(n) {
                categories.push(n.clone());
            }
        }
    }
    let mut algorithms: Vec<&str> = Vec::new();
    for s in &swept {
        for a in s.algorithms.keys() {
            if !algorithms.contains(&a.as_str()) {
                algorithms.push(a);
            }
        }
    }
    // The algorithm is named in a line's label only when it is not what the inner axis sweeps.
    let by_algorithm = algorithms.len() > 1 && inner_name != "algorithm";
    let mut out = Vec::new();
    for (id, title, y_label, read) in METRICS {
        let mut series: Vec<Series> = Vec::new();
        for s in &swept {
            let axes = &s.nominal.axes;
            let Some(x) = axes.last().and_then(|a| match &a.value {
                AxisValue::Number(v) => Some(*v),
                AxisValue::Name(n) => categories.iter().position(|c| c == n).map(|i| i as f64),
            }) else {
                continue;
            };
            let outer: Vec<String> = axes[..axes.len() - 1]
                .iter()
                .map(|a| format!("{} {}", a.name, a.value))
                .collect();
            for (name, a) in &s.algorithms {
                let Some(y) = read(a).filter(|y| y.is_finite()) else {
                    continue;
                };
                let mut parts = outer.clone();
                if by_algorithm {
                    parts.push(name.clone());
                }
                let line = if parts.is_empty() {
                    title.to_string()
                } else {
                    parts.join(", ")
                };
                match series.iter_mut().find(|l| l.label == line) {
                    Some(l) => l.points.push(Point::new(x, y)),
                    None => series.push(Series {
                        label: line,
                        points: vec![Point::new(x, y)],
                        style: Style::Line,
                    }),
                }
            }
        }
        if series.is_empty() {
            continue;
        }
        let mut chart = Chart::new(format!("{title} against {inner_name}"), &label, y_label);
        chart.log_y = id == "sweep-ber";
        if named {
            chart.x_categories = Some(categories.clone());
        }
        chart.series = series;
        out.push(Figure {
            id,
            caption: format!(
                "{title} of every step against {label}, one line per value of the outer axes \
                 (results.json's `{}`).",
                metric_field(id)
            ),
            chart,
        });
    }
    out
}

/// The `results.json` field a sweep figure plots.
fn metric_field(id: &str) -> &'static str {
    match id {
        "sweep-error" => "error_m",
        "sweep-width" => "width_3db_cm",
        "sweep-psl" => "sidelobe_db",
        "sweep-snr" => "snr_db",
        _ => "payload.ber",
    }
}
