//! The ambiguity function of a waveform as the AWG plays it (its 8-bit codes, the segment padded
//! as the M8195A pads it, looped), or the cross-ambiguity of a saved capture against its
//! reference: the zero-Doppler cut's figures, the Doppler shift that costs 1 dB of peak, and the
//! delay-Doppler map as a plot.

use super::pipeline::Alignable;
use super::transmit::{Dac, Transmission};
use crate::catalog::Catalog;
use crate::driver::open::plan_awg;
use crate::driver::AwgSettings;
use crate::dsp::ambiguity::{cut_figures, Ambiguity, Wrap};
use crate::measure::error::MeasureError;
use crate::measure::records::reprocess::{self, Record};
use crate::physics::C0;
use crate::storage::plot::{draw_heatmap, Heatmap};
use crate::waveform::WaveformSpec;
use num_complex::Complex64;
use serde::Serialize;
use std::path::{Path, PathBuf};

/// The catalog model whose segment padding is applied.
const AWG_MODEL: &str = "keysight-m8195a";
/// Doppler cuts of the plot.
const PLOT_DOPPLER_CUTS: usize = 81;
/// Dynamic range of the plot, dB.
const PLOT_RANGE_DB: f64 = 50.0;

/// What `radbench waveform ambiguity` reports.
#[derive(Debug, Clone, Serialize)]
pub struct AmbiguityReport {
    /// `ambiguity` (the waveform against itself) or `cross-ambiguity` (a capture against it).
    pub kind: &'static str,
    pub waveform: String,
    pub sample_rate_hz: f64,
    /// Samples of the looped segment (the AWG's padding included).
    pub segment_samples: usize,
    /// `periodic` (the looped segment, what the radar sees) or `single` (one repetition,
    /// zero-padded: `--single`).
    pub wrap: &'static str,
    /// Samples the waveform itself has (before padding).
    pub waveform_samples: usize,
    /// The codes' SQNR, dB (what 8-bit quantisation costs).
    pub sqnr_db: f64,
    /// Zero-Doppler cut: the peak (1 for the waveform against itself) and its delay, seconds.
    pub peak: f64,
    pub peak_delay_s: f64,
    /// -3 dB main-lobe width, seconds, and as range (c0 width / 2), metres.
    pub width_3db_s: f64,
    pub width_3db_m: f64,
    /// Peak and integrated side-lobe levels of the zero-Doppler cut, dB.
    pub psl_db: f64,
    pub isl_db: f64,
    /// The Doppler shift that lowers the largest value of its cut by 1 dB, Hz (`null` when it
    /// never does within half the sample rate), and as a radial velocity at the carrier, m/s.
    pub doppler_1db_hz: Option<f64>,
    pub velocity_1db_mps: Option<f64>,
    pub carrier_hz: f64,
    /// The capture folder, for a cross-ambiguity.
    pub capture: Option<PathBuf>,
    /// The plot written, if any.
    pub plot: Option<PathBuf>,
}

/// The reference as the AWG loops it: its codes (per unit full scale) padded with zeros to the
/// segment the catalog's M8195A would load (the unpadded length when the waveform does not fit).
fn as_uploaded(tx: &Transmission) -> Vec<Complex64> {
    let padded = Catalog::embedded()
        .ok()
        .and_then(|c| c.get(AWG_MODEL).ok().cloned())
        .and_then(|m| {
            m.awg.as_ref()?;
            let settings = AwgSettings {
                sample_rate_hz: tx.sample_rate_hz(),
                ..AwgSettings::default()
            };
            plan_awg(&m, &settings, &tx.iq)
                .ok()
                .map(|d| d.padded_samples as usize)
        })
        .unwrap_or(tx.reference.len());
    let mut s = tx.reference.clone();
    s.resize(padded.max(s.len()), Complex64::new(0.0, 0.0));
    s
}

/// The ambiguity of `spec` (bits from `seed` or `payload`) as uploaded, or with `capture` the
/// cross-ambiguity of that capture's first repetition (its own waveform, as recorded) against
/// its reference; `plot` draws the delay-Doppler map (`.png`); `single` takes one
/// repetition alone (zero-padded) instead of the looped segment.
pub fn ambiguity(
    spec: &WaveformSpec,
    seed: u64,
    payload: Option<&[u8]>,
    capture: Option<&Path>,
    plot: Option<&Path>,
    carrier_hz: f64,
    single: bool,
) -> Result<AmbiguityReport, MeasureError> {
    let (tx, x) = match capture {
        None => {
            let tx = Transmission::new(spec, payload, seed, Dac::default())?;
            let s = as_uploaded(&tx);
            (std::sync::Arc::new(tx), s)
        }
        Some(dir) => {
            let bad = |reason: String| MeasureError::option("capture", dir.display(), reason);
            let source = reprocess::discover(&[dir.to_path_buf()])
                .into_iter()
                .next()
                .ok_or_else(|| bad("a capture folder or .sigmf-meta".into()))?
                .map_err(|e| bad(format!("a capture folder or .sigmf-meta ({})", e.reason)))?;
            let loaded = reprocess::load_for_processing(&source, None, None)?;
            let resolved = reprocess::resolve(
                &loaded,
                &reprocess::WaveformChoice::default(),
                &Default::default(),
                None,
            )?;
            let first = loaded
                .repetitions
                .first()
                .ok_or_else(|| bad("a capture with at least one repetition".into()))?;
            let mut pipeline = reprocess::pipeline(&resolved, first.sample_rate_hz())?;
            let aligned = first.align_in(&mut pipeline)?;
            (resolved.tx, aligned.samples)
        }
    };
    let fs = tx.sample_rate_hz();
    let mut s = as_uploaded(&tx);
    if s.len() < x.len() {
        s.resize(x.len(), Complex64::new(0.0, 0.0));
    }
    let wrap = if single {
        Wrap::Aperiodic
    } else {
        Wrap::Periodic
    };
    let mut a = Ambiguity::new(&x, &s, fs, wrap).ok_or_else(|| {
        MeasureError::option("waveform", tx.name(), "a waveform with some energy")
    })?;
    let zero = a.cut(0.0);
    let f = cut_figures(&zero, |m| a.delay_s(m)).ok_or_else(|| {
        MeasureError::option(
            "capture",
            capture.map_or(String::new(), |c| c.display().to_string()),
            "a capture whose correlation with the reference is not flat",
        )
    })?;
    let doppler = a.doppler_for_loss(1.0);
    let mut report = AmbiguityReport {
        kind: if capture.is_some() {
            "cross-ambiguity"
        } else {
            "ambiguity"
        },
        waveform: tx.name().to_string(),
        sample_rate_hz: fs,
        wrap: if single { "single" } else { "periodic" },
        segment_samples: s.len(),
        waveform_samples: tx.reference.len(),
        sqnr_db: tx.quantised.sqnr_db,
        peak: f.peak,
        peak_delay_s: f.peak_delay_s,
        width_3db_s: f.width_3db_s,
        width_3db_m: C0 * f.width_3db_s / 2.0,
        psl_db: f.psl_db,
        isl_db: f.isl_db,
        doppler_1db_hz: doppler,
        velocity_1db_mps: doppler.map(|d| C0 * d / (2.0 * carrier_hz)),
        carrier_hz,
        capture: capture.map(Path::to_path_buf),
        plot: None,
    };
    if let Some(path) = plot {
        let map = delay_doppler_map(&mut a, &report);
        draw_heatmap(path, &map)?;
        report.plot = Some(path.to_path_buf());
    }
    Ok(report)
}

/// The delay-Doppler map around the peak: Doppler up to 3 times the 1 dB shift (or 100
/// Doppler resolutions), delays wide enough for 30 main-lobe widths and the peak's walk.
fn delay_doppler_map(a: &mut Ambiguity, r: &AmbiguityReport) -> Heatmap {
    let fs = r.sample_rate_hz;
    let resolution = fs / r.segment_samples as f64;
    let nu_max = r.doppler_1db_hz.map_or(100.0 * resolution, |d| 3.0 * d);
    let (unit, scale) = if nu_max >= 1e6 {
        ("MHz", 1e6)
    } else if nu_max >= 1e3 {
        ("kHz", 1e3)
    } else {
        ("Hz", 1.0)
    };
    let dopplers: Vec<f64> = (0..PLOT_DOPPLER_CUTS)
        .map(|i| nu_max * (2.0 * i as f64 / (PLOT_DOPPLER_CUTS - 1) as f64 - 1.0))
        .collect();
    let cuts: Vec<Vec<Complex64>> = dopplers.iter().map(|&nu| a.cut(nu)).collect();
    let lags = a.lags();
    let peak_lag = |c: &Vec<Complex64>| {
        c.iter()
            .enumerate()
            .max_by(|x, y| x.1.norm().total_cmp(&y.1.norm()))
            .map_or(0.0, |(m, _)| a.delay_s(m).abs())
    };
    let walk = cuts.iter().map(peak_lag).fold(0.0, f64::max);
    let half_s = (30.0 * r.width_3db_s).max(1.3 * walk).max(8.0 / fs);
    let half = ((half_s * fs).ceil() as usize).min(lags / 2 - 1).max(1);
    let centre = (r.peak_delay_s * fs).round() as isize;
    let x: Vec<f64> = (-(half as isize)..=half as isize)
        .map(|m| (centre + m) as f64 / fs * 1e9)
        .collect();
    let mut db = Vec::with_capacity(x.len() * dopplers.len());
    let peak = r.peak.max(1e-300);
    for m in -(half as isize)..=half as isize {
        let idx = (centre + m).rem_euclid(lags as isize) as usize;
        for c in &cuts {
            db.push(20.0 * (c[idx].norm() / peak).max(1e-15).log10());
        }
    }
    Heatmap {
        title: format!(
            "{} of {}: |A(delay, Doppler)| (dB under the zero-Doppler peak)",
            r.kind, r.waveform
        ),
        x_label: "delay (ns)".into(),
        y_label: format!("Doppler shift ({unit})"),
        x_window: (x[0], x[x.len() - 1]),
        x,
        y: dopplers.iter().map(|d| d / scale).collect(),
        db,
        range_db: PLOT_RANGE_DB,
        marks: Vec::new(),
    }
}
