//! Which plots a run gets, from its plan and `results.json` alone:
//!
//! | steps | figure |
//! |---|---|
//! The swept kinds' own figures are named in campaign/kind.rs (one table); the others follow from
//! the steps' targets.
//!
//! | swept `position` | range error per step against the nominal position, interpolated and on the grid, with the ±c0/(2 fs) and ±c0/(4 fs) bounds (thesis Fig. 4.13) |
//! | two or more targets | resolved or not against the separation, per algorithm and bandwidth |
//! | one target, not swept in position / attenuation / SNR | -3 dB width and peak side-lobe level per step, the thesis' simulation and lab values beside (Tables 4.5, 4.7) |
//! | swept `tx-attenuation` or `snr` | BER (95 % interval) with the waveform's theory and the BER the measured MER implies, EVM (rms, 95th percentile) with the white-noise line, -3 dB width, PSL and range error |
//!
//! Every plotted number is a number of `results.json` (or computed from one: BER intervals, the
//! theory curve); nothing is invented.

use super::plots::{Chart, HLine, Point, Series, Style};
use crate::campaign::axis::SweepParameter;
use crate::campaign::Manifest;
use crate::campaign::{AlgorithmResult, MeanStd, SpreadFigures, StepResult};
use crate::physics::C0;
use crate::waveform::{WaveformKind, WaveformSpec};

/// One plot of the report.
#[derive(Debug, Clone, PartialEq)]
pub struct Figure {
    /// Stable id (`accuracy-error`, `resolution`, `single-width`, `single-psl`, `link-ber`,
    /// `link-width`, `link-psl`, `link-error`): the html element's id.
    pub id: &'static str,
    /// What the plot shows, one paragraph.
    pub caption: String,
    pub chart: Chart,
}

/// The thesis' single-target figures of a family (its room holds them).
pub(crate) use crate::measure::processing::family::ThesisWidths;

/// Tables 4.5 (MSK-LFM) and 4.7 (OFDM) and the lab sections 4.4.1 / 4.5.1, at 1 GHz; `None` for
/// a family the thesis did not measure.
pub(crate) fn thesis_widths(kind: WaveformKind) -> Option<ThesisWidths> {
    crate::measure::processing::family::of_kind(kind).thesis_widths()
}

/// The waveform a step used.
pub(crate) fn waveform_of(manifest: &Manifest, step: &StepResult) -> Option<WaveformSpec> {
    let plan = &manifest.plan;
    let s = plan.steps.iter().find(|s| s.index == step.index)?;
    plan.waveforms.get(s.waveform).copied()
}

pub(crate) fn is_accuracy(s: &StepResult) -> bool {
    s.nominal.parameter == Some(SweepParameter::Position)
}

pub(crate) fn is_resolution(s: &StepResult) -> bool {
    s.nominal.targets.len() >= 2
}

/// The smallest separation of a step's nominal targets, metres.
pub(crate) fn separation_m(s: &StepResult) -> Option<f64> {
    let r = s.nominal.ranges();
    r.windows(2).map(|w| (w[1] - w[0]).abs()).reduce(f64::min)
}

/// Wilson score interval (95 %) of a bit-error rate.
pub fn wilson95(errors: usize, bits: usize) -> (f64, f64) {
    if bits == 0 {
        return (0.0, 1.0);
    }
    let n = bits as f64;
    let p = errors as f64 / n;
    let z = 1.959_963_984_540_054_f64;
    let d = 1.0 + z * z / n;
    let centre = (p + z * z / (2.0 * n)) / d;
    let half = z * (p * (1.0 - p) / n + z * z / (4.0 * n * n)).sqrt() / d;
    ((centre - half).max(0.0), (centre + half).min(1.0))
}

/// The waveform's theoretical BER at `ebn0_db` (thesis-notes: MSK-LFM Q(sqrt(2 Eb/N0)), OFDM
/// Q(sqrt(2 Eb/N0 / (1 + cp)))).
pub fn theory(w: &WaveformSpec, ebn0_db: f64) -> f64 {
    crate::measure::processing::family::of(w).ber_theory(ebn0_db)
}

/// The Eb/N0 (dB) at which the theory gives `ber` (bisection; 0 < ber < 0.5).
pub(crate) fn theory_ebn0_db(w: &WaveformSpec, ber: f64) -> Option<f64> {
    if !(ber > 0.0 && ber < 0.5) {
        return None;
    }
    let (mut lo, mut hi) = (-40.0_f64, 40.0_f64);
    for _ in 0..100 {
        let mid = (lo + hi) / 2.0;
        if theory(w, mid) > ber {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    Some((lo + hi) / 2.0)
}

/// The algorithm names of these steps, in order of first use.
fn algorithms(steps: &[&StepResult]) -> Vec<String> {
    let mut names: Vec<String> = Vec::new();
    for s in steps {
        for n in s.algorithms.keys() {
            if !names.contains(n) {
                names.push(n.clone());
            }
        }
    }
    names
}

pub(crate) fn accuracy(manifest: &Manifest, steps: &[&StepResult]) -> Option<Figure> {
    let fs = waveform_of(manifest, steps[0])?.sample_rate_hz();
    let half = C0 / (2.0 * fs) * 100.0;
    let quarter = C0 / (4.0 * fs) * 100.0;
    let mut chart = Chart::new(
        "Range error against the nominal position",
        "nominal position (m)",
        "measured - nominal range (cm)",
    );
    for name in algorithms(steps) {
        let of = |f: &dyn Fn(&AlgorithmResult) -> Option<Point>| -> Vec<Point> {
            steps
                .iter()
                .filter_map(|s| {
                    let x = *s.nominal.ranges().first()?;
                    let a = s.algorithms.get(&name)?;
                    f(a).map(|mut p| {
                        p.x = x;
                        p
                    })
                })
                .collect()
        };
        chart.series.push(Series {
            label: format!("{name}, sub-sample interpolation (±1 std)"),
            points: of(&|a| {
                let e = a.error_m?;
                let std = strongest_range_std(a);
                Some(Point::new(0.0, e * 100.0).with_std(std.map(|s| s * 100.0)))
            }),
            style: Style::Line,
        });
        chart.series.push(Series {
            label: format!("{name}, on the grid (no interpolation)"),
            points: of(&|a| Some(Point::new(0.0, a.error_on_grid_m? * 100.0))),
            style: Style::Line,
        });
    }
    chart.series.retain(|s| !s.points.is_empty());
    if chart.series.is_empty() {
        return None;
    }
    for (y, label) in [
        (half, format!("±c0/(2 fs) = {half:.3} cm (thesis bound)")),
        (
            quarter,
            format!("±c0/(4 fs) = {quarter:.3} cm (half a cell)"),
        ),
    ] {
        chart.hlines.push(HLine {
            y,
            label,
            dashed: y == quarter,
        });
        chart.hlines.push(HLine {
            y: -y,
            label: String::new(),
            dashed: y == quarter,
        });
    }
    Some(Figure {
        id: "accuracy-error",
        caption: format!(
            "Measured minus nominal range at each step (thesis Fig. 4.13), with sub-sample \
             interpolation (error bars: ±1 standard deviation of the repetitions' ranges, when \
             there are several) and without it (the detection's nearest profile cell). Bounds for \
             fs = {} GSa/s: ±c0/(2 fs) is the thesis' bound, ±c0/(4 fs) half a sample, the \
             largest error rounding to the grid can make.",
            fs / 1e9
        ),
        chart,
    })
}

/// The range error against the targets' radial velocity (a `velocity` sweep): against the ground
/// truth where it is known (simulated benches), else against the nominal range; for an MSK-LFM
/// chirp, the range-Doppler coupling's prediction beside it.
pub(crate) fn velocity(manifest: &Manifest, steps: &[&StepResult]) -> Option<Figure> {
    let mut chart = Chart::new(
        "Range error against the targets' velocity",
        "radial velocity (m/s, + receding)",
        "measured - true range (cm)",
    );
    for name in algorithms(steps) {
        let points: Vec<Point> = steps
            .iter()
            .filter_map(|s| {
                let v = s.nominal.velocity_mps?;
                let a = s.algorithms.get(&name)?;
                let e = a.truth_error_m.or(a.error_m)?;
                Some(Point::new(v, e * 100.0))
            })
            .collect();
        chart.series.push(Series {
            label: name,
            points,
            style: Style::Line,
        });
    }
    chart.series.retain(|s| !s.points.is_empty());
    if chart.series.is_empty() {
        return None;
    }
    // An LFM chirp of duration T over B maps a Doppler shift fd onto a delay fd T / B: a range
    // shift of v fc T / B for a target at v (fd = -2 v fc / c0, the mock lab's convention).
    let carrier = manifest
        .plan
        .bench
        .scene
        .as_ref()
        .or(manifest.base_scene.as_ref())
        .map(|s| s.carrier_hz);
    let mut coupling = String::new();
    if let (
        Some(fc),
        Some(WaveformSpec::MskLfm {
            pulse_s,
            bandwidth_hz,
            ..
        }),
    ) = (carrier, waveform_of(manifest, steps[0]))
    {
        let k = fc * pulse_s / bandwidth_hz;
        let vs: Vec<f64> = steps
            .iter()
            .filter_map(|s| s.nominal.velocity_mps)
            .collect();
        let (lo, hi) = vs
            .iter()
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), &v| {
                (a.min(v), b.max(v))
            });
        chart.series.push(Series {
            label: format!(
                "range-Doppler coupling, fc T / B = {:.3} mm per m/s",
                k * 1e3
            ),
            points: vec![
                Point::new(lo, COUPLING_SIGN * k * lo * 100.0),
                Point::new(hi, COUPLING_SIGN * k * hi * 100.0),
            ],
            style: Style::Dashed,
        });
        coupling = format!(
            " The dashed line is the chirp's range-Doppler coupling: a Doppler shift fd moves the \
             correlation peak by fd T / B, a range shift of v fc T / B ({:.3} mm per m/s at \
             fc = {} GHz, T = {} us, B = {} GHz).",
            k * 1e3,
            fc / 1e9,
            pulse_s * 1e6,
            bandwidth_hz / 1e9
        );
    }
    Some(Figure {
        id: "velocity-error",
        caption: format!(
            "Measured minus true range (the simulated ground truth; the nominal range on a bench \
             without one) at each step, against the targets' radial velocity.{coupling}"
        ),
        chart,
    })
}

/// The sign of the chirp's range-Doppler coupling on the mock lab (a receding target, v > 0,
/// fd < 0).
const COUPLING_SIGN: f64 = 1.0;

/// The repetitions' range spread of the target nearest the error (the strongest, in practice
/// the only one of an accuracy step).
fn strongest_range_std(a: &AlgorithmResult) -> Option<f64> {
    a.targets
        .iter()
        .max_by(|x, y| x.level_db.total_cmp(&y.level_db))
        .and_then(|t| t.range_std_m)
}

pub(super) fn resolution(steps: &[&StepResult]) -> Option<Figure> {
    let mut rows: Vec<(String, f64)> = Vec::new();
    for s in steps {
        for (name, a) in &s.algorithms {
            if a.resolved.is_some() && !rows.contains(&(name.clone(), s.nominal.bandwidth_hz)) {
                rows.push((name.clone(), s.nominal.bandwidth_hz));
            }
        }
    }
    if rows.is_empty() {
        return None;
    }
    let labels: Vec<String> = rows
        .iter()
        .map(|(n, b)| format!("{n}, {} GHz", b / 1e9))
        .collect();
    let mut chart = Chart::new(
        "Resolved (filled) or not (hollow) against the separation",
        "separation of the targets (cm)",
        "",
    );
    chart.y_categories = Some(labels.clone());
    for (k, (name, bw)) in rows.iter().enumerate() {
        let points = steps
            .iter()
            .filter(|s| s.nominal.bandwidth_hz == *bw)
            .filter_map(|s| {
                let r = s.algorithms.get(name)?.resolved?;
                Some(Point {
                    x: separation_m(s)? * 100.0,
                    y: k as f64,
                    bar: None,
                    filled: r,
                })
            })
            .collect();
        chart.series.push(Series {
            label: labels[k].clone(),
            points,
            style: Style::Markers,
        });
    }
    let bandwidths = rows
        .iter()
        .map(|(_, b)| *b)
        .fold(Vec::<f64>::new(), |mut v, b| {
            if !v.contains(&b) {
                v.push(b);
            }
            v
        });
    for b in &bandwidths {
        let cell = C0 / (2.0 * b) * 100.0;
        chart
            .vlines
            .push((cell, format!("c0/(2B) = {cell:.1} cm at {} GHz", b / 1e9)));
    }
    let cells: Vec<String> = rows
        .iter()
        .map(|(_, b)| *b)
        .fold(Vec::<f64>::new(), |mut v, b| {
            if !v.contains(&b) {
                v.push(b);
            }
            v
        })
        .iter()
        .map(|b| format!("{:.1} cm at {} GHz", C0 / (2.0 * b) * 100.0, b / 1e9))
        .collect();
    Some(Figure {
        id: "resolution",
        caption: format!(
            "Each step's targets resolved or not, per algorithm and bandwidth: resolved when each \
             target has its own detection within ±s/2 (s: the separation), against the ground \
             truth on a simulated bench. Dotted: the resolution cell c0/(2B): {}.",
            cells.join(", ")
        ),
        chart,
    })
}

/// The value plotted for a figure: the repetitions' mean ± std when there are several, else the
/// (only) measurement.
fn mean_std(
    a: &AlgorithmResult,
    value: Option<f64>,
    spread: impl Fn(&SpreadFigures) -> Option<MeanStd>,
) -> Option<Point> {
    match a.spread.as_ref().and_then(spread) {
        Some(m) => Some(Point::new(0.0, m.mean).with_std(Some(m.std))),
        None => value.map(|v| Point::new(0.0, v)),
    }
}

pub(super) fn single_target(manifest: &Manifest, steps: &[&StepResult]) -> Vec<Figure> {
    let mut cats = Vec::new();
    let mut width = Vec::new();
    let mut psl = Vec::new();
    for s in steps {
        for (name, a) in &s.algorithms {
            if a.width_3db_cm.is_none() && a.sidelobe_db.is_none() {
                continue;
            }
            let x = cats.len() as f64;
            cats.push(format!("step {} {name}", s.index));
            if let Some(mut p) = mean_std(a, a.width_3db_cm, |f| f.width_3db_cm) {
                p.x = x;
                width.push(p);
            }
            if let Some(mut p) = mean_std(a, a.sidelobe_db, |f| f.sidelobe_db) {
                p.x = x;
                psl.push(p);
            }
        }
    }
    if cats.is_empty() {
        return Vec::new();
    }
    // The thesis' values hold at 1 GHz for its two waveforms.
    let kind = waveform_of(manifest, steps[0]).map(|w| w.kind());
    let at_1ghz = steps.iter().all(|s| s.nominal.bandwidth_hz == 1e9);
    let thesis = kind.filter(|_| at_1ghz).and_then(thesis_widths);
    let waveform = kind.map_or("", |k| k.name());
    let mut out = Vec::new();
    for (id, title, unit, points, pick) in [
        (
            "single-width",
            "-3 dB main-lobe width",
            "-3 dB width (cm)",
            width,
            (|t: (f64, f64, &'static str)| t.0) as fn((f64, f64, &'static str)) -> f64,
        ),
        (
            "single-psl",
            "Peak side-lobe level",
            "peak side-lobe level (dB)",
            psl,
            |t: (f64, f64, &'static str)| t.1,
        ),
    ] {
        if points.is_empty() {
            continue;
        }
        let mut chart = Chart::new(format!("{title}, one target ({waveform})"), "", unit);
        chart.x_categories = Some(cats.clone());
        chart.series.push(Series {
            label: "radbench (mean ±1 std over the repetitions)".into(),
            points,
            style: Style::Markers,
        });
        if let Some(t) = &thesis {
            chart.hlines.push(HLine {
                y: pick(t.simulation),
                label: format!(
                    "thesis simulation ({}): {}",
                    t.simulation.2,
                    pick(t.simulation)
                ),
                dashed: true,
            });
            chart.hlines.push(HLine {
                y: pick(t.lab),
                label: format!("thesis lab ({}): {}", t.lab.2, pick(t.lab)),
                dashed: false,
            });
        }
        out.push(Figure {
            id,
            caption: format!(
                "{title} of the strongest target at each single-target step and algorithm: the \
                 mean of the repetitions processed one by one, ±1 standard deviation (one \
                 repetition: its value). {}",
                if thesis.is_some() {
                    "Beside it the thesis' simulation value (Table 4.5 for MSK-LFM, 4.7 for OFDM) \
                     and its lab value (4.4.1 / 4.5.1), both at 1 GHz."
                } else {
                    "The thesis' values (1 GHz) do not apply to this bandwidth and are not drawn."
                }
            ),
            chart,
        });
    }
    out
}

pub(crate) fn link_figures(manifest: &Manifest, steps: &[&StepResult]) -> Vec<Figure> {
    let snr = steps[0].nominal.parameter == Some(SweepParameter::Snr);
    let x_label = if snr {
        "scene SNR (dB)"
    } else {
        "Tx attenuation (dB)"
    };
    let names = algorithms(steps);
    let mut out: Vec<Figure> = ber_figure(manifest, steps, &names, snr, x_label)
        .into_iter()
        .collect();
    out.extend(evm_figure(steps, &names, snr, x_label));
    out.extend(link_radar_figures(steps, &names, x_label));
    out
}

/// The bit-error rate at each step, measured, with the theory beside when it can be fitted.
fn ber_figure(
    manifest: &Manifest,
    steps: &[&StepResult],
    names: &[String],
    snr: bool,
    x_label: &str,
) -> Option<Figure> {
    let mut ber = Chart::new("Bit-error rate", x_label, "bit-error rate");
    ber.log_y = true;
    let w = waveform_of(manifest, steps[0]);
    // (swept value, Eb/N0 the theory needs for the measured BER) of the steps with errors
    let mut implied = Vec::new();
    for name in names {
        let mut points = Vec::new();
        for s in steps {
            let (Some(x), Some(p)) = (
                s.nominal.value,
                s.algorithms.get(name).and_then(|a| a.payload.as_ref()),
            ) else {
                continue;
            };
            if p.bits == 0 {
                continue;
            }
            let (lo, hi) = wilson95(p.bit_errors, p.bits);
            if p.bit_errors == 0 {
                // Nothing to draw on a log scale: the hollow marker sits at the upper bound.
                points.push(Point {
                    x,
                    y: hi,
                    bar: None,
                    filled: false,
                });
            } else {
                points.push(Point {
                    x,
                    y: p.ber,
                    bar: Some((lo, hi)),
                    filled: true,
                });
                if let Some(e) = w.as_ref().and_then(|w| theory_ebn0_db(w, p.ber)) {
                    implied.push((x, e));
                }
            }
        }
        if !points.is_empty() {
            ber.series.push(Series {
                label: format!("{name} measured (95 % interval; hollow: no errors, upper bound)"),
                points,
                style: Style::Markers,
            });
        }
    }
    // The BER the measured MER implies for Gaussian noise on the data symbols: Q(sqrt(MER)) for
    // QPSK (OFDM) and for MSK's (I, Q) symbol pairs alike.
    for name in names {
        let points: Vec<Point> = steps
            .iter()
            .filter_map(|s| {
                let mer = s.algorithms.get(name)?.payload.as_ref()?.mer_db?;
                let ber = crate::waveform::ber::q_function(10f64.powf(mer / 20.0));
                let x = s.nominal.value?;
                (ber >= 1e-9).then(|| Point::new(x, ber))
            })
            .collect();
        if !points.is_empty() {
            ber.series.push(Series {
                label: format!("{name}: Q(sqrt(MER)), the BER the measured MER implies"),
                points,
                style: Style::Line,
            });
        }
    }
    let theory_note = match (w.as_ref(), implied.is_empty()) {
        (Some(w), false) => {
            let (series, note) = ber_theory(w, steps, &implied, snr);
            ber.series.push(series);
            note
        }
        _ => "No step had bit errors, so no offset between the swept parameter and Eb/N0 can \
              be fitted: the theory is not drawn."
            .to_string(),
    };
    (!ber.series.is_empty()).then(|| Figure {
        id: "link-ber",
        caption: format!(
            "Bit-error rate of the decoded payload at each step (every repetition's bits \
             counted), with its 95 % Wilson interval; a step without errors is a hollow marker \
             at the interval's upper bound. {theory_note}"
        ),
        chart: ber,
    })
}

/// The data symbols' EVM (rms and 95th percentile) at each step, with the line a link limited by
/// white noise follows (MER = +-x + K, K fitted to the measured MER).
fn evm_figure(steps: &[&StepResult], names: &[String], snr: bool, x_label: &str) -> Option<Figure> {
    let mut chart = Chart::new("Error-vector magnitude", x_label, "EVM (%)");
    chart.log_y = true;
    let sign = if snr { 1.0 } else { -1.0 };
    let mut offsets = Vec::new();
    for name in names {
        let mut rms = Vec::new();
        let mut p95 = Vec::new();
        for s in steps {
            let (Some(x), Some(p)) = (
                s.nominal.value,
                s.algorithms.get(name).and_then(|a| a.payload.as_ref()),
            ) else {
                continue;
            };
            if let Some(e) = p.evm_rms_pct.filter(|e| *e > 0.0) {
                rms.push(Point::new(x, e));
            }
            if let Some(e) = p.evm_p95_pct.filter(|e| *e > 0.0) {
                p95.push(Point::new(x, e));
            }
            if let Some(m) = p.mer_db {
                offsets.push(m - sign * x);
            }
        }
        for (label, points, style) in [
            ("EVM rms", rms, Style::Line),
            ("EVM 95th percentile", p95, Style::Markers),
        ] {
            if !points.is_empty() {
                chart.series.push(Series {
                    label: format!("{name} {label}"),
                    points,
                    style,
                });
            }
        }
    }
    if chart.series.is_empty() {
        return None;
    }
    let mut note = String::new();
    if !offsets.is_empty() {
        let k = offsets.iter().sum::<f64>() / offsets.len() as f64;
        let (x0, x1) = steps
            .iter()
            .filter_map(|s| s.nominal.value)
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), x| {
                (a.min(x), b.max(x))
            });
        let minus = if snr { "" } else { "-" };
        chart.series.push(Series {
            label: format!("white noise: MER = {minus}x + {k:.1} dB (fitted)"),
            points: (0..=40)
                .map(|i| {
                    let x = x0 + (x1 - x0) * i as f64 / 40.0;
                    Point::new(x, 100.0 * 10f64.powf(-(sign * x + k) / 20.0))
                })
                .collect(),
            style: Style::Dashed,
        });
        note = format!(
            " The dashed line is what a link limited by white noise gives: EVM = 10^(-MER/20),              MER moving 1 dB per dB of the swept parameter, K = {k:.2} dB fitted to the measured              MER; where the points leave it, something else than noise limits the link (the              DAC's and ADC's quantisation, clipping, the chain)."
        );
    }
    Some(Figure {
        id: "link-evm",
        caption: format!(
            "Error-vector magnitude of the decoded data symbols against those sent (data-aided),              rms and 95th percentile, of each step's coherent average. MER = -20 log10(EVM              rms).{note}"
        ),
        chart,
    })
}

/// The theory's BER curve with Eb/N0 = K - attenuation (or K + SNR), K fitted to the `implied`
/// points, and the caption's note on it.
fn ber_theory(
    w: &WaveformSpec,
    steps: &[&StepResult],
    implied: &[(f64, f64)],
    snr: bool,
) -> (Series, String) {
    let sign = if snr { 1.0 } else { -1.0 };
    let k = implied.iter().map(|(x, e)| e - sign * x).sum::<f64>() / implied.len() as f64;
    let (x0, x1) = steps
        .iter()
        .filter_map(|s| s.nominal.value)
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), x| {
            (a.min(x), b.max(x))
        });
    let points = (0..=60)
        .map(|i| {
            let x = x0 + (x1 - x0) * i as f64 / 60.0;
            Point::new(x, theory(w, sign * x + k))
        })
        .filter(|p| p.y >= 1e-9)
        .collect();
    let minus = if snr { "" } else { "-" };
    let swept = if snr { "SNR" } else { "attenuation" };
    let series = Series {
        label: format!(
            "{} theory, Eb/N0 = {minus}x + {k:.1} dB (fitted)",
            w.kind().name()
        ),
        points,
        style: Style::Dashed,
    };
    let note = format!(
        "The dashed curve is the {} theory ({}) with Eb/N0 = {minus}{swept} + K; K = {k:.2} dB \
         is fitted (mean over the {} step(s) with bit errors of the Eb/N0 the theory needs for \
         the measured BER), since the bench's absolute Eb/N0 is not measured. The curve tests \
         the shape (1 dB of Eb/N0 per dB of {swept}), not the absolute level.",
        w.kind().name(),
        crate::measure::processing::family::of(w).ber_theory_formula(),
        implied.len(),
    );
    (series, note)
}

/// Width, peak side-lobe level and range error of the strongest target against the swept
/// parameter, one series per algorithm.
fn link_radar_figures(steps: &[&StepResult], names: &[String], x_label: &str) -> Vec<Figure> {
    type Pick = fn(&AlgorithmResult) -> Option<Point>;
    let radar: [(&'static str, &str, &str, Pick); 3] = [
        (
            "link-width",
            "-3 dB main-lobe width",
            "-3 dB width (cm)",
            |a| mean_std(a, a.width_3db_cm, |f| f.width_3db_cm),
        ),
        ("link-psl", "Peak side-lobe level", "PSL (dB)", |a| {
            mean_std(a, a.sidelobe_db, |f| f.sidelobe_db)
        }),
        (
            "link-error",
            "Range error (interpolated)",
            "measured - nominal (mm)",
            |a| {
                let std = strongest_range_std(a).map(|s| s * 1e3);
                a.error_m.map(|e| Point::new(0.0, e * 1e3).with_std(std))
            },
        ),
    ];
    let mut out = Vec::new();
    for (id, title, unit, pick) in radar {
        let mut chart = Chart::new(title, x_label, unit);
        for name in names {
            let points: Vec<Point> = steps
                .iter()
                .filter_map(|s| {
                    let mut p = pick(s.algorithms.get(name)?)?;
                    p.x = s.nominal.value?;
                    Some(p)
                })
                .collect();
            if !points.is_empty() {
                chart.series.push(Series {
                    label: format!("{name} (mean ±1 std over the repetitions)"),
                    points,
                    style: Style::Line,
                });
            }
        }
        if chart.series.is_empty() {
            continue;
        }
        out.push(Figure {
            id,
            caption: format!(
                "{title} of the strongest target against the {}: the mean of the repetitions \
                 processed one by one, ±1 standard deviation (one repetition: its value; the \
                 range error is the coherent average's, its bar the repetitions' range spread).",
                x_label.split(" (").next().unwrap_or(x_label)
            ),
            chart,
        });
    }
    out
}
