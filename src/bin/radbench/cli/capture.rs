//! `radbench capture`: one complete measurement, on the bench of a bench file or on the built-in
//! mock lab. Parses, calls `measure`, prints.

use super::args::{PayloadArgs, WaveformArgs};
use radbench::driver::RfPermit;
use radbench::exit::bad_input;
use radbench::measure;
use radbench::measure::Calibration;
use radbench::measure::Interrupt;
use radbench::measure::MeasureError;
use radbench::measure::Provenance;
use radbench::measure::{AwgLink, ScopeLink};
use radbench::measure::{Bench, BenchSource, BuiltIn};
use radbench::measure::{CaptureRequest, Measurement};
use radbench::measure::{NotRecorded, Recorded, Recorder};
use radbench::waveform::WaveformKind;
use std::path::{Path, PathBuf};

#[derive(Debug, clap::Args)]
pub struct Args {
    /// Bench file (TOML) naming the instruments; without one, a simulated bench (mock_lab) is
    /// started in-process on 127.0.0.1.
    #[arg(long, value_name = "FILE", help_heading = "Bench")]
    pub bench: Option<PathBuf>,
    #[arg(long, value_parser = super::args::listed::<WaveformKind>(), default_value = "msk-lfm", help_heading = "Waveform")]
    pub waveform: WaveformKind,
    #[command(flatten, next_help_heading = "Waveform")]
    pub waveform_args: WaveformArgs,
    #[command(flatten, next_help_heading = "Processing")]
    pub processing: radbench::measure::ProcessingChoices,
    /// Subtract this earlier capture (its .sigmf-meta) before processing, e.g. an empty scene.
    #[arg(long, value_name = "FILE", help_heading = "Processing")]
    pub background: Option<PathBuf>,
    /// Output folder (default runs/<UTC time>-<waveform>).
    #[arg(long, value_name = "DIR", help_heading = "Output")]
    pub out: Option<PathBuf>,
    /// Explicit permit to switch on the AWG outputs and the Tx/Rx front ends for this capture.
    #[arg(long, help_heading = "Bench")]
    pub allow_rf: bool,
    /// Write into an --out folder that holds files already (they are replaced; the command says
    /// which).
    #[arg(long, help_heading = "Output")]
    pub force: bool,
    /// Leave the transmitter off (noise-floor and leakage checks); needs --allow-rf for the rest.
    #[arg(long, help_heading = "Bench")]
    pub tx_off: bool,
    /// Print one JSON object instead of the text report.
    #[arg(long, help_heading = "Output")]
    pub json: bool,
    /// The payload text or the PRBS seed (the library's: the Python package parses them too).
    #[command(flatten, next_help_heading = "Waveform")]
    pub bits: PayloadArgs,
    /// Marker-triggered repetitions per measurement: each processed, and their coherent average
    /// reported with the spread (mean and standard deviation) of the repetitions.
    #[arg(
        long,
        value_name = "N",
        default_value_t = 1,
        help_heading = "Processing"
    )]
    pub repetitions: usize,
    /// Longest wait for the marker-triggered acquisition, seconds.
    #[arg(
        long,
        default_value_t = 10.0,
        allow_hyphen_values = true,
        help_heading = "Bench"
    )]
    pub wait: f64,
    #[command(flatten, next_help_heading = "Bench")]
    pub timeout: super::args::TimeoutArgs,
    /// Built-in mock lab only: its scene file (see examples/scene.toml).
    #[arg(long, value_name = "FILE", help_heading = "Built-in lab")]
    pub scene: Option<PathBuf>,
    /// Built-in mock lab only: transport to the AWG.
    #[arg(long, value_parser = super::args::listed::<AwgLink>(), default_value = "hislip", help_heading = "Built-in lab")]
    pub awg_transport: AwgLink,
    /// Built-in mock lab only: transport to the scope.
    #[arg(long, value_parser = super::args::listed::<ScopeLink>(), default_value = "vicp", help_heading = "Built-in lab")]
    pub scope_transport: ScopeLink,
    #[command(flatten, next_help_heading = "Built-in lab")]
    pub scope_model: super::scope_model::ScopeModelArgs,
    /// Capture N times, or `forever` (until Ctrl-C or the live page's Stop): each capture's
    /// files in a folder of its own in --out (capture-0001, ...); the bench is connected and the
    /// waveform uploaded once, RF is on only while capturing.
    #[arg(long, value_name = "N|forever", value_parser = parse_repeat, help_heading = "Output")]
    pub repeat: Option<Repeat>,
    #[command(flatten, next_help_heading = "Live")]
    pub live: super::live::LiveArgs,
}

/// `--repeat`: how many captures (`None`: until stopped).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Repeat(pub Option<u64>);

/// `--repeat N|forever`.
pub(crate) fn parse_repeat(s: &str) -> Result<Repeat, String> {
    if s == "forever" {
        return Ok(Repeat(None));
    }
    match s.parse::<u64>() {
        Ok(n) if n >= 1 => Ok(Repeat(Some(n))),
        _ => Err(format!(
            "`{s}`: allowed: a whole number of captures, 1 or more, or `forever`"
        )),
    }
}

// Shared with the Python package's warm session (one definition of each).
pub(crate) use radbench::in_memory::{calibration_warnings, prepare_out, resolve_correction};

/// A range with its standard uncertainty, to the uncertainty's first digit: `1.000037 m ± 0.8 µm`
/// (`1.0002 m` at least four places; the range alone at four places without one).
pub(crate) fn range_text(range_m: f64, std_m: Option<f64>) -> String {
    let Some(std) = std_m.filter(|s| s.is_finite() && *s > 0.0) else {
        return format!("{range_m:.4} m");
    };
    let places = (-std.log10()).floor().clamp(4.0, 9.0) as usize;
    let u = if std < 10e-6 {
        format!("{:.1} µm", std * 1e6)
    } else if std < 1e-3 {
        format!("{:.0} µm", std * 1e6)
    } else {
        format!("{:.2} mm", std * 1e3)
    };
    format!("{range_m:.places$} m ± {u}")
}

/// The bench of `--bench`, or the built-in lab with `--scene` and the transports.
pub(crate) fn bench_source(
    bench: Option<&Path>,
    scene: Option<&Path>,
    awg: AwgLink,
    scope: ScopeLink,
) -> anyhow::Result<BenchSource> {
    if let Some(path) = bench {
        if scene.is_some() {
            return Err(bad_input(
                "--scene applies to the built-in mock lab only: with --bench, change the scene \
                 through the lab's control channel",
            ));
        }
        return Ok(BenchSource::File(path.to_path_buf()));
    }
    let scene = match scene {
        Some(p) => super::mock_lab::load_scene(p)?,
        None => mock_lab::scene::Scene::default(),
    };
    Ok(BenchSource::BuiltIn(Box::new(BuiltIn {
        scene,
        awg,
        scope,
        scope_model: Default::default(),
    })))
}

/// Opens the bench and says which one it is (on stderr, unless `quiet`).
pub(crate) async fn open_bench(source: BenchSource, quiet: bool) -> anyhow::Result<Bench> {
    let built_in = matches!(source, BenchSource::BuiltIn(_));
    let bench = Bench::open(source).await?;
    if !quiet && built_in {
        eprintln!("no --bench file: using {}", bench.describe());
    }
    Ok(bench)
}

/// The I/O journal of `--trace-io`.
pub(crate) fn journal(
    global: &super::global::Global,
) -> anyhow::Result<Option<radbench::transport::Journal>> {
    Ok(match &global.trace_io {
        Some(p) => Some(radbench::transport::Journal::create(p, false)?),
        None => None,
    })
}

/// The default output folder: `runs/<UTC time>-<name>`.
/// The `range_m` of each target in a summary's (or a ground truth's) `targets` list, as text.
pub(super) fn target_ranges(targets: &serde_json::Value) -> Vec<String> {
    targets
        .as_array()
        .map(|t| {
            t.iter()
                .filter_map(|x| Some((x["range_m"].as_f64()?, x["range_std_m"].as_f64())))
                .map(|(r, s)| range_text(r, s))
                .collect()
        })
        .unwrap_or_default()
}

pub(crate) fn default_out(name: &str) -> PathBuf {
    let stamp = radbench::storage::utc_now_rfc3339()
        .replace([':', '-'], "")
        .replace('.', "_");
    PathBuf::from("runs").join(format!("{stamp}-{name}"))
}

/// One capture (no `--repeat`): taken, the raw files written beside its processing, the
/// processed files written, the report printed.
#[allow(clippy::too_many_arguments)]
pub(super) async fn once(
    args: &Args,
    global: &super::global::Global,
    bench: &Bench,
    request: &CaptureRequest,
    generation: Option<measure::Generation>,
    permit: &RfPermit,
    interrupt: &Interrupt,
    out: &Path,
    calibration: Option<&Calibration>,
) -> anyhow::Result<()> {
    let (taken, mut prepared) = measure::take(
        bench,
        request,
        generation,
        args.repetitions,
        permit,
        journal(global)?,
        interrupt,
    )
    .await?;
    let provenance = Provenance {
        bench_file: bench.path.clone(),
        simulated: bench.is_simulated(),
    };
    let Recorded {
        measurement: m,
        summary,
    } = Recorder::new(out, &provenance)
        .record(taken, &mut prepared, |m| {
            if let Some(cal) = calibration {
                let warnings = calibration_warnings(cal, &m.taken.identities);
                m.processing.processed.warnings.extend(warnings);
            }
        })
        .await
        .map_err(|e| not_recorded(e, out))?;
    if let Some(signal) = interrupt.received() {
        eprintln!(
            "{} received after the capture: the bench is safe and the files are written to {}",
            signal.name(),
            out.display()
        );
        return Err(MeasureError::Interrupted {
            signal,
            report: m.taken.safe_state.to_string(),
        }
        .into());
    }
    if args.json {
        super::terminal::out(&summary.to_string())
    } else {
        super::terminal::out(&report(&m, out))
    }
}

/// Why a capture's files were not all written, as the command's error: when its processing
/// failed, where its raw capture is kept and how to process it again.
pub(crate) fn not_recorded(e: NotRecorded, out: &Path) -> anyhow::Error {
    let error = anyhow::Error::from(e.error);
    if !e.raw_kept {
        return error;
    }
    error.context(format!(
        "the raw capture is kept in {}: `radbench process {}` processes it again",
        out.display(),
        out.display()
    ))
}

/// The text report of a measurement.
pub(crate) fn report(m: &Measurement, out: &Path) -> String {
    use std::fmt::Write as _;
    let mut text = String::new();
    // Writing to a String cannot fail.
    macro_rules! println {
        ($($arg:tt)*) => { writeln!(text, $($arg)*).unwrap_or(()) };
    }
    let p = &m.processing.processed;
    let o = &m.processing.options;
    println!(
        "{} capture, {} processing, {} samples per repetition at {} GSa/s",
        m.taken.tx.name(),
        o.algorithm.name(),
        m.period(),
        m.taken.tx.sample_rate_hz() / 1e9
    );
    if let Some(c) = &o.correction {
        println!("correction {} with {}", c.mode, c.calibration);
    }
    if let Some(p) = &m.taken.tx.predistortion {
        println!(
            "pre-distorted: {:+.2} dB more back-off, SQNR {:.1} -> {:.1} dB, largest boost {:.1} dB; \
             tx I/Q {:+.2} dB, {:+.2} deg, {:+.2} ps undone",
            p.extra_backoff_db,
            p.sqnr_db_before,
            p.sqnr_db_after,
            p.peak_boost_db,
            p.tx_iq_gain_db,
            p.tx_iq_phase_deg,
            p.tx_iq_skew_ps
        );
    }
    if p.targets.is_empty() {
        println!("targets: none");
    } else {
        println!("targets:");
        for (k, t) in p.targets.iter().enumerate() {
            let spread = m
                .processing
                .spread
                .as_ref()
                .and_then(|s| s.targets.get(k))
                .and_then(|s| s.range)
                .map(|r| {
                    format!(
                        "   +- {:.2} mm over {} of {} repetitions",
                        r.std * 1e3,
                        r.n,
                        m.taken.captured.repetitions()
                    )
                })
                .unwrap_or_default();
            let moving = t
                .velocity_mps
                .map(|v| format!("   {} m/s", radbench::measure::signed(v, 1)))
                .unwrap_or_default();
            println!(
                "  {:>9}   {:>6.1} dB{moving}{spread}",
                range_text(t.range_m, t.range_std_m),
                t.level_db
            );
        }
    }
    let opt = |v: Option<f64>, unit: &str| v.map_or("-".to_string(), |x| format!("{x:.2} {unit}"));
    let pm = |s: Option<radbench::measure::Stat>, unit: &str| {
        s.map(|s| format!(" (repetitions: {:.2} +- {:.2} {unit})", s.mean, s.std))
            .unwrap_or_default()
    };
    let spread = m.processing.spread.as_ref();
    println!(
        "-3 dB width: {}{}",
        opt(p.width_3db_cm, "cm"),
        pm(spread.and_then(|s| s.width_3db_cm), "cm")
    );
    println!(
        "peak side-lobe: {}{}",
        opt(p.sidelobe_db, "dB"),
        pm(spread.and_then(|s| s.sidelobe_db), "dB")
    );
    println!(
        "SNR (the strongest target over the noise beside the band): {}; over the detector's \
         residual floor: {}",
        opt(p.snr_db, "dB"),
        opt(p.peak_to_floor_db, "dB")
    );
    let losses = &p.losses_db;
    if losses.window > 0.0 || losses.correction.is_some() {
        println!(
            "SNR lost to the window: {:.2} dB; to the correction: {}",
            losses.window,
            opt(losses.correction, "dB")
        );
    }
    if let Some(pl) = &p.payload {
        match (&pl.text, &pl.error) {
            (Some(t), _) => println!(
                "payload: {t:?} ({} bit errors in {})",
                pl.bit_errors, pl.bits
            ),
            (None, Some(e)) => println!("payload: not decoded: {e}"),
            (None, None) => println!(
                "data bits: {} errors in {} (BER {})",
                pl.bit_errors,
                pl.bits,
                radbench::measure::rate(pl.ber)
            ),
        }
    }
    if let Some(truth) = &m.taken.ground_truth {
        let ranges = target_ranges(&truth["targets"]);
        println!("simulated scene (ground truth): {}", ranges.join(", "));
    }
    for w in &p.warnings {
        println!("warning: {w}");
    }
    println!("files: {}", out.display());
    text.trim_end().to_string()
}

#[cfg(test)]
mod tests {
    use super::range_text;

    #[test]
    fn a_range_is_printed_to_its_uncertainty() {
        assert_eq!(range_text(1.000_037_2, Some(0.8e-6)), "1.000037 m ± 0.8 µm");
        assert_eq!(range_text(1.000_237, Some(150e-6)), "1.0002 m ± 150 µm");
        assert_eq!(range_text(2.5, Some(2e-3)), "2.5000 m ± 2.00 mm");
        assert_eq!(range_text(2.5, None), "2.5000 m");
    }
}
