//! One complete measurement on a bench: check everything checkable, connect, capture under the
//! safe-state guard, process through the [`Pipeline`] off the async runtime.
//!
//! Order, so that a measurement that was going to be refused never radiates: the transmission is
//! generated, the processing options checked, the instrument settings planned against the catalog,
//! then the pipeline is built (decimator, plans) while the instruments are connected and the
//! waveform uploaded (connecting sends no RF command, the upload leaves the outputs off); only
//! when both are done is RF switched on. A preparation that fails stops the measurement there,
//! the bench put in its safe state when the upload had begun. With a background (checked through the
//! pipeline) the pipeline is built and the background read and checked before any instrument is
//! connected: a file that does not fit is refused with nothing sent.

use super::bench::blocking::off_runtime;
use super::bench::in_use::Bench;
use super::bench::interrupt::Interrupt;
use super::bench::station::{self, CapturePlan, Captured, Identities, Station, Uploaded};
use super::error::MeasureError;
use super::processing::clipping::{RecordClipping, ScopeAdc};
use super::processing::options::ProcessOptions;
use super::processing::pipeline::{
    Alignable, Aligned, Pipeline, Processed, RawIq, RawWords, RecordGeometry,
};
use super::processing::transmit::{Dac, Transmission};
use super::records::repeat::{self, RepetitionResult, Spread};
use crate::catalog::Catalog;
use crate::driver::{Journal, RfPermit, SafeStateReport};
use crate::waveform::WaveformSpec;
use serde_json::Value;
use std::path::PathBuf;
use std::sync::Arc;

/// What to measure and how.
#[derive(Debug, Clone)]
pub struct CaptureRequest {
    pub waveform: WaveformSpec,
    /// Bytes to send (PRBS bits from `seed` when `None`).
    pub payload: Option<Vec<u8>>,
    pub seed: u64,
    pub options: ProcessOptions,
    pub tx_off: bool,
    /// Longest wait for the marker-triggered acquisition, seconds.
    pub wait_s: f64,
    /// An earlier capture (SigMF) to subtract before processing.
    pub background: Option<PathBuf>,
}

/// A finished capture, processed.
pub struct Measurement {
    /// The capture as taken, and the bench's safe state after it.
    pub taken: Taken,
    /// What the pipeline made of it.
    pub processing: Processing,
}

/// A background capture as used: where it is and what it held.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct BackgroundFile {
    pub path: PathBuf,
    pub sha256: String,
}

impl Measurement {
    /// Samples of one repetition at the waveform rate.
    pub fn period(&self) -> usize {
        self.taken.plan.period
    }
}

/// Everything prepared before the bench is touched.
pub struct Prepared {
    pub tx: Arc<Transmission>,
    pub plan: CapturePlan,
    /// `None` only while a worker thread processes with it.
    pipeline: Option<Pipeline>,
    pub background: Option<Aligned>,
    /// The background's file, for the records.
    pub background_file: Option<BackgroundFile>,
}

impl Prepared {
    /// Another preparation of the same transmission and capture plan, processed with `options`
    /// (a campaign applies several algorithms to the same captures). Touches no instrument. The
    /// capture plan was checked against this preparation's options: `options` must keep its
    /// range window.
    pub(crate) async fn with_options(
        &self,
        options: ProcessOptions,
    ) -> Result<Prepared, MeasureError> {
        super::processing::pipeline::validate(&self.tx, &options)?;
        let fs = self.tx.sample_rate_hz();
        let geometry = RecordGeometry::for_capture(self.plan.period, fs, &options);
        let rate = self.plan.scope.sample_rate_hz;
        let tx = self.tx.clone();
        let pipeline = off_runtime(move || {
            let mut pipeline = Pipeline::new(tx, options, geometry)?;
            pipeline.prepare_capture_rate(rate)?;
            Ok::<_, MeasureError>(pipeline)
        })
        .await??;
        Ok(Prepared {
            tx: self.tx.clone(),
            plan: self.plan.clone(),
            pipeline: Some(pipeline),
            background: self.background.clone(),
            background_file: self.background_file.clone(),
        })
    }

    /// The options a capture of `captured` is processed with (this preparation's, with the
    /// AWG amplitude the instrument applied), known before it is processed: the raw files
    /// record them while the capture is processed.
    pub(crate) fn options_for(&self, captured: &Captured) -> ProcessOptions {
        let mut options = self.pipeline().options().clone();
        options.awg_amplitude_vpp = Some(captured.applied.awg.i_amplitude_vpp);
        options
    }

    /// The pipeline captures of this preparation go through.
    pub fn pipeline(&self) -> &Pipeline {
        self.pipeline
            .as_ref()
            .expect("the pipeline is back from its worker")
    }
}

/// Generates the waveform, checks every option, plans the instruments, reads the background and
/// builds the pipeline. Touches no instrument.
pub async fn prepare(
    bench: &Bench,
    catalog: &Catalog,
    request: &CaptureRequest,
) -> Result<Prepared, MeasureError> {
    let planned = plan_request(bench, catalog, request).await?;
    let built = build_pipeline(&planned, request).await?;
    Ok(planned.with(built))
}

/// The part of [`prepare`] before the pipeline: the transmission generated (pre-distorted as the
/// correction asks), the options checked against it, the instruments planned against the
/// catalog. Touches no instrument.
pub(crate) struct Planned {
    tx: Arc<Transmission>,
    plan: CapturePlan,
}

/// The part of [`prepare`] that takes the time: the pipeline (decimation filter, FFT plans,
/// detector tables) and the background read, aligned and hashed.
pub(crate) struct Built {
    pipeline: Pipeline,
    background: Option<Aligned>,
    background_file: Option<BackgroundFile>,
}

impl Planned {
    fn with(self, built: Built) -> Prepared {
        Prepared {
            tx: self.tx,
            plan: self.plan,
            pipeline: Some(built.pipeline),
            background: built.background,
            background_file: built.background_file,
        }
    }
}

/// [`prepare`] up to the pipeline (see [`Planned`]).
pub(crate) async fn plan_request(
    bench: &Bench,
    catalog: &Catalog,
    request: &CaptureRequest,
) -> Result<Planned, MeasureError> {
    plan_generated(bench, catalog, request, None).await
}

/// A request's transmission (its waveform, payload and seed, before any correction), generated
/// on a blocking thread from the moment it is started: `radbench capture` starts it before the
/// bench file is read, and [`take`] waits for it. It touches no instrument; its errors are
/// reported where generating would have reported them, after the bench file's.
pub struct Generation {
    key: (WaveformSpec, Option<Vec<u8>>, u64),
    work: tokio::task::JoinHandle<Result<Transmission, MeasureError>>,
}

impl Generation {
    /// Starts generating the transmission of a request's `waveform`, `payload` and `seed`.
    pub fn start(waveform: WaveformSpec, payload: Option<Vec<u8>>, seed: u64) -> Generation {
        let key = (waveform, payload, seed);
        let (spec, payload, seed) = key.clone();
        let work = tokio::task::spawn_blocking(move || {
            Transmission::new(&spec, payload.as_deref(), seed, Dac::default())
        });
        Generation { key, work }
    }

    /// The transmission, if it was started for `request`'s waveform, payload and seed.
    async fn of(self, request: &CaptureRequest) -> Option<Result<Transmission, MeasureError>> {
        let (spec, payload, seed) = &self.key;
        if *spec != request.waveform || *payload != request.payload || *seed != request.seed {
            self.work.abort();
            return None;
        }
        Some(
            self.work
                .await
                .map_err(|e| MeasureError::Worker(e.to_string()))
                .and_then(|tx| tx),
        )
    }
}

/// [`plan_request`] with the transmission from `generation` when it was started for `request`.
async fn plan_generated(
    bench: &Bench,
    catalog: &Catalog,
    request: &CaptureRequest,
    generation: Option<Generation>,
) -> Result<Planned, MeasureError> {
    let generated = match generation {
        Some(g) => g.of(request).await,
        None => None,
    };
    let tx = match generated {
        Some(tx) => tx?,
        None => {
            let spec = request.waveform;
            let payload = request.payload.clone();
            let seed = request.seed;
            off_runtime(move || Transmission::new(&spec, payload.as_deref(), seed, Dac::default()))
                .await??
        }
    };
    // Pre-distorted for the chain's response when the correction asks (before the instruments
    // are planned: the catalog's limits are checked on the codes that will play).
    let tx = Arc::new(tx.with_correction(&request.options)?);
    super::processing::pipeline::validate(&tx, &request.options)?;
    let plan = station::plan(
        &bench.file,
        catalog,
        &tx,
        &request.options,
        request.tx_off,
        request.wait_s,
    )?;
    Ok(Planned { tx, plan })
}

/// The rest of [`prepare`] (see [`Built`]), off the runtime. Touches no instrument.
pub(crate) async fn build_pipeline(
    planned: &Planned,
    request: &CaptureRequest,
) -> Result<Built, MeasureError> {
    let options = request.options.clone();
    let background = request.background.clone();
    let fs = planned.tx.sample_rate_hz();
    let rate = planned.plan.scope.sample_rate_hz;
    let geometry = RecordGeometry::for_capture(planned.plan.period, fs, &options);
    let tx2 = planned.tx.clone();
    off_runtime(move || {
        let mut pipeline = Pipeline::new(tx2, options, geometry)?;
        pipeline.prepare_capture_rate(rate)?;
        let (background, file) = match background {
            Some(path) => {
                let aligned = read_background(&mut pipeline, &path, rate)?;
                let data = crate::storage::recording::sigmf_paths(&path)?.1;
                let sha256 = crate::storage::hash::sha256_file(&data)?;
                // Recorded absolute, so the capture can be re-processed from anywhere.
                let path = std::fs::canonicalize(&path).unwrap_or(path);
                (Some(aligned), Some(BackgroundFile { path, sha256 }))
            }
            None => (None, None),
        };
        Ok::<_, MeasureError>(Built {
            pipeline,
            background,
            background_file: file,
        })
    })
    .await?
}

/// Reads and aligns a background capture, checking that it fits this measurement.
pub(crate) fn read_background(
    pipeline: &mut Pipeline,
    path: &std::path::Path,
    capture_rate_hz: f64,
) -> Result<Aligned, MeasureError> {
    use crate::storage::{read_sigmf, SampleUnit};
    let rec = read_sigmf(path)?;
    let first_point_s = rec.radbench.as_ref().and_then(|r| r.trigger_offset_s);
    let (Some(rate), SampleUnit::Volts, Some(first_point_s)) =
        (rec.sample_rate_hz, rec.unit, first_point_s)
    else {
        return Err(MeasureError::option(
            "background",
            path.display(),
            "a capture radbench wrote (core:sample_rate, radbench:vertical_gain/offset and \
             radbench:trigger_offset_s give its volts and its timing)",
        ));
    };
    if (rate - capture_rate_hz).abs() > 1e-6 * capture_rate_hz {
        return Err(MeasureError::option(
            "background",
            path.display(),
            format!(
                "a capture at this bench's rate of {capture_rate_hz} Sa/s; this one was taken \
                 at {rate} Sa/s"
            ),
        ));
    }
    // The background must be of the same waveform: the same parameters (and bits, so the same
    // seed or payload: checked through the sample count of one repetition below).
    let meta = rec.radbench.as_ref().map(|r| &r.keys);
    let spec = meta
        .and_then(|k| k.get("waveform"))
        .and_then(|w| w.get("spec"))
        .and_then(|s| serde_json::from_value::<WaveformSpec>(s.clone()).ok());
    let ours = pipeline.transmission().spec;
    if let Some(theirs) = spec {
        if theirs != ours {
            return Err(MeasureError::option(
                "background",
                path.display(),
                format!(
                    "a capture of the same waveform; {}",
                    waveform_difference(&theirs, &ours)
                ),
            ));
        }
    }
    // Several repetitions follow each other in the file: the first one is the background.
    let first_count = meta
        .and_then(|k| k.get("repetitions"))
        .and_then(|r| r.get(0))
        .and_then(|r| r.get("sample_count"))
        .and_then(serde_json::Value::as_u64)
        .map_or(rec.samples.len(), |n| (n as usize).min(rec.samples.len()));
    let mut samples = rec.samples;
    samples.truncate(first_count);
    let raw = RawIq {
        samples,
        sample_rate_hz: rate,
        first_point_s,
    };
    pipeline.align(&raw).map_err(|e| match e {
        MeasureError::RecordTooShort { points, needed } => MeasureError::option(
            "background",
            path.display(),
            format!(
                "a capture of the same waveform ({needed} points per repetition); this one holds \
                 {points}"
            ),
        ),
        other => other,
    })
}

/// The connected bench, kept across the measurements of a campaign: the waveform is uploaded
/// once and again only when it changes or the AWG lost it.
pub struct Rig {
    station: Station,
    /// The transmission the AWG holds and what the upload left.
    loaded: Option<(Arc<Transmission>, Uploaded)>,
    /// `loaded` was uploaded by [`Rig::upload_ahead`] for the next measurement, in this process
    /// and with nothing in between: used as it is, not read back from the AWG first.
    fresh: bool,
}

impl Rig {
    /// Connects every instrument of the bench and arms the panic hook's safe state.
    pub async fn connect(
        bench: &Bench,
        catalog: &Catalog,
        journal: Option<Journal>,
    ) -> Result<Rig, MeasureError> {
        let station = Station::connect(&bench.file, catalog, journal).await?;
        station.install_panic_hook();
        Ok(Rig {
            station,
            loaded: None,
            fresh: false,
        })
    }

    /// Forgets what the AWG holds: the next measurement uploads (and configures the AWG and
    /// scope) again; a campaign step that changes the AWG amplitude or V/div asks for it.
    pub(crate) fn forget_upload(&mut self) {
        self.loaded = None;
        self.fresh = false;
    }

    /// Uploads `tx` for the next measurement (AWG configured and loaded with its outputs left
    /// off, scope configured for `segments` triggers per acquisition): nothing radiates. On a
    /// failure, or when `interrupt` fires first, the bench is put in its safe state (as the
    /// capture's guard does) and the error returned.
    pub(crate) async fn upload_ahead(
        &mut self,
        tx: &Arc<Transmission>,
        plan: &CapturePlan,
        segments: u32,
        interrupt: &Interrupt,
    ) -> Result<(), MeasureError> {
        self.loaded = None;
        self.fresh = false;
        let outcome = tokio::select! {
            up = self.station.upload(tx, plan, segments) => Some(up),
            _ = interrupt.wait() => None,
        };
        match outcome {
            Some(Ok(up)) => {
                self.loaded = Some((tx.clone(), up));
                self.fresh = true;
                Ok(())
            }
            Some(Err(e)) => {
                self.engage_safe_state().await;
                Err(e)
            }
            None => {
                let report = self.engage_safe_state().await;
                Err(MeasureError::Interrupted {
                    signal: interrupt
                        .received()
                        .unwrap_or(super::bench::interrupt::StopSignal::Interrupt),
                    report: report.to_string(),
                })
            }
        }
    }

    /// Runs the bench's safe-state sequence now, warning when it did not complete.
    pub(crate) async fn engage_safe_state(&mut self) -> SafeStateReport {
        self.loaded = None;
        self.fresh = false;
        let report = self.station.safe_state().engage().await;
        if !report.is_safe() {
            eprintln!(
                "WARNING: the safe state did not complete: {report}; switch the bench off by hand"
            );
        }
        report
    }

    pub fn identities(&self) -> &Identities {
        &self.station.identities
    }

    /// The bench's safe-state sequence.
    pub fn safe_state(&self) -> &crate::driver::SafeState {
        self.station.safe_state()
    }

    /// One measurement of `repetitions` marker-triggered repetitions under the safe-state guard,
    /// processed through the prepared pipeline off the runtime: each repetition alone, and their
    /// coherent average as the result.
    pub async fn measure(
        &mut self,
        bench: &Bench,
        prepared: &mut Prepared,
        repetitions: usize,
        permit: &RfPermit,
        interrupt: &Interrupt,
    ) -> Result<Measurement, MeasureError> {
        self.acquire(bench, prepared, repetitions, permit, interrupt)
            .await?
            .processed(prepared)
            .await
    }

    /// The bench part of [`Rig::measure`]: `repetitions` marker-triggered repetitions under the
    /// safe-state guard, not processed. A campaign processes a step's capture on a thread of its
    /// own while the next step is captured.
    pub async fn acquire(
        &mut self,
        bench: &Bench,
        prepared: &Prepared,
        repetitions: usize,
        permit: &RfPermit,
        interrupt: &Interrupt,
    ) -> Result<Taken, MeasureError> {
        check_repetitions(repetitions)?;
        check_manual_confirmed(bench, permit)?;
        let fresh = std::mem::take(&mut self.fresh);
        let loaded = self
            .loaded
            .as_ref()
            .filter(|(tx, _)| Arc::ptr_eq(tx, &prepared.tx))
            .map(|(_, up)| up);
        let (result, report) = self
            .station
            .capture(
                &prepared.tx,
                &prepared.plan,
                loaded,
                fresh,
                repetitions,
                permit,
                interrupt,
            )
            .await;
        if !report.is_safe() {
            eprintln!(
                "WARNING: the safe state did not complete: {report}; switch the bench off by hand"
            );
        }
        let captured = match result {
            Ok(c) => c,
            Err(e) => {
                // Whatever the AWG holds now is unknown: upload again next time.
                self.loaded = None;
                return Err(e);
            }
        };
        self.loaded = Some((prepared.tx.clone(), captured.uploaded.clone()));
        let ground_truth = bench.ground_truth().await;
        Ok(Taken {
            bench_warnings: bench.file.uncalibrated_warning().into_iter().collect(),
            tx: prepared.tx.clone(),
            plan: prepared.plan.clone(),
            captured,
            identities: self.station.identities.clone(),
            ground_truth,
            safe_state: report,
            background: prepared.background_file.clone(),
        })
    }
}

/// A capture taken and the bench back in its safe state, not processed yet.
pub struct Taken {
    pub tx: Arc<Transmission>,
    pub plan: CapturePlan,
    /// Every repetition's raw capture.
    pub captured: Captured,
    pub identities: Identities,
    /// The simulated scene of this capture (ground truth), on a simulated bench.
    pub ground_truth: Option<Value>,
    pub safe_state: SafeStateReport,
    /// The background subtracted, if any: its file and SHA-256.
    pub background: Option<BackgroundFile>,
    /// What every output of this capture must say about the bench (it is not calibrated).
    pub(crate) bench_warnings: Vec<String>,
}

impl Taken {
    /// This capture processed through `prepared` ([`process_with`]), as a measurement
    /// ([`measure`], [`Rig::measure`]: nothing written). The recorder (`records::recorder`)
    /// processes a capture while it writes its raw files.
    async fn processed(self, prepared: &mut Prepared) -> Result<Measurement, MeasureError> {
        let processing = process_with(prepared, &self.captured).await?;
        Ok(self.with(processing))
    }

    /// The measurement, with what a pipeline made of this capture.
    pub fn with(self, mut processing: Processing) -> Measurement {
        // The bench's first: they qualify every figure after them.
        let own = std::mem::take(&mut processing.processed.warnings);
        processing.processed.warnings = self.bench_warnings.clone();
        processing.processed.warnings.extend(own);
        if let Some(truth) = &self.ground_truth {
            let o = &processing.options;
            let outside: Vec<String> = truth["targets"]
                .as_array()
                .into_iter()
                .flatten()
                .filter_map(|t| t["range_m"].as_f64())
                .filter(|r| *r < o.min_range_m || *r > o.max_range_m)
                .map(|r| format!("{r:.3} m"))
                .collect();
            if !outside.is_empty() {
                processing.processed.warnings.push(format!(
                    "the simulated scene has a target at {} outside the range window \
                     {:.2}..{:.2} m, which is not searched: widen --min-range/--max-range to see it",
                    outside.join(", "),
                    o.min_range_m,
                    o.max_range_m
                ));
            }
        }
        Measurement {
            taken: self,
            processing,
        }
    }
}

/// What one pipeline made of a capture.
pub struct Processing {
    /// The coherent average of the repetitions (or the one repetition), processed.
    pub processed: Processed,
    /// Each repetition processed alone (empty for a single repetition).
    pub repetitions: Vec<RepetitionResult>,
    /// The repetitions' spread around the result (several repetitions only).
    pub spread: Option<Spread>,
    /// The options as used (with the AWG amplitude the instrument applied).
    pub options: ProcessOptions,
}

/// Processes a capture through `prepared`'s pipeline, off the runtime: each repetition alone and
/// their coherent average. [`Rig::measure`] does this for its own capture, the recorder
/// (`records::recorder`) while it writes the raw capture.
pub(crate) async fn process_with(
    prepared: &mut Prepared,
    captured: &Captured,
) -> Result<Processing, MeasureError> {
    let mut lent = prepared.lend()?;
    let raws = captured_raws(captured);
    let amplitude = captured.applied.awg.i_amplitude_vpp;
    // The pipeline goes to the worker thread and comes back.
    let (lent, outcome) = off_runtime(move || {
        let outcome = lent.process_raws(amplitude, &raws);
        (lent, outcome)
    })
    .await?;
    prepared.give_back(lent);
    outcome
}

/// A preparation's pipeline (and background), lent to a thread that processes with it.
pub(crate) struct LentPipeline {
    pipeline: Pipeline,
    background: Option<Aligned>,
    bandwidth_hz: f64,
    /// The scope's ADC and vertical scale as planned.
    adc: ScopeAdc,
}

impl LentPipeline {
    /// A campaign's previous step for the captures processed next (`ranging::Previous`).
    pub(crate) fn set_previous_step(
        &mut self,
        previous: Vec<super::processing::ranging::Previous>,
    ) {
        self.pipeline.set_previous_step(previous);
    }

    /// The calibration's record as the step before a campaign's first (`ranging::Previous`).
    pub(crate) fn calibration_as_previous(
        &self,
        set: &[f64],
    ) -> Vec<super::processing::ranging::Previous> {
        self.pipeline.calibration_as_previous(set)
    }

    /// Processes `captured` (see [`process_with`]) on the calling thread.
    pub(crate) fn process(&mut self, captured: &Captured) -> Result<Processing, MeasureError> {
        let raws = captured_raws(captured);
        self.process_raws(captured.applied.awg.i_amplitude_vpp, &raws)
    }

    /// Processes the scope's words of every repetition, their samples at the ADC's rails
    /// counted.
    fn process_raws(
        &mut self,
        awg_amplitude_vpp: f64,
        raws: &[RawWords],
    ) -> Result<Processing, MeasureError> {
        self.pipeline.set_awg_amplitude(awg_amplitude_vpp)?;
        let clipped: Vec<Option<RecordClipping>> =
            raws.iter().map(|r| Some(r.clipping(&self.adc))).collect();
        let (processed, repetitions, spread) = process_repetitions(
            &mut self.pipeline,
            raws,
            self.background.as_ref(),
            self.bandwidth_hz,
            &clipped,
        )?;
        Ok(Processing {
            processed,
            repetitions,
            spread,
            options: self.pipeline.options().clone(),
        })
    }
}

impl Prepared {
    /// Lends this preparation's pipeline to a worker; [`Prepared::give_back`] returns it.
    pub(crate) fn lend(&mut self) -> Result<LentPipeline, MeasureError> {
        let pipeline = self.pipeline.take().ok_or_else(|| {
            MeasureError::Worker("an earlier measurement lost the pipeline".into())
        })?;
        Ok(LentPipeline {
            pipeline,
            background: self.background.take(),
            bandwidth_hz: self.tx.bandwidth_hz(),
            adc: self.plan.scope_adc(),
        })
    }

    /// Takes back what [`Prepared::lend`] lent.
    pub(crate) fn give_back(&mut self, lent: LentPipeline) {
        self.pipeline = Some(lent.pipeline);
        self.background = lent.background;
    }
}

fn captured_raws(captured: &Captured) -> Vec<RawWords> {
    (0..captured.repetitions())
        .map(|k| captured.raw_words(k))
        .collect()
}

/// Most repetitions one measurement takes.
pub(crate) const MAX_REPETITIONS: usize = 1000;

/// Aligns every repetition (raw captures at the capture rate), processes each alone (when there
/// are several) and their coherent average. `clipped` holds each repetition's samples at the
/// ADC's rails when they were counted (one entry per repetition, or none): each repetition is
/// processed with its own, the average with the total (clipping distortion is the same in every
/// repetition, so averaging does not lower it).
pub(crate) fn process_repetitions<R: Alignable>(
    pipeline: &mut Pipeline,
    raws: &[R],
    background: Option<&Aligned>,
    bandwidth_hz: f64,
    clipped: &[Option<RecordClipping>],
) -> Result<(Processed, Vec<RepetitionResult>, Option<Spread>), MeasureError> {
    // A recording can name no repetition at all (an empty `.trc` sequence): refused, not averaged.
    if raws.is_empty() {
        return Err(MeasureError::RecordTooShort {
            points: 0,
            needed: pipeline.geometry().period,
        });
    }
    let clipped: Vec<Option<RecordClipping>> = (0..raws.len())
        .map(|k| clipped.get(k).copied().flatten())
        .collect();
    let aligned = raws
        .iter()
        .map(|r| r.align_in(pipeline))
        .collect::<Result<Vec<_>, _>>()?;
    if aligned.len() == 1 {
        let one = aligned.into_iter().next().expect("one repetition");
        let processed = pipeline.process_clipped(one, background, clipped[0].as_ref())?;
        return Ok((processed, Vec::new(), None));
    }
    let total = clipped
        .iter()
        .copied()
        .collect::<Option<Vec<_>>>()
        .and_then(|all| RecordClipping::total(&all));
    let mean = repeat::average(&aligned).expect("at least one repetition");
    let mut each = Vec::with_capacity(aligned.len());
    for (a, c) in aligned.into_iter().zip(&clipped) {
        each.push(RepetitionResult::from(&pipeline.process_clipped(
            a,
            background,
            c.as_ref(),
        )?));
    }
    let processed = pipeline.process_clipped(mean, background, total.as_ref())?;
    let tolerance = crate::physics::C0 / (4.0 * bandwidth_hz);
    let spread = repeat::spread(&processed.targets, &each, tolerance);
    Ok((processed, each, Some(spread)))
}

/// Refuses `permit` on a bench with manual front ends unless the operator's confirmation is in
/// it ([`RfPermit::with_manual_front_ends_confirmed`]): checked by every library entry point that
/// radiates, before anything is sent, so that the command line's prompt is not the only guard.
pub(crate) fn check_manual_confirmed(bench: &Bench, permit: &RfPermit) -> Result<(), MeasureError> {
    if bench.file.manual.is_empty() || permit.manual_front_ends_confirmed() {
        return Ok(());
    }
    Err(MeasureError::ManualNotConfirmed {
        names: super::bench::manual::names(&bench.file.manual),
    })
}

/// [`prepare`], connect, one measurement of `repetitions`.
pub async fn measure(
    bench: &Bench,
    request: &CaptureRequest,
    repetitions: usize,
    permit: &RfPermit,
    journal: Option<Journal>,
    interrupt: &Interrupt,
) -> Result<Measurement, MeasureError> {
    let (taken, mut prepared) = take(
        bench,
        request,
        None,
        repetitions,
        permit,
        journal,
        interrupt,
    )
    .await?;
    taken.processed(&mut prepared).await
}

/// [`measure`] up to the capture: taken, the bench back in its safe state, not processed yet,
/// with the preparation that processes it. `radbench capture` records it
/// ([`Recorder::record`](crate::measure::Recorder::record)): the raw capture written while it is
/// processed, so that a capture whose processing fails is still kept.
/// `generation`: the request's transmission, started earlier ([`Generation::start`]).
pub async fn take(
    bench: &Bench,
    request: &CaptureRequest,
    generation: Option<Generation>,
    repetitions: usize,
    permit: &RfPermit,
    journal: Option<Journal>,
    interrupt: &Interrupt,
) -> Result<(Taken, Prepared), MeasureError> {
    check_repetitions(repetitions)?;
    // Before anything is sent (the upload included).
    check_manual_confirmed(bench, permit)?;
    let catalog = bench.file.catalog()?;
    let planned = plan_generated(bench, &catalog, request, generation).await?;
    let (built, mut rig) = if request.background.is_some() {
        // A background is read and checked against this measurement before any instrument is
        // talked to: a file that does not fit is bad input, refused with nothing sent.
        let built = build_pipeline(&planned, request).await?;
        (built, Rig::connect(bench, &catalog, journal).await?)
    } else {
        let segments = planned.plan.sequence_segments(repetitions);
        build_while_uploading(
            build_pipeline(&planned, request),
            Rig::connect(bench, &catalog, journal),
            &planned.tx,
            &planned.plan,
            segments,
            interrupt,
        )
        .await?
    };
    let prepared = planned.with(built);
    // RF goes on in here, only now that every check has passed and the pipeline is built.
    let taken = rig
        .acquire(bench, &prepared, repetitions, permit, interrupt)
        .await?;
    Ok((taken, prepared))
}

/// [`prepare`] on a connected rig, as [`take`] prepares a one-shot capture: the waveform is
/// uploaded while the pipeline is built (a warm session's first capture of a request). Without
/// a rig, or with a background (checked before anything is sent), the pipeline alone is built.
/// When the upload or the build fails after the upload began, the rig is gone (`None`: its
/// connections dropped, the bench in its safe state as [`build_while_uploading`] leaves it).
pub(crate) async fn prepare_uploading(
    bench: &Bench,
    catalog: &Catalog,
    request: &CaptureRequest,
    rig: &mut Option<Rig>,
    repetitions: usize,
    interrupt: &Interrupt,
) -> Result<Prepared, MeasureError> {
    let planned = plan_request(bench, catalog, request).await?;
    match rig.take() {
        Some(connected) if request.background.is_none() => {
            let segments = planned.plan.sequence_segments(repetitions);
            let (built, connected) = build_while_uploading(
                build_pipeline(&planned, request),
                async { Ok(connected) },
                &planned.tx,
                &planned.plan,
                segments,
                interrupt,
            )
            .await?;
            *rig = Some(connected);
            Ok(planned.with(built))
        }
        other => {
            *rig = other;
            let built = build_pipeline(&planned, request).await?;
            Ok(planned.with(built))
        }
    }
}

/// Connects, then uploads the waveform, while the pipeline is built: the instruments' round
/// trips and the pipeline's computing overlap. Nothing here radiates: connecting sends no RF
/// command, the upload configures the AWG and the scope with the outputs left off, and RF goes
/// on only in [`Rig::acquire`], after this has returned with the pipeline built.
///
/// The preparation's error wins, as when it came first: a refused preparation is reported at
/// once while the instruments connect (the connection is dropped half-way, nothing uploaded); a
/// failed connection waits for the preparation. A preparation that fails while (or after) the
/// waveform is uploaded waits for the upload to end, then puts the bench in its safe state
/// (outputs off, AWG stopped, Tx and Rx off) before it is reported. A failed or interrupted
/// upload puts the bench in its safe state at once, as inside the capture's guard.
pub(crate) async fn build_while_uploading<B>(
    building: impl std::future::Future<Output = Result<B, MeasureError>>,
    connecting: impl std::future::Future<Output = Result<Rig, MeasureError>>,
    tx: &Arc<Transmission>,
    plan: &CapturePlan,
    segments: u32,
    interrupt: &Interrupt,
) -> Result<(B, Rig), MeasureError> {
    tokio::pin!(building);
    tokio::pin!(connecting);
    let mut rig = tokio::select! {
        built = &mut building => {
            // Built before the instruments answered: the upload goes on in the capture's guard.
            let built = built?;
            return Ok((built, connecting.await?));
        }
        connected = &mut connecting => match connected {
            Ok(rig) => rig,
            Err(e) => {
                building.await?;
                return Err(e);
            }
        },
    };
    let (built, uploaded) = tokio::join!(building, rig.upload_ahead(tx, plan, segments, interrupt));
    match (built, uploaded) {
        (Ok(built), Ok(())) => Ok((built, rig)),
        (Ok(_), Err(e)) => Err(e),
        (Err(e), uploaded) => {
            if uploaded.is_ok() {
                // The AWG and scope are set up but nothing was switched on: leave the bench in
                // its safe state all the same, as after any failed measurement.
                rig.engage_safe_state().await;
            }
            Err(e)
        }
    }
}

/// The number of repetitions one measurement may ask for (checked before anything is connected).
pub fn check_repetitions(repetitions: usize) -> Result<(), MeasureError> {
    if (1..=MAX_REPETITIONS).contains(&repetitions) {
        Ok(())
    } else {
        Err(MeasureError::option(
            "repetitions",
            repetitions,
            format!("1..={MAX_REPETITIONS}"),
        ))
    }
}

/// How a background's waveform differs from this capture's, in the parameters' own names.
fn waveform_difference(theirs: &WaveformSpec, ours: &WaveformSpec) -> String {
    if theirs.name() != ours.name() {
        return format!(
            "it holds {}, this capture sends {}",
            theirs.name(),
            ours.name()
        );
    }
    let fields = |spec: &WaveformSpec| match serde_json::to_value(spec) {
        Ok(serde_json::Value::Object(map)) => map,
        _ => serde_json::Map::new(),
    };
    let (a, b) = (fields(theirs), fields(ours));
    let differing: Vec<String> = a
        .iter()
        .filter(|(k, v)| b.get(*k) != Some(*v))
        .map(|(k, v)| {
            let here = b.get(k).map_or("-".to_string(), ToString::to_string);
            format!("{k} {v} there, {here} here")
        })
        .collect();
    format!("its {} differs: {}", theirs.name(), differing.join("; "))
}

#[cfg(test)]
mod tests {
    use super::process_repetitions;
    use crate::measure::{
        Dac, MeasureError, Pipeline, ProcessOptions, RawIq, RecordGeometry, Transmission,
    };
    use crate::waveform::WaveformSpec;

    /// The upload goes on while the pipeline is built; a preparation that fails after the upload
    /// began is reported, and the bench ends in its safe state with nothing ever switched on.
    #[tokio::test(flavor = "multi_thread", worker_threads = 2)]
    async fn a_preparation_failing_during_the_upload_leaves_the_bench_safe_never_radiating() {
        use super::{build_while_uploading, plan_request, CaptureRequest, Rig};
        use crate::measure::{Bench, BenchSource, BuiltIn, Interrupt};
        use std::time::Duration;
        let bench = Bench::open(BenchSource::BuiltIn(Box::<BuiltIn>::default()))
            .await
            .unwrap();
        let lab = &bench.lab.as_ref().unwrap().bench;
        let catalog = bench.file.catalog().unwrap();
        let kind = crate::waveform::WaveformKind::MskLfm;
        let request = CaptureRequest {
            waveform: kind.thesis_default(),
            payload: None,
            seed: 1,
            options: ProcessOptions::for_waveform(kind),
            tx_off: false,
            wait_s: 10.0,
            background: None,
        };
        let planned = plan_request(&bench, &catalog, &request).await.unwrap();
        let uploading = || {
            lab.awg
                .log()
                .texts()
                .iter()
                .any(|t| t.contains(":TRAC1:DEF"))
        };
        // The preparation fails once the AWG has been told to define the waveform's segment.
        let failing = async {
            let began = async {
                while !uploading() {
                    tokio::time::sleep(Duration::from_millis(1)).await;
                }
            };
            tokio::time::timeout(Duration::from_secs(30), began)
                .await
                .expect("the upload began within 30 s");
            Err::<(), _>(MeasureError::Worker("the preparation failed".into()))
        };
        let err = build_while_uploading(
            failing,
            Rig::connect(&bench, &catalog, None),
            &planned.tx,
            &planned.plan,
            planned.plan.sequence_segments(1),
            &Interrupt::never(),
        )
        .await
        .err()
        .expect("the preparation's failure is reported");
        assert!(
            matches!(&err, MeasureError::Worker(m) if m == "the preparation failed"),
            "{err}"
        );
        assert!(uploading(), "the upload had begun");
        assert!(lab.is_safe(), "outputs off, AWG stopped, Tx off");
        let awg = lab.awg.log().texts();
        let commands: Vec<&str> = awg
            .iter()
            .flat_map(|t| t.split(';'))
            .map(str::trim)
            .collect();
        assert!(
            !commands
                .iter()
                .any(|c| c.contains("OUTP") && c.ends_with(" ON")),
            "an AWG output was switched on: {awg:?}"
        );
        assert!(
            commands.iter().any(|c| c.contains("OUTP1 OFF")),
            "the safe state ran after the upload: {awg:?}"
        );
        for (name, front) in [("tx", &lab.tx), ("rx", &lab.rx)] {
            assert!(!front.front_end().rf_enabled, "{name} off");
            let writes: Vec<String> = front
                .log()
                .texts()
                .into_iter()
                .filter(|t| t.starts_with("W 02"))
                .collect();
            assert!(
                writes.iter().all(|t| t.starts_with("W 02 0000")),
                "{name} was enabled: {writes:?}"
            );
        }
    }

    #[test]
    fn a_capture_without_repetitions_is_refused_not_averaged() {
        let spec = WaveformSpec::msk_lfm_default();
        let tx = std::sync::Arc::new(Transmission::new(&spec, None, 1, Dac::default()).unwrap());
        let options = ProcessOptions::for_waveform(spec.kind());
        let geometry = RecordGeometry::for_capture(tx.len(), tx.sample_rate_hz(), &options);
        let mut p = Pipeline::new(tx.clone(), options, geometry).unwrap();
        let none: [RawIq; 0] = [];
        let err = process_repetitions(&mut p, &none, None, tx.bandwidth_hz(), &[]).unwrap_err();
        assert!(
            matches!(err, MeasureError::RecordTooShort { points: 0, needed } if needed == geometry.period),
            "{err}"
        );
    }
}
