//! Running a response calibration on a bench (`radbench calibrate response`, campaigns): the
//! reference pillar captured with the transmitter on and off, the response measured
//! (`response::measure`), and the correction tried on the same captures before it may be stored.

use super::response::{
    measure, Calibration, InstrumentsSeen, PhaseAnchor, ReferenceFigures, ResidualWindows,
    Response, ResponseHeader, FORMAT,
};
use crate::driver::RfPermit;
use crate::measure::bench::in_use::Bench;
use crate::measure::bench::interrupt::Interrupt;
use crate::measure::bench::station::{Captured, Identities};
use crate::measure::capture::{prepare, CaptureRequest, Rig};
use crate::measure::error::MeasureError;
use crate::measure::processing::options::ProcessOptions;
use crate::measure::processing::pipeline::{Aligned, Pipeline, Processed, RecordGeometry};
use crate::waveform::WaveformSpec;
use std::path::Path;

/// The side-lobe level must come this much closer to a flat chain's, dB, for a correction to be
/// stored (or the width by [`MIN_WIDTH_IMPROVEMENT_CM`]).
pub(crate) const MIN_IMPROVEMENT_DB: f64 = 0.1;

/// ... or the -3 dB width this much closer, cm (0.5 mm: a few times what correcting a flat chain
/// moves it, 0.01-0.02 cm).
pub(crate) const MIN_WIDTH_IMPROVEMENT_CM: f64 = 0.05;

/// A chain that measures this uneven (gain ripple p-p, dB; phase ripple p-p, degrees) or shows a
/// discrete echo may be corrected to a reference within [`NEAR_FLAT_DB`] and [`NEAR_FLAT_CM`] of
/// a flat chain's figures even when they were that close before.
const UNEVEN_RIPPLE_DB: f64 = 0.5;
const UNEVEN_PHASE_DEG: f64 = 5.0;
const NEAR_FLAT_DB: f64 = 0.15;
const NEAR_FLAT_CM: f64 = 0.1;

/// A flat band's -3 dB width in range cells `c / 2B` (a sinc's).
const FLAT_CHAIN_WIDTH: f64 = 0.8859;

/// The peak side-lobe of a flat band's point spread without a window (the first side-lobe of a
/// sinc), which the calibration's processing uses, dB.
pub(crate) const FLAT_CHAIN_SIDELOBE_DB: f64 = -13.26;

/// Samples (at the waveform's rate, after alignment) of the receiver's own noise that the DC and
/// I/Q imbalance are read from, at least: the transmitter-off capture takes as many repetitions
/// as reach this, never more than the transmitter-on one. 2^20 samples give those figures a
/// standard deviation under 0.01 dB and 0.07 degrees of white noise (about 1 / sqrt(N)); the
/// band-limited noise after decimation counts for fewer independent samples, a few times that.
pub(crate) const OFF_NOISE_SAMPLES: usize = 1 << 20;

/// Repetitions captured with the transmitter off when `on` are captured with it on, for
/// repetitions of `period` samples.
pub(crate) fn off_repetitions(on: usize, period: usize) -> usize {
    OFF_NOISE_SAMPLES
        .div_ceil(period.max(1))
        .clamp(1, on.max(1))
}

/// What to calibrate.
#[derive(Debug, Clone, Copy)]
pub struct CalibrateRequest {
    /// What to transmit: the table covers this waveform's band.
    pub waveform: WaveformSpec,
    pub reference_range_m: f64,
    pub repetitions: usize,
    /// Half-width of the window around the reference's echo, seconds.
    pub gate_s: f64,
    /// A fixed reflector the user named in the reference's scene (antennas to reflector), m:
    /// measured as the scene's, never as the chain's, however close to the reference.
    pub reflector_m: Option<f64>,
}

/// A response measured on a bench, with the reference's figures before and after correcting it.
#[derive(Debug, Clone)]
pub struct Calibrated {
    pub request: CalibrateRequest,
    pub response: Response,
    pub reference: ReferenceFigures,
    pub identities: Identities,
    pub system_delay_s: f64,
}

impl Calibrated {
    /// What the correction did to the reference (its side-lobe and width before and after), or
    /// why it does not help: it must bring the side-lobe (by `MIN_IMPROVEMENT_DB`) or the -3 dB
    /// width (by `MIN_WIDTH_IMPROVEMENT_CM`) closer to a flat chain's and take neither further
    /// away by more than that. Closer, not lower: a chain's echo can as well lower a side-lobe (as
    /// the thesis' lab measured with OFDM, Table 4.7) as raise it.
    pub fn verdict(&self) -> Result<String, String> {
        let f = &self.reference;
        let flat_width_cm = FLAT_CHAIN_WIDTH * crate::physics::C0
            / (2.0 * self.request.waveform.bandwidth_hz())
            * 100.0;
        let off_psl = |db: f64| (db - FLAT_CHAIN_SIDELOBE_DB).abs();
        let off_width = |cm: f64| (cm - flat_width_cm).abs();
        let (Some(b), Some(a), Some(wb), Some(wa)) = (
            f.sidelobe_db_before,
            f.sidelobe_db_after,
            f.width_cm_before,
            f.width_cm_after,
        ) else {
            return Err(
                "the reference's side-lobes could not be measured (is the pillar alone, within \
                 0.3 m of the reference range?)"
                    .into(),
            );
        };
        let psl_gain = off_psl(b) - off_psl(a);
        let width_gain = off_width(wb) - off_width(wa);
        let closer = psl_gain >= MIN_IMPROVEMENT_DB || width_gain >= MIN_WIDTH_IMPROVEMENT_CM;
        let worse = psl_gain < -MIN_IMPROVEMENT_DB || width_gain < -MIN_WIDTH_IMPROVEMENT_CM;
        let what = format!(
            "side-lobe {b:.2} -> {a:.2} dB, width {wb:.2} -> {wa:.2} cm; a flat chain's \
             {FLAT_CHAIN_SIDELOBE_DB} dB, {flat_width_cm:.2} cm"
        );
        // A chain can be far from flat and still give a nearly flat side-lobe and width (the
        // thesis-lab chain with OFDM does): there, a correction that leaves the reference flat
        // is kept.
        let m = &self.response.figures;
        let uneven = m.ripple_db_pp >= UNEVEN_RIPPLE_DB
            || m.phase_ripple_deg_pp >= UNEVEN_PHASE_DEG
            || !self.response.chain_echoes.is_empty();
        let flat_after = off_psl(a) <= NEAR_FLAT_DB && off_width(wa) <= NEAR_FLAT_CM;
        if (closer || (uneven && flat_after)) && !worse {
            Ok(what)
        } else {
            Err(format!(
                "correcting does not bring the reference closer to a flat chain ({what}; at least \
                 {MIN_IMPROVEMENT_DB} dB or {MIN_WIDTH_IMPROVEMENT_CM} cm closer needed, neither \
                 further): the chain is as flat as this measures, or the reference is not alone \
                 within the gate"
            ))
        }
    }

    /// Writes the calibration to `path` (the table beside it).
    pub fn save(&self, path: &Path) -> Result<Calibration, MeasureError> {
        let id = &self.identities;
        let header = ResponseHeader {
            format: FORMAT.into(),
            data: String::new(),
            data_sha256: String::new(),
            columns: Vec::new(),
            measured_at: crate::storage::utc_now_rfc3339(),
            radbench_version: env!("CARGO_PKG_VERSION").into(),
            waveform: self.request.waveform.name().into(),
            band_hz: self.response.band_hz,
            reference_range_m: self.request.reference_range_m,
            repetitions: self.request.repetitions,
            gate_ns: self.request.gate_s * 1e9,
            reflector_m: self.request.reflector_m,
            system_delay_s: self.system_delay_s,
            figures: self.response.figures,
            reference: self.reference,
            instruments: InstrumentsSeen {
                awg: id.awg.clone(),
                scope: id.scope.clone(),
                tx: id.tx.clone(),
                rx: id.rx.clone(),
            },
            chain_echoes: self.response.chain_echoes.clone(),
            scene_echoes: self.response.scene_echoes.clone(),
            residual: self.response.residual.clone(),
        };
        Calibration::save(path, &self.response, header)
    }
}

/// Every range window (`--window`), for the calibration's residual profiles.
pub(crate) fn residual_windows() -> Vec<(&'static str, crate::dsp::Window)> {
    <crate::measure::processing::options::WindowName as strum::VariantArray>::VARIANTS
        .iter()
        .map(|w| (w.name(), w.to_dsp()))
        .collect()
}

/// The aligned repetitions as `response::measure` takes them.
pub(crate) fn repetitions(aligned: &[Aligned]) -> Vec<super::response::Repetition<'_>> {
    aligned
        .iter()
        .map(|a| super::response::Repetition {
            samples: &a.samples,
            residual_s: a.residual_s,
        })
        .collect()
}

/// The reference's figures in one processed record: the detection nearest its range.
fn reference_of(p: &Processed, range_m: f64) -> (Option<f64>, Option<f64>, Option<f64>) {
    let t = p
        .targets
        .iter()
        .filter(|t| (t.range_m - range_m).abs() < 0.3)
        .max_by(|a, b| a.level_db.total_cmp(&b.level_db));
    (
        t.and_then(|t| t.sidelobe_db),
        t.and_then(|t| t.width_3db_cm),
        t.map(|t| t.range_m),
    )
}

/// `request` with the bench file's fixed reflector (`[reference] reflector_m`) where
/// `--reflector` names none, checked as `--reflector` is, before any RF.
fn with_bench_reflector(
    request: &CalibrateRequest,
    bench: &Bench,
) -> Result<CalibrateRequest, MeasureError> {
    let (None, Some(r)) = (request.reflector_m, bench.file.reference_reflector_m()) else {
        return Ok(*request);
    };
    super::response::check_reflector_m(Some(r), request.reference_range_m).map_err(|e| {
        let allowed = match e {
            MeasureError::Option { allowed, .. } => allowed,
            other => other.to_string(),
        };
        let line = bench
            .file
            .lines
            .get("reference.reflector_m")
            .map(|l| format!("line {l}: "))
            .unwrap_or_default();
        MeasureError::BenchFile(crate::measure::bench::bench_file::BenchFileError::Invalid {
            path: bench.file.path.clone(),
            message: format!(
                "{line}[reference] reflector_m = {r}: {allowed} (or name the reflector of this \
                 calibration with --reflector)"
            ),
        })
    })?;
    Ok(CalibrateRequest {
        reflector_m: Some(r),
        ..*request
    })
}

/// Calibrates on `bench` through a connected `rig` (a campaign keeps its own), with the user's
/// `permit` (refused on a bench with manual front ends unless it carries their confirmation).
pub async fn calibrate_with(
    rig: &mut Rig,
    bench: &Bench,
    request: &CalibrateRequest,
    permit: &RfPermit,
    interrupt: &Interrupt,
) -> Result<Calibrated, MeasureError> {
    crate::measure::capture::check_manual_confirmed(bench, permit)?;
    let request = &with_bench_reflector(request, bench)?;
    let catalog = bench.file.catalog()?;
    let kind = request.waveform.kind();
    let system_delay_s = bench.file.system_delay_s();
    let options = ProcessOptions {
        system_delay_s,
        max_range_m: request.reference_range_m + 4.0,
        ..ProcessOptions::for_waveform(kind)
    };
    let capture = |tx_off| CaptureRequest {
        waveform: request.waveform,
        payload: None,
        seed: 1,
        options: options.clone(),
        tx_off,
        wait_s: 10.0,
        background: None,
    };
    // Both preparations at once (each builds its pipeline off the runtime), before any RF.
    let (request_on, request_off) = (capture(false), capture(true));
    let (on, off) = tokio::join!(
        prepare(bench, &catalog, &request_on),
        prepare(bench, &catalog, &request_off)
    );
    let (on, off) = (on?, off?);
    let reps = request.repetitions;
    let tx = on.tx.clone();
    let fs = tx.sample_rate_hz();
    let geometry = RecordGeometry::for_capture(on.plan.period, fs, &options);
    let capture_rate_hz = on.plan.scope.sample_rate_hz;
    // The calibration's own pipelines (two: the transmitter-off repetitions are aligned on both
    // cores) are built while the bench captures with RF on...
    let build = || {
        let (tx, options) = (tx.clone(), options.clone());
        tokio::task::spawn_blocking(move || {
            let mut pipeline = Pipeline::new(tx, options, geometry)?;
            pipeline.prepare_capture_rate(capture_rate_hz)?;
            Ok::<_, MeasureError>(pipeline)
        })
    };
    let (building, building_2) = (build(), build());
    let built = |b: tokio::task::JoinHandle<Result<Pipeline, MeasureError>>| async move {
        b.await.map_err(|e| MeasureError::Worker(e.to_string()))?
    };
    let taken_on = rig.acquire(bench, &on, reps, permit, interrupt).await?;
    let awg_vpp = taken_on.captured.applied.awg.i_amplitude_vpp;
    // ...and align those repetitions and process their average uncorrected while it captures
    // with RF off.
    let aligning = async {
        let pipeline = built(building).await?;
        crate::measure::bench::blocking::off_runtime(move || {
            let mut pipeline = pipeline;
            pipeline.set_awg_amplitude(awg_vpp)?;
            let aligned = align(&mut pipeline, &taken_on.captured, 0..reps)?;
            let before = uncorrected(&mut pipeline, &aligned)?;
            Ok::<_, MeasureError>((pipeline, aligned, before))
        })
        .await?
    };
    let (taken_off, aligned_on, pipeline_2) = tokio::join!(
        rig.acquire(
            bench,
            &off,
            off_repetitions(reps, geometry.period),
            permit,
            interrupt
        ),
        aligning,
        built(building_2)
    );
    let (taken_off, (mut pipeline, on_aligned, before), mut pipeline_2) =
        (taken_off?, aligned_on?, pipeline_2?);
    let identities = rig.identities().clone();
    let request = *request;
    let expected_delay_s = 2.0 * request.reference_range_m / crate::dsp::C0 + system_delay_s;
    let (response, reference) = crate::measure::bench::blocking::off_runtime(move || {
        let off = &taken_off.captured;
        let half = off.repetitions() / 2;
        let (first, second) = rayon::join(
            || align(&mut pipeline, off, 0..half),
            || align(&mut pipeline_2, off, half..off.repetitions()),
        );
        let mut off_aligned = first?;
        off_aligned.extend(second?);
        let response = measure(
            &tx.reference,
            fs,
            &repetitions(&on_aligned),
            &off_aligned
                .iter()
                .map(|a| a.samples.as_slice())
                .collect::<Vec<_>>(),
            expected_delay_s,
            request.gate_s,
            system_delay_s,
            named_delay_s(&request),
            &ResidualWindows {
                windows: &residual_windows(),
                band_hz: tx.band_hz(),
            },
        )?;
        let reference = corrected(&mut pipeline, &response, before, &request)?;
        Ok::<_, MeasureError>((response, reference))
    })
    .await??;
    Ok(Calibrated {
        request,
        response,
        reference,
        identities,
        system_delay_s,
    })
}

/// Where the named reflector's echo lies relative to the reference's, s.
pub(crate) fn named_delay_s(request: &CalibrateRequest) -> Option<f64> {
    request
        .reflector_m
        .map(|r| 2.0 * (r - request.reference_range_m) / crate::dsp::C0)
}

/// Repetitions `which` of `captured`, decimated and aligned.
fn align(
    pipeline: &mut Pipeline,
    captured: &Captured,
    which: std::ops::Range<usize>,
) -> Result<Vec<Aligned>, MeasureError> {
    which
        .map(|k| pipeline.align_words(&captured.raw_words(k)))
        .collect()
}

/// The repetitions' average, and what processing it uncorrected made of it.
struct Uncorrected {
    mean: Aligned,
    before: Processed,
    /// The records `mean` averages.
    averaged: usize,
}

fn uncorrected(pipeline: &mut Pipeline, aligned: &[Aligned]) -> Result<Uncorrected, MeasureError> {
    let mean = crate::measure::records::repeat::average(aligned).ok_or_else(|| {
        MeasureError::option("repetitions", 0, "at least 1 repetition with RF on")
    })?;
    let before = pipeline.process(mean.clone(), None)?;
    Ok(Uncorrected {
        mean,
        before,
        averaged: aligned.len(),
    })
}

/// The reference's figures in the repetitions' average, uncorrected and corrected with
/// `response`.
pub(crate) fn try_correction(
    pipeline: &mut Pipeline,
    response: &Response,
    aligned: &[Aligned],
    request: &CalibrateRequest,
) -> Result<ReferenceFigures, MeasureError> {
    let before = uncorrected(pipeline, aligned)?;
    corrected(pipeline, response, before, request)
}

/// [`try_correction`] once the average was processed uncorrected.
fn corrected(
    pipeline: &mut Pipeline,
    response: &Response,
    uncorrected: Uncorrected,
    request: &CalibrateRequest,
) -> Result<ReferenceFigures, MeasureError> {
    let Uncorrected {
        mean,
        before,
        averaged,
    } = uncorrected;
    let period = mean.samples.len();
    let fs = pipeline.transmission().sample_rate_hz();
    pipeline.set_equaliser(Some(response.equaliser(period, fs)?));
    let after = pipeline.process(mean, None)?;
    pipeline.set_equaliser(None);
    let range = request.reference_range_m;
    let (sb, wb, rb) = reference_of(&before, range);
    let (sa, wa, ra) = reference_of(&after, range);
    let phase_anchor = pipeline
        .phase_anchor(&after, range, request.reflector_m)
        .map(|a| PhaseAnchor {
            // Each record's trigger jitter is its own: their average's is sqrt(n) smaller.
            repetitions: Some(averaged),
            ..a
        });
    Ok(ReferenceFigures {
        sidelobe_db_before: sb,
        sidelobe_db_after: sa,
        width_cm_before: wb,
        width_cm_after: wa,
        range_m_before: rb,
        range_m_after: ra,
        phase_anchor,
    })
}
