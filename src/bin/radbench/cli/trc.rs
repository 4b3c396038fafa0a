//! `radbench trc FILE... [--json]`: the header and a summary of LeCroy `.trc` files, per segment
//! for sequence-mode records.

use std::path::{Path, PathBuf};

use serde_json::{json, Value};

use radbench::storage::{read_trc, RecordingError};
use radbench::trc::{Segment, Trace};

#[derive(Debug, clap::Args)]
pub struct Args {
    /// .trc files (as saved by the scope, by radbench, or a saved `WF? ALL` reply).
    #[arg(value_name = "FILE", required = true)]
    pub files: Vec<PathBuf>,
    /// Print one JSON object {"traces": [...], "errors": [...]} instead of text.
    #[arg(long)]
    pub json: bool,
    /// With --json: the first and last N volts and times of each segment.
    #[arg(long, default_value_t = 8, value_name = "N")]
    pub points: usize,
    /// Text: list at most this many segments of a sequence.
    #[arg(long, default_value_t = 20, value_name = "N")]
    pub max_segments: usize,
}

/// Min, max, mean and RMS of some volts.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub(crate) struct Stats {
    pub min_v: f64,
    pub max_v: f64,
    pub mean_v: f64,
    pub rms_v: f64,
}

impl Stats {
    /// Statistics of `volts`; None when there are none.
    pub(crate) fn of(volts: impl Iterator<Item = f64>) -> Option<Stats> {
        let (mut n, mut sum, mut sq) = (0usize, 0.0, 0.0);
        let (mut min, mut max) = (f64::INFINITY, f64::NEG_INFINITY);
        for v in volts {
            n += 1;
            sum += v;
            sq += v * v;
            min = min.min(v);
            max = max.max(v);
        }
        (n > 0).then(|| Stats {
            min_v: min,
            max_v: max,
            mean_v: sum / n as f64,
            rms_v: (sq / n as f64).sqrt(),
        })
    }
}

/// Statistics of every point of the trace (all segments), without a copy in volts.
fn trace_stats(t: &Trace) -> Option<Stats> {
    let gain = f64::from(t.desc.vertical_gain);
    let offset = f64::from(t.desc.vertical_offset);
    Stats::of(t.codes.iter().map(|c| gain * f64::from(*c) - offset))
}

fn segment_stats(s: &Segment<'_>) -> Option<Stats> {
    Stats::of(s.codes.iter().map(|c| s.volt(*c)))
}

/// `value` with an SI prefix, e.g. `si(1.25e-9, "s")` = `1.25 ns`.
pub(crate) fn si(value: f64, unit: &str) -> String {
    if value == 0.0 || !value.is_finite() {
        return format!("{value} {unit}");
    }
    const PREFIXES: [(f64, &str); 9] = [
        (1e12, "T"),
        (1e9, "G"),
        (1e6, "M"),
        (1e3, "k"),
        (1.0, ""),
        (1e-3, "m"),
        (1e-6, "u"),
        (1e-9, "n"),
        (1e-12, "p"),
    ];
    let Some((scale, prefix)) = PREFIXES
        .iter()
        .find(|(s, _)| value.abs() >= *s * 0.9995)
        .copied()
    else {
        return format!("{value:.4e} {unit}");
    };
    let number = format!("{:.4}", value / scale);
    let number = number.trim_end_matches('0').trim_end_matches('.');
    format!("{number} {prefix}{unit}")
}

fn ends<T: Copy>(all: &[T], n: usize) -> (Vec<T>, Vec<T>) {
    let n = n.min(all.len());
    (all[..n].to_vec(), all[all.len() - n..].to_vec())
}

/// The JSON of one trace (the `--json` schema, one entry of `traces`).
pub(crate) fn trace_json(path: &Path, t: &Trace, points: usize) -> Value {
    let d = &t.desc;
    let per_segment = t.codes.len() / t.segment_count().max(1);
    let interval = t.sample_interval_s();
    let segments: Vec<Value> = t
        .segments()
        .map(|s| {
            let (first, last) = ends(s.codes, points);
            let volts =
                |codes: Vec<i16>| -> Vec<f64> { codes.iter().map(|c| s.volt(*c)).collect() };
            let (first_volts, last_volts) = (volts(first), volts(last));
            let n = s.codes.len();
            let k = points.min(n);
            let first_times: Vec<f64> = (0..k).map(|i| s.time(i)).collect();
            let last_times: Vec<f64> = (n - k..n).map(|i| s.time(i)).collect();
            json!({
                "index": s.index,
                "trigger_time_s": s.trigger_time_s,
                "trigger_offset_s": s.trigger_offset_s,
                "stats": segment_stats(&s),
                "first_volts": first_volts,
                "last_volts": last_volts,
                "first_times_s": first_times,
                "last_times_s": last_times,
            })
        })
        .collect();
    json!({
        "file": path.display().to_string(),
        "channel": (t.channel > 0).then_some(t.channel),
        "header": d,
        "trigger_time": d.trigger_time.iso(),
        "record_type": d.record_type_name(),
        "coupling": d.coupling_name(),
        "user_text": t.user_text,
        "ris_offsets_s": t.ris_offsets,
        "points": t.codes.len(),
        "segment_count": t.segment_count(),
        "points_per_segment": per_segment,
        "sample_interval_s": interval,
        "sample_rate_hz": 1.0 / interval,
        "segment_duration_s": per_segment as f64 * interval,
        "stats": trace_stats(t),
        "segments": segments,
    })
}

fn print_text(path: &Path, t: &Trace, max_segments: usize) {
    let d = &t.desc;
    let per_segment = t.codes.len() / t.segment_count().max(1);
    let interval = t.sample_interval_s();
    let unit = if d.vertunit.is_empty() {
        "V"
    } else {
        &d.vertunit
    };
    println!("{}", path.display());
    let source = d.source_channel().map_or_else(
        || format!("unknown ({})", d.wave_source),
        |c| format!("C{c}"),
    );
    println!(
        "  instrument       {} #{}, source {source}{}",
        d.instrument_name,
        d.instrument_number,
        if d.trace_label.is_empty() {
            String::new()
        } else {
            format!(", label {:?}", d.trace_label)
        }
    );
    println!(
        "  format           {}, COMM_TYPE {} ({}), COMM_ORDER {}, nominal bits {}",
        d.template_name,
        d.comm_type,
        if d.comm_type == 1 {
            "16-bit words"
        } else {
            "8-bit bytes"
        },
        d.order.name(),
        d.nominal_bits
    );
    if t.is_sequence() {
        println!(
            "  points           {} in {} segments of {per_segment} (sequence)",
            t.codes.len(),
            t.segment_count()
        );
    } else {
        println!("  points           {}", t.codes.len());
    }
    println!(
        "  sample interval  {} ({}), horizontal offset {}",
        si(interval, &d.horunit.to_lowercase()),
        si(1.0 / interval, "Sa/s"),
        si(d.horiz_offset, "s")
    );
    println!(
        "  vertical         gain {:e} {unit}/code, offset {} (volts = gain x code - offset), coupling {}",
        d.vertical_gain,
        si(f64::from(d.vertical_offset), unit),
        d.coupling_name()
    );
    println!(
        "  trigger time     {} (scope clock), record type {}",
        d.trigger_time.iso(),
        d.record_type_name()
    );
    if !t.user_text.is_empty() {
        println!("  user text        {:?}", t.user_text);
    }
    if !t.ris_offsets.is_empty() {
        println!("  RIS sweeps       {}", t.ris_offsets.len());
    }
    match trace_stats(t) {
        Some(s) => println!(
            "  volts            min {}  max {}  mean {}  RMS {}",
            si(s.min_v, unit),
            si(s.max_v, unit),
            si(s.mean_v, unit),
            si(s.rms_v, unit)
        ),
        None => println!("  volts            (no points)"),
    }
    println!(
        "  duration         {}{}",
        si(per_segment as f64 * interval, "s"),
        if t.is_sequence() { " per segment" } else { "" }
    );
    if t.is_sequence() {
        println!(
            "  {:>7}  {:<14}  {:<14}  {:<12}  {:<12}  {:<12}  RMS",
            "segment", "trigger time", "trigger offset", "min", "max", "mean"
        );
        for s in t.segments().take(max_segments) {
            let st = segment_stats(&s);
            let col = |f: fn(&Stats) -> f64| st.as_ref().map_or("-".into(), |x| si(f(x), unit));
            println!(
                "  {:>7}  {:<14}  {:<14}  {:<12}  {:<12}  {:<12}  {}",
                s.index,
                s.trigger_time_s.map_or("-".into(), |x| si(x, "s")),
                si(s.trigger_offset_s, "s"),
                col(|x| x.min_v),
                col(|x| x.max_v),
                col(|x| x.mean_v),
                col(|x| x.rms_v)
            );
        }
        if t.segment_count() > max_segments {
            println!(
                "  ... {} more segments (--max-segments {} lists them all)",
                t.segment_count() - max_segments,
                t.segment_count()
            );
        }
    }
}

pub(crate) fn run(args: Args, _global: &super::global::Global) -> anyhow::Result<()> {
    report_files(
        &args.files,
        args.json,
        "traces",
        read_trc,
        |path, t| trace_json(path, t, args.points),
        |path, t| print_text(path, t, args.max_segments),
    )
}

/// Reads each file, prints it (text, or one JSON object `{KEY: [...], "errors": [...]}`), goes
/// on after a file that cannot be read, and ends with [`finish`]. Shared by `trc` and
/// `recording`.
pub(crate) fn report_files<T>(
    files: &[PathBuf],
    json: bool,
    key: &str,
    read: impl Fn(&Path) -> Result<T, RecordingError>,
    to_json: impl Fn(&Path, &T) -> Value,
    print: impl Fn(&Path, &T),
) -> anyhow::Result<()> {
    let mut out = Vec::new();
    let mut errors = Vec::new();
    for (k, path) in files.iter().enumerate() {
        match read(path) {
            Ok(r) if json => out.push(to_json(path, &r)),
            Ok(r) => {
                if k > 0 {
                    println!();
                }
                print(path, &r);
            }
            Err(e) => {
                if !json && files.len() > 1 {
                    eprintln!("error: {e}");
                }
                errors.push(e);
            }
        }
    }
    if json {
        let listed: Vec<Value> = errors
            .iter()
            .map(|e| json!({"file": e.path().display().to_string(), "error": e.to_string()}))
            .collect();
        println!(
            "{}",
            serde_json::to_string_pretty(&json!({key: out, "errors": listed}))?
        );
    }
    finish(errors, files.len())
}

/// Ok when every file was read; the one error, or a count naming the files, otherwise.
pub(crate) fn finish(mut errors: Vec<RecordingError>, files: usize) -> anyhow::Result<()> {
    match errors.len() {
        0 => Ok(()),
        1 if files == 1 => Err(errors.remove(0).into()),
        n => Err(radbench::exit::bad_input(format!(
            "{n} of {files} files could not be read: {}",
            errors
                .iter()
                .map(ToString::to_string)
                .collect::<Vec<_>>()
                .join("; ")
        ))),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn si_prefixes() {
        assert_eq!(si(1e-9, "s"), "1 ns");
        assert_eq!(si(-3.6457e-7, "s"), "-364.57 ns");
        assert_eq!(si(2.5e-3, "s"), "2.5 ms");
        assert_eq!(si(1e9, "Sa/s"), "1 GSa/s");
        assert_eq!(si(0.0, "V"), "0 V");
        assert_eq!(si(0.25, "V"), "250 mV");
        assert_eq!(si(8.47e-22, "s"), "8.4700e-22 s");
    }

    #[test]
    fn stats_of_volts() {
        let s = Stats::of([1.0, -1.0, 3.0, 1.0].into_iter()).unwrap();
        assert_eq!((s.min_v, s.max_v, s.mean_v), (-1.0, 3.0, 1.0));
        assert!((s.rms_v - 3f64.sqrt()).abs() < 1e-12);
        assert!(Stats::of(std::iter::empty()).is_none());
    }
}
