//! What `radbench capture` decides before it measures, shared by the command and the warm
//! session ([`super::BenchSession`]): the options of one capture given as keywords (parsed by
//! the command's clap definitions and [`crate::measure::ProcessingChoices`]), the correction it
//! uses, the warnings about that correction, and the output folder's checks.

use super::keywords;
use super::options::{PayloadArgs, WaveformArgs};
use crate::exit::bad_input;
use crate::measure::{Bench, Calibration, CorrectionMode, Identities, ProcessingChoices};
use crate::waveform::WaveformKind;
use clap::Parser;
use std::path::{Path, PathBuf};
use std::sync::Arc;

/// The options of `radbench capture` that are neither processing choices nor the session's
/// (`waveform`, `repetitions`, `out` are arguments of their own).
#[derive(clap::Parser)]
#[command(disable_help_flag = true, disable_version_flag = true)]
struct CaptureParser {
    #[command(flatten)]
    waveform_args: WaveformArgs,
    #[command(flatten)]
    bits: PayloadArgs,
    /// Leave the transmitter off (noise-floor and leakage checks).
    #[arg(long)]
    tx_off: bool,
    /// Longest wait for the marker-triggered acquisition, seconds.
    #[arg(long, default_value_t = 10.0, allow_hyphen_values = true)]
    wait: f64,
    /// Subtract this earlier capture (its .sigmf-meta) before processing.
    #[arg(long)]
    background: Option<PathBuf>,
    /// Write into an `out` folder that holds files already.
    #[arg(long)]
    force: bool,
}

/// One capture's options as `radbench capture` takes them, given as keywords.
#[derive(Debug, Clone)]
pub struct CaptureOptions {
    pub waveform: WaveformKind,
    pub waveform_args: WaveformArgs,
    pub payload: Option<String>,
    pub seed: u64,
    pub choices: ProcessingChoices,
    pub repetitions: usize,
    pub tx_off: bool,
    pub wait_s: f64,
    pub background: Option<PathBuf>,
    pub out: Option<PathBuf>,
    pub force: bool,
}

impl CaptureOptions {
    /// `keywords`: a JSON object of the processing choices (`algorithm`, `window`, `m`, ...)
    /// and the command's own options (`bandwidth`, `payload`, `seed`, `tx_off`, `wait`,
    /// `background`, `force`); errors name the keyword, as `process()`'s do.
    pub fn from_keywords(
        waveform: WaveformKind,
        keywords: &str,
        repetitions: usize,
        out: Option<PathBuf>,
    ) -> anyhow::Result<CaptureOptions> {
        use clap::CommandFactory;
        let (choices, own) = keywords::split(keywords)?;
        let longs: Vec<String> = CaptureParser::command()
            .get_arguments()
            .filter_map(|a| a.get_long())
            .map(String::from)
            .collect();
        // An unknown keyword is compared with the processing choices too (did you mean ...).
        let known: Vec<String> = longs
            .iter()
            .cloned()
            .chain(ProcessingChoices::KEYS.iter().map(|k| k.to_string()))
            .collect();
        keywords::check_known(&own, &known, &[])?;
        let argv = ["capture"]
            .into_iter()
            .map(String::from)
            .chain(own.iter().cloned());
        let args = CaptureParser::try_parse_from(argv)
            .map_err(|e| keywords::in_keywords(keywords::parse_error(&e), &longs))?;
        crate::measure::check_repetitions(repetitions)?;
        // Checked now, before anything is sent: a bad value is refused with the bench untouched.
        args.waveform_args
            .spec(waveform)
            .map_err(|e| keywords::in_keywords(e, &longs))?;
        Ok(CaptureOptions {
            waveform,
            waveform_args: args.waveform_args,
            payload: args.bits.payload,
            seed: args.bits.seed,
            choices,
            repetitions,
            tx_off: args.tx_off,
            wait_s: args.wait,
            background: args.background,
            out,
            force: args.force,
        })
    }
}

/// The correction a capture uses: `--correction`, `--calibration`, then the bench file's; loaded
/// and checked here, once, for everything the capture does with it.
pub fn resolve_correction(
    correction: Option<CorrectionMode>,
    calibration: Option<&Path>,
    bench: &Bench,
) -> anyhow::Result<Option<Arc<Calibration>>> {
    let named = calibration.map(Path::to_path_buf).or_else(|| {
        bench
            .path
            .as_ref()
            .and_then(|p| bench.file.response_path(p))
    });
    match (correction, named) {
        (Some(CorrectionMode::None), _) => Ok(None),
        (_, Some(path)) => Ok(Some(Arc::new(Calibration::load(&path)?))),
        (Some(mode), None) => Err(bad_input(format!(
            "--correction {} needs a response calibration: the bench file names none; run \
             `radbench calibrate response --reference-range R --bench FILE --allow-rf` or pass \
             --calibration FILE",
            mode.name()
        ))),
        (None, None) => Ok(None),
    }
}

/// Warnings about a calibration used on this bench: other instruments than it was measured with.
pub fn calibration_warnings(cal: &Calibration, identities: &Identities) -> Vec<String> {
    let seen = &cal.header.instruments;
    let mut out = Vec::new();
    for (what, then, now) in [
        ("AWG", Some(&seen.awg), Some(&identities.awg)),
        ("scope", Some(&seen.scope), Some(&identities.scope)),
        ("Tx", seen.tx.as_ref(), identities.tx.as_ref()),
        ("Rx", seen.rx.as_ref(), identities.rx.as_ref()),
    ] {
        if then != now {
            out.push(format!(
                "the response calibration {} was measured with the {what} {:?}, this capture \
                 used {:?}: measure it again on this bench (`radbench calibrate response`)",
                cal.path.display(),
                then.map_or("none", |s| s.as_str()),
                now.map_or("none", |s| s.as_str()),
            ));
        }
    }
    out
}

/// Checks the output folder before anything radiates: a new or empty folder is created and
/// written to; one that holds files needs `force` (the files it holds are listed in the message,
/// or printed as replaced). A file, or a folder that cannot be written, is bad input.
pub fn prepare_out(out: &Path, force: bool) -> anyhow::Result<()> {
    if out.exists() && !out.is_dir() {
        return Err(bad_input(format!(
            "--out {}: is a file; give a folder (it is created when missing)",
            out.display()
        )));
    }
    if out.is_dir() {
        let mut held: Vec<String> = std::fs::read_dir(out)
            .map_err(|e| bad_input(format!("--out {}: cannot read it: {e}", out.display())))?
            .filter_map(Result::ok)
            .map(|e| e.file_name().to_string_lossy().into_owned())
            .filter(|n| !n.starts_with('.'))
            .collect();
        held.sort();
        if !held.is_empty() {
            let list = held.join(", ");
            if !force {
                return Err(bad_input(format!(
                    "--out {}: holds files already ({list}); give a new folder, or --force to \
                     replace them",
                    out.display()
                )));
            }
            eprintln!(
                "--force: files in {} are replaced where this capture writes the same names ({list})",
                out.display()
            );
        }
    }
    std::fs::create_dir_all(out)
        .map_err(|e| bad_input(format!("--out {}: cannot create it: {e}", out.display())))?;
    // A folder that cannot be written must not cost a capture: try before RF goes on.
    let probe = out.join(format!(".radbench-write-probe-{}", std::process::id()));
    std::fs::OpenOptions::new()
        .write(true)
        .create_new(true)
        .open(&probe)
        .and_then(|_| std::fs::remove_file(&probe))
        .map_err(|e| {
            bad_input(format!(
                "--out {}: cannot write into it: {e}",
                out.display()
            ))
        })?;
    Ok(())
}
