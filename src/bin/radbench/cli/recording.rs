//! `radbench recording FILE... [--json]`: what a SigMF recording holds: datatype, rate, samples,
//! statistics of I and Q, and radbench's metadata when present.

use std::path::PathBuf;

use num_complex::Complex64;
use serde_json::{json, Value};

use super::trc::{report_files, si};
use radbench::storage::{read_sigmf, Recording, SampleUnit};

#[derive(Debug, clap::Args)]
pub struct Args {
    /// Recordings: the .sigmf-meta, the .sigmf-data, or their common base name.
    #[arg(value_name = "FILE", required = true)]
    pub files: Vec<PathBuf>,
    /// Print one JSON object {"recordings": [...], "errors": [...]} instead of text.
    #[arg(long)]
    pub json: bool,
    /// How many samples to show from the start.
    #[arg(long, default_value_t = 4, value_name = "N")]
    pub first: usize,
}

/// Mean, RMS, min and max of I and Q, and the RMS magnitude.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub(crate) struct IqStats {
    pub mean_i: f64,
    pub mean_q: f64,
    pub rms_i: f64,
    pub rms_q: f64,
    pub rms: f64,
    pub min_i: f64,
    pub max_i: f64,
    pub min_q: f64,
    pub max_q: f64,
}

impl IqStats {
    pub(crate) fn of(samples: &[Complex64]) -> Option<IqStats> {
        if samples.is_empty() {
            return None;
        }
        let n = samples.len() as f64;
        let mut s = IqStats {
            mean_i: 0.0,
            mean_q: 0.0,
            rms_i: 0.0,
            rms_q: 0.0,
            rms: 0.0,
            min_i: f64::INFINITY,
            max_i: f64::NEG_INFINITY,
            min_q: f64::INFINITY,
            max_q: f64::NEG_INFINITY,
        };
        for z in samples {
            s.mean_i += z.re;
            s.mean_q += z.im;
            s.rms_i += z.re * z.re;
            s.rms_q += z.im * z.im;
            s.min_i = s.min_i.min(z.re);
            s.max_i = s.max_i.max(z.re);
            s.min_q = s.min_q.min(z.im);
            s.max_q = s.max_q.max(z.im);
        }
        s.rms = ((s.rms_i + s.rms_q) / n).sqrt();
        s.mean_i /= n;
        s.mean_q /= n;
        s.rms_i = (s.rms_i / n).sqrt();
        s.rms_q = (s.rms_q / n).sqrt();
        Some(s)
    }
}

fn unit_name(u: SampleUnit) -> &'static str {
    match u {
        SampleUnit::Volts => "volts",
        SampleUnit::Native => "native",
    }
}

/// The JSON of one recording (one entry of `recordings`).
pub(crate) fn recording_json(r: &Recording, first: usize) -> Value {
    let n = r.samples.len();
    let head: Vec<[f64; 2]> = r.samples[..first.min(n)]
        .iter()
        .map(|z| [z.re, z.im])
        .collect();
    json!({
        "meta": r.meta_path.display().to_string(),
        "data": r.data_path.display().to_string(),
        "datatype": r.datatype.to_string(),
        "sample_rate_hz": r.sample_rate_hz,
        "samples": n,
        "duration_s": r.sample_rate_hz.map(|f| n as f64 / f),
        "datetime": r.datetime(),
        "frequency_hz": r.frequency_hz(),
        "version": r.version,
        "description": r.description,
        "hw": r.hw,
        "recorder": r.recorder,
        "extensions": r.extensions,
        "captures": r.captures,
        "sha512_checked": r.sha512_checked,
        "unit": unit_name(r.unit),
        "radbench": r.radbench.as_ref().map(|m| &m.keys),
        "first_samples": head,
        "stats": IqStats::of(&r.samples),
    })
}

fn print_text(r: &Recording, first: usize) {
    let unit = match r.unit {
        SampleUnit::Volts => "V",
        SampleUnit::Native => "",
    };
    let n = r.samples.len();
    println!("{}", r.meta_path.display());
    println!("  data file    {}", r.data_path.display());
    println!(
        "  datatype     {}{}",
        r.datatype,
        match r.unit {
            SampleUnit::Volts => ", in volts (radbench:vertical_gain/offset)",
            SampleUnit::Native => ", in the datatype's own scale (no radbench scaling)",
        }
    );
    match r.sample_rate_hz {
        Some(f) => println!(
            "  samples      {n} at {} ({})",
            si(f, "Sa/s"),
            si(n as f64 / f, "s")
        ),
        None => println!("  samples      {n} (no core:sample_rate)"),
    }
    if let Some(t) = r.datetime() {
        println!("  datetime     {t}");
    }
    if let Some(f) = r.frequency_hz() {
        println!("  frequency    {}", si(f, "Hz"));
    }
    if let Some(text) = &r.recorder {
        println!("  recorder     {text}");
    }
    if !r.extensions.is_empty() {
        let names: Vec<String> = r
            .extensions
            .iter()
            .map(|e| format!("{} {}", e.name, e.version))
            .collect();
        println!("  extensions   {}", names.join(", "));
    }
    println!(
        "  sha512       {}",
        if r.sha512_checked {
            "matches"
        } else {
            "not given"
        }
    );
    if let Some(m) = &r.radbench {
        let keys: Vec<&str> = m.keys.keys().map(String::as_str).collect();
        println!("  radbench:    {}", keys.join(", "));
        if let Some(t) = m.trigger_offset_s {
            println!("  first sample {} after the marker edge", si(t, "s"));
        }
        if let Some(kind) = m.waveform().and_then(|w| w["kind"].as_str()) {
            println!("  waveform     {kind}");
        }
    }
    if let Some(s) = IqStats::of(&r.samples) {
        let v = |x: f64| format!("{x:.6e}{}{unit}", if unit.is_empty() { "" } else { " " });
        println!(
            "  I            mean {}  RMS {}  min {}  max {}",
            v(s.mean_i),
            v(s.rms_i),
            v(s.min_i),
            v(s.max_i)
        );
        println!(
            "  Q            mean {}  RMS {}  min {}  max {}",
            v(s.mean_q),
            v(s.rms_q),
            v(s.min_q),
            v(s.max_q)
        );
        println!("  RMS |I+jQ|   {}", v(s.rms));
    }
    let head: Vec<String> = r.samples[..first.min(n)]
        .iter()
        .map(|z| format!("{:.6e}{:+.6e}j", z.re, z.im))
        .collect();
    if !head.is_empty() {
        println!("  first        {}", head.join("  "));
    }
}

pub(crate) fn run(args: Args, _global: &super::global::Global) -> anyhow::Result<()> {
    report_files(
        &args.files,
        args.json,
        "recordings",
        read_sigmf,
        |_, r| recording_json(r, args.first),
        |_, r| print_text(r, args.first),
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn iq_stats() {
        let s = IqStats::of(&[Complex64::new(1.0, -2.0), Complex64::new(3.0, 2.0)]).unwrap();
        assert_eq!((s.mean_i, s.mean_q), (2.0, 0.0));
        assert_eq!((s.min_i, s.max_i, s.min_q, s.max_q), (1.0, 3.0, -2.0, 2.0));
        assert!((s.rms_i - 5f64.sqrt()).abs() < 1e-12);
        assert!((s.rms - 9f64.sqrt()).abs() < 1e-12);
        assert!(IqStats::of(&[]).is_none());
    }
}
