//! `radbench waveform ambiguity`: the delay-Doppler ambiguity function of a waveform as the AWG
//! plays it, or a capture's cross-ambiguity against its reference (`measure::ambiguity` does
//! the work).

use super::args::WaveformArgs;
use radbench::measure::{ambiguity, AmbiguityReport};
use radbench::waveform::WaveformKind;
use std::path::PathBuf;

#[derive(Debug, clap::Args)]
pub struct Args {
    #[command(subcommand)]
    pub command: WaveformCommand,
}

#[derive(Debug, clap::Subcommand)]
pub enum WaveformCommand {
    /// The delay-Doppler ambiguity function of the waveform as uploaded (the AWG's 8-bit codes,
    /// the segment padded and looped): its zero-Doppler cut's -3 dB width, peak and integrated
    /// side-lobe levels, and the Doppler shift that costs 1 dB of peak. With --capture, the
    /// cross-ambiguity of a saved capture against its reference.
    Ambiguity(Box<AmbiguityArgs>),
}

#[derive(Debug, clap::Args)]
pub struct AmbiguityArgs {
    /// The waveform.
    #[arg(long, value_parser = super::args::listed::<WaveformKind>(), default_value = "msk-lfm")]
    pub waveform: WaveformKind,
    #[command(flatten)]
    pub waveform_args: WaveformArgs,
    /// Data to carry (UTF-8 text) instead of PRBS bits.
    #[arg(long, value_name = "TEXT")]
    pub payload: Option<String>,
    /// Seed of the PRBS bits when no payload is given.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// A capture folder (or its .sigmf-meta): the cross-ambiguity of its first repetition
    /// against its reference (the waveform it recorded; the waveform options are not used).
    #[arg(long, value_name = "DIR")]
    pub capture: Option<PathBuf>,
    /// Draw the delay-Doppler map (.png).
    #[arg(long, value_name = "FILE")]
    pub plot: Option<PathBuf>,
    /// The carrier the Doppler shift is turned into a velocity with, Hz.
    #[arg(long, value_name = "HZ", default_value_t = 80e9)]
    pub carrier: f64,
    /// One repetition alone (zero-padded: an isolated pulse, the textbook's ambiguity function)
    /// instead of the looped segment the radar correlates.
    #[arg(long)]
    pub single: bool,
    /// Print one JSON object.
    #[arg(long)]
    pub json: bool,
}

pub(crate) fn run(args: Args, _global: &super::global::Global) -> anyhow::Result<()> {
    match args.command {
        WaveformCommand::Ambiguity(a) => run_ambiguity(*a),
    }
}

fn run_ambiguity(args: AmbiguityArgs) -> anyhow::Result<()> {
    if !(args.carrier.is_finite() && args.carrier > 0.0) {
        return Err(radbench::exit::bad_input(format!(
            "--carrier {}: allowed: a positive frequency in Hz (80e9 for the bench)",
            args.carrier
        )));
    }
    if let Some(p) = &args.plot {
        let png = p.extension().is_some_and(|e| e.eq_ignore_ascii_case("png"));
        if !png {
            return Err(radbench::exit::bad_input(format!(
                "--plot {}: allowed: a .png file (the delay-Doppler map is a heat map)",
                p.display()
            )));
        }
    }
    let kind = args.waveform;
    let spec = args.waveform_args.spec(kind)?;
    let report = ambiguity(
        &spec,
        args.seed,
        args.payload.as_ref().map(|p| p.as_bytes()),
        args.capture.as_deref(),
        args.plot.as_deref(),
        args.carrier,
        args.single,
    )?;
    if args.json {
        super::terminal::out(&serde_json::to_string(&report)?)
    } else {
        super::terminal::out(&text(&report))
    }
}

fn text(r: &AmbiguityReport) -> String {
    let mut out = match &r.capture {
        Some(c) => format!(
            "cross-ambiguity of {} against its {} reference\n",
            c.display(),
            r.waveform
        ),
        None => format!(
            "ambiguity of {} as uploaded: {} samples at {} GSa/s ({} padded by the AWG), 8-bit \
             codes (SQNR {:.1} dB)\n",
            r.waveform,
            r.waveform_samples,
            r.sample_rate_hz / 1e9,
            r.segment_samples,
            r.sqnr_db
        ),
    };
    out += &format!(
        "zero-Doppler cut: peak {:.4} at {:.3} ns, -3 dB width {:.3} ns ({:.2} cm), peak \
         side-lobe {:.2} dB, integrated side-lobe {:.2} dB\n",
        r.peak,
        r.peak_delay_s * 1e9,
        r.width_3db_s * 1e9,
        r.width_3db_m * 100.0,
        r.psl_db,
        r.isl_db
    );
    out += &match (r.doppler_1db_hz, r.velocity_1db_mps) {
        (Some(d), Some(v)) => format!(
            "1 dB of peak lost at a Doppler shift of {} ({v:.3} m/s radial at {} GHz)",
            hz(d),
            r.carrier_hz / 1e9
        ),
        _ => "the peak never falls by 1 dB within half the sample rate".to_string(),
    };
    if let Some(p) = &r.plot {
        out += &format!("\nplot: {}", p.display());
    }
    out
}

fn hz(v: f64) -> String {
    if v >= 1e6 {
        format!("{:.3} MHz", v / 1e6)
    } else if v >= 1e3 {
        format!("{:.3} kHz", v / 1e3)
    } else {
        format!("{v:.1} Hz")
    }
}
