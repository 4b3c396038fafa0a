//! `radbench calibrate response`: the chain's response measured on one reference pillar, checked
//! to help, and stored beside the bench file (`measure::response`).

use super::args::WaveformArgs;
use super::capture::{bench_source, journal, open_bench};
use radbench::measure::Interrupt;
use radbench::measure::MeasureError;
use radbench::measure::Rig;
use radbench::measure::{calibrate_with, CalibrateRequest, Calibrated};
use radbench::measure::{response_path, response_report, store_response};
use radbench::measure::{AwgLink, Calibration, Response, ScopeLink};
use radbench::waveform::WaveformKind;
use std::path::{Path, PathBuf};

#[derive(Debug, clap::Args)]
pub struct Args {
    /// True range of the reference pillar (antennas to pillar), metres. The bench's system delay
    /// must be calibrated already (`radbench calibrate --reference-range R`).
    #[arg(long, value_name = "METRES", allow_hyphen_values = true)]
    pub reference_range: f64,
    /// Bench file: the result is stored beside it and named in its [calibration] section.
    /// Without one, the built-in mock lab is measured.
    #[arg(long, value_name = "FILE")]
    pub bench: Option<PathBuf>,
    /// Scene of the built-in mock lab (examples/scene.toml; `[chain] preset = "thesis-lab"` for
    /// a realistic chain).
    #[arg(long, value_name = "FILE")]
    pub scene: Option<PathBuf>,
    /// Explicit permit to switch on the AWG outputs and the Tx/Rx front ends.
    #[arg(long)]
    pub allow_rf: bool,
    /// The waveform whose band is measured: calibrate with the waveform (and its parameters,
    /// e.g. `--band upper`) the captures will use.
    #[arg(long, value_parser = super::args::listed::<WaveformKind>(), default_value = "msk-lfm")]
    pub waveform: WaveformKind,
    #[command(flatten)]
    pub waveform_args: WaveformArgs,
    /// Repetitions averaged with the transmitter on. With it off, as many as give 2^20 noise
    /// samples for DC and I/Q imbalance (at most this many).
    #[arg(long, default_value_t = 16, value_name = "N")]
    pub repetitions: usize,
    /// Half-width of the window around the reference's echo, ns: the longest chain echo
    /// measured (and 1 / (2 gate) the finest ripple resolved). Other echoes must lie outside it
    /// (and its taper, half as wide again). Default: up to 8 ns, less when the reference is so
    /// close that the Tx -> Rx leakage would fall inside (a reference at 2 m or more gets 8 ns).
    #[arg(long, value_name = "NS", allow_hyphen_values = true)]
    pub gate_ns: Option<f64>,
    /// A fixed reflector in the reference's scene (a reference reflector, a mount), antennas to
    /// reflector, metres, at least 0.3 m from the reference. Named, it is measured as the
    /// scene's: unnamed within the gate, it is taken for the chain's own response, and every
    /// capture corrected with it carries its image (phase ranges drift with the target's place:
    /// docs/metrology.md).
    #[arg(long, value_name = "METRES", allow_hyphen_values = true)]
    pub reflector: Option<f64>,
    /// Where to write the calibration (a .toml header; the table goes beside it as .npy).
    /// Default: beside the bench file, <bench>-response.toml; with the built-in lab, nothing
    /// is written without it.
    #[arg(long, value_name = "FILE")]
    pub out: Option<PathBuf>,
    /// Store the calibration even when correcting with it does not bring the reference's
    /// side-lobe or width closer to a flat chain's.
    #[arg(long)]
    pub force: bool,
    /// Draw the measured gain and phase against frequency (FILE.svg or FILE.png).
    #[arg(long, value_name = "FILE")]
    pub plot: Option<PathBuf>,
    /// Print one JSON object.
    #[arg(long)]
    pub json: bool,
    #[command(flatten)]
    pub scope_model: super::scope_model::ScopeModelArgs,
}

fn check(args: &Args) -> Result<(), MeasureError> {
    radbench::measure::check(args.reference_range, 2.0)?;
    radbench::measure::check_repetitions(args.repetitions)?;
    radbench::measure::check_gate_ns(args.gate_ns)?;
    radbench::measure::check_reflector_m(args.reflector, args.reference_range)?;
    radbench::measure::check_response_out(args.out.as_deref())?;
    if let Some(plot) = &args.plot {
        let ext = plot.extension().and_then(|e| e.to_str()).unwrap_or("");
        if !matches!(ext, "svg" | "png") {
            return Err(MeasureError::option(
                "plot",
                plot.display(),
                "a file name ending in .svg or .png",
            ));
        }
    }
    if !args.allow_rf {
        return Err(MeasureError::NoPermit { run: "calibration" });
    }
    Ok(())
}

pub(crate) fn run(args: Args, global: &super::global::Global) -> anyhow::Result<()> {
    check(&args)?;
    let waveform = args.waveform_args.spec(args.waveform)?;
    let started = std::time::Instant::now();
    super::global::runtime()?.block_on(async {
        let source = args.scope_model.apply(bench_source(
            args.bench.as_deref(),
            args.scene.as_deref(),
            AwgLink::Hislip,
            ScopeLink::Vicp,
        )?)?;
        let manual = super::manual_front::confirm_file(args.bench.as_deref(), "calibration")?;
        let interrupt = Interrupt::listen()?;
        let mut bench = open_bench(source, args.json).await?;
        let out = response_path(args.out.as_deref(), &bench);
        let catalog = bench.file.catalog()?;
        let request = CalibrateRequest {
            waveform,
            reference_range_m: args.reference_range,
            repetitions: args.repetitions,
            gate_s: gate_s(&args),
            reflector_m: args.reflector,
        };
        let mut rig = Rig::connect(&bench, &catalog, journal(global)?).await?;
        let calibrated =
            calibrate_with(&mut rig, &bench, &request, &manual.permit(), &interrupt).await?;
        drop(rig);
        let verdict = calibrated.verdict();
        if let (Err(why), false) = (&verdict, args.force) {
            print_report(&args, &calibrated, None, Some(why));
            return Err(MeasureError::CorrectionRefused(format!(
                "not stored: {why} (--force stores it anyway)"
            ))
            .into());
        }
        if let Some(plot) = &args.plot {
            draw(plot, &calibrated.response)?;
        }
        let stored = match &out {
            Some(path) => Some(store_response(&calibrated, path, &mut bench)?),
            None => None,
        };
        print_report(&args, &calibrated, stored.as_ref(), verdict.err().as_ref());
        if !args.json {
            eprintln!("took {:.2} s", started.elapsed().as_secs_f64());
        }
        Ok(())
    })
}

/// The gate asked for, or the default for the reference's range.
fn gate_s(args: &Args) -> f64 {
    radbench::measure::gate_or_default_s(args.gate_ns, args.reference_range)
}

/// A reference nearer than this can leave a ghost 0.5 m ahead of a corrected pillar with the
/// low side-lobe windows (11 and 17 of 96 combinations at 0.6 and 0.7 m, clean from 0.8 m on;
/// docs/calibration.md, Known limits), m.
const NEAREST_CLEAN_REFERENCE_M: f64 = 0.8;

fn print_report(
    args: &Args,
    calibrated: &Calibrated,
    stored: Option<&Calibration>,
    refused: Option<&String>,
) {
    if args.json {
        let report = response_report(calibrated, stored, refused.map(String::as_str));
        println!("{report}");
        return;
    }
    let (r, f) = (&calibrated.response, &calibrated.reference);
    let g = &r.figures;
    let opt = |v: Option<f64>, unit: &str| v.map_or("-".into(), |v| format!("{v:.2} {unit}"));
    println!(
        "chain response over {:.3} .. {:.3} GHz ({} repetitions, gate +-{:.1} ns)",
        r.band_hz[0] / 1e9,
        r.band_hz[1] / 1e9,
        args.repetitions,
        gate_s(args) * 1e9
    );
    println!("  gain ripple          {:.2} dB p-p", g.ripple_db_pp);
    println!(
        "  phase ripple         {:.2} deg p-p",
        g.phase_ripple_deg_pp
    );
    println!(
        "  group-delay ripple   {:.1} ps p-p",
        g.group_delay_ripple_ps_pp
    );
    println!("  delay offset         {:+.1} ps", g.delay_offset_ps);
    println!(
        "  rx I/Q imbalance     {:+.2} dB, {:+.2} deg (from the receiver's noise, Tx off)",
        g.rx_iq_gain_db, g.rx_iq_phase_deg
    );
    println!(
        "  tx I/Q imbalance     {:+.2} dB, {:+.2} deg (from the image, the receiver's told apart)",
        g.tx_iq_gain_db, g.tx_iq_phase_deg
    );
    if g.iq_skews_separated {
        println!(
            "  I/Q skew             tx {:+.2} ps, rx {:+.2} ps (+-{:.2} ps)",
            g.tx_iq_skew_ps, g.rx_iq_skew_ps, g.iq_skew_sd_ps
        );
    } else {
        println!(
            "  I/Q skew             {:+.1} ps in the image, tx and rx not told apart at this \
             reference (its echo's carrier phase is near a multiple of 90 deg): neither is \
             corrected; move the reference by about 0.25 mm and calibrate again to separate them",
            g.iq_skew_ps
        );
    }
    println!("  image left           {:.1} dB", g.image_db);
    println!(
        "  DC offset            I {:+.4} V, Q {:+.4} V",
        g.dc_v[0], g.dc_v[1]
    );
    println!(
        "  spread over reps     {:.3} dB, {:.2} deg (largest across the band)",
        g.spread_db_max, g.spread_deg_max
    );
    for e in &r.chain_echoes {
        println!(
            "  chain echo           {:.2} ns behind every path, {:.1} dB, {:+.0} deg (an IF \
             cable's, or another mismatch; kept in the response)",
            e.delay_ns, e.level_db, e.phase_deg
        );
    }
    for e in &r.scene_echoes {
        let place = if e.delay_ns < 0.0 {
            "ahead of"
        } else {
            "behind"
        };
        println!(
            "  leakage/scene        {:.2} ns {place} the reference, {:.1} dB (divided out of the \
             reference only)",
            e.delay_ns.abs(),
            e.level_db
        );
    }
    let reference_m = calibrated.request.reference_range_m;
    if reference_m < NEAREST_CLEAN_REFERENCE_M {
        println!(
            "  reference near       {reference_m} m: nearer than {NEAREST_CLEAN_REFERENCE_M} m the \
             corrected captures can show a ghost about 0.5 m ahead of a strong target with the low \
             side-lobe windows (docs/calibration.md, Known limits); calibrate at \
             {NEAREST_CLEAN_REFERENCE_M} m or more"
        );
    }
    if let Some(db) = g.leakage_unseen_db {
        println!(
            "  leakage not found    {:.2} m ahead of the reference (range 0), under {db:.1} dB \
             (none there, or the chain's response there hides it, and the fit may hold it as \
             the chain's): a corrected capture may then show its image that far ahead of a \
             strong target, which the residual profile keeps from being reported; calibrating \
             with the reference 0.3 m further may let the search see it",
            calibrated.request.reference_range_m
        );
    }
    if let (Some(m), Some(db)) = (g.echo_ahead_m, g.echo_ahead_db) {
        println!(
            "  echo ahead           at {m:.2} m, {:.2} m ahead of the reference, {db:.1} dB, inside \
             the gate: a chain's echoes follow its main path, so this is likely the scene's (a \
             mount, a table edge), and the fit took it for the chain's own response, which every \
             corrected capture then carries (phase ranges err with the target's place). If it \
             stays put, name it: --reflector {m:.2} (or [reference] reflector_m = {m:.2} in the \
             bench file); else take it away and calibrate again (docs/calibration.md)",
            calibrated.request.reference_range_m - m
        );
    }
    println!(
        "reference pillar: side-lobe {} -> {}, -3 dB width {} -> {}, range {}",
        opt(f.sidelobe_db_before, "dB"),
        opt(f.sidelobe_db_after, "dB"),
        opt(f.width_cm_before, "cm"),
        opt(f.width_cm_after, "cm"),
        range_change(f.range_m_before, f.range_m_after),
    );
    match (stored, refused) {
        (_, Some(why)) if stored.is_none() => println!("NOT stored: {why}"),
        (Some(c), Some(why)) => println!("stored in {} with --force: {why}", c.path.display()),
        (Some(c), None) => println!("stored in {}", c.path.display()),
        (None, _) => println!(
            "built-in mock lab: not stored (pass --out FILE.toml, or --bench FILE to store it \
             beside the bench file)"
        ),
    }
}

/// The measured gain (dB) and phase (degrees / 10) against frequency, with the spread.
/// The reference's range before and after the correction, at the precision it is measured to
/// (0.1 mm), with the change in millimetres: the correction moves it by far less than a
/// centimetre, which `2.00 m -> 2.00 m` would hide.
fn range_change(before: Option<f64>, after: Option<f64>) -> String {
    let m = |v: Option<f64>| v.map_or("-".to_string(), |v| format!("{v:.4} m"));
    match (before, after) {
        (Some(b), Some(a)) => format!(
            "{} -> {} ({} mm)",
            m(before),
            m(after),
            radbench::measure::signed((a - b) * 1e3, 1)
        ),
        _ => format!("{} -> {}", m(before), m(after)),
    }
}

fn draw(path: &Path, r: &Response) -> Result<(), MeasureError> {
    use radbench::storage::{Curve, LineStyle, ProfilePlot};
    let f: Vec<f64> = r.table.freq_hz.iter().map(|f| f / 1e9).collect();
    let gain: Vec<f64> = r
        .table
        .response
        .iter()
        .map(|h| 20.0 * h.norm().max(1e-300).log10())
        .collect();
    let phase: Vec<f64> = r
        .table
        .response
        .iter()
        .map(|h| h.arg().to_degrees() / 10.0)
        .collect();
    let band = |sign: f64| -> Vec<f64> {
        gain.iter()
            .zip(&r.spread_db)
            .map(|(g, s)| g + sign * s)
            .collect()
    };
    let mut plot = ProfilePlot::new(
        "Chain response (radbench calibrate response)",
        vec![
            Curve::solid("gain (dB)", f.clone(), gain.clone()),
            Curve::solid("phase (deg / 10)", f.clone(), phase),
            Curve {
                label: "gain + spread".into(),
                range_m: f.clone(),
                db: band(1.0),
                style: LineStyle::Dashed,
            },
            Curve {
                label: "gain - spread".into(),
                range_m: f,
                db: band(-1.0),
                style: LineStyle::Dashed,
            },
        ],
    );
    plot.window_m = Some(contiguous_around_zero(&r.table.freq_hz));
    plot.y_label = "gain (dB), phase (deg / 10)".into();
    plot.x_label = "frequency offset from the carrier (GHz)".into();
    radbench::storage::draw(path, &plot)?;
    Ok(())
}

/// The run of table frequencies around 0 Hz without a gap (a step over 3 times the usual), GHz:
/// beyond it the waveform's power dips under the table's floor and the response is not shown.
fn contiguous_around_zero(freq_hz: &[f64]) -> (f64, f64) {
    let steps: Vec<f64> = freq_hz.windows(2).map(|w| w[1] - w[0]).collect();
    let mut sorted = steps.clone();
    sorted.sort_by(f64::total_cmp);
    let usual = sorted.get(sorted.len() / 2).copied().unwrap_or(0.0);
    let centre = freq_hz
        .partition_point(|&f| f < 0.0)
        .min(freq_hz.len().saturating_sub(1));
    let (mut lo, mut hi) = (centre, centre);
    while lo > 0 && steps[lo - 1] <= 3.0 * usual {
        lo -= 1;
    }
    while hi + 1 < freq_hz.len() && steps[hi] <= 3.0 * usual {
        hi += 1;
    }
    match (freq_hz.get(lo), freq_hz.get(hi)) {
        (Some(a), Some(b)) if b > a => (a / 1e9, b / 1e9),
        _ => (-1.0, 1.0),
    }
}

#[cfg(test)]
mod tests {
    #[test]
    fn ranges_show_the_millimetres_the_correction_moves() {
        assert_eq!(
            super::range_change(Some(2.00031), Some(1.99992)),
            "2.0003 m -> 1.9999 m (-0.4 mm)"
        );
        assert_eq!(super::range_change(Some(2.0), None), "2.0000 m -> -");
    }
}
