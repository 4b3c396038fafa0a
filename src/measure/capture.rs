//! One complete measurement on a bench: check everything checkable, connect, capture under the
//! safe-state guard, process through the [`Pipeline`] off the async runtime.
//!
//! Order, so that a measurement that was going to be refused never radiates: the transmission is
//! generated, the processing options checked, the instrument settings planned against the catalog,
//! the background read and checked, the pipeline built (decimator, plans); only then are the
//! instruments connected and RF switched on.

use super::bench::Bench;
use super::interrupt::Interrupt;
use super::options::ProcessOptions;
use super::pipeline::{Aligned, Pipeline, Processed, RawIq, RecordGeometry};
use super::station::{self, CapturePlan, Captured, Identities, Station};
use super::transmit::{Dac, Transmission};
use super::{off_runtime, MeasureError};
use crate::catalog::Catalog;
use crate::driver::{Journal, RfPermit, SafeStateReport};
use crate::waveform::spec::WaveformSpec;
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
    pub tx: Arc<Transmission>,
    pub plan: CapturePlan,
    pub captured: Captured,
    pub processed: Processed,
    /// The options as used (with the AWG amplitude the instrument applied).
    pub options: ProcessOptions,
    pub identities: Identities,
    /// The simulated scene of this capture (ground truth), on a simulated bench.
    pub ground_truth: Option<Value>,
    pub safe_state: SafeStateReport,
}

impl Measurement {
    /// Samples of one repetition at the waveform rate.
    pub fn period(&self) -> usize {
        self.plan.period
    }
}

/// Everything prepared before the bench is touched.
pub struct Prepared {
    pub tx: Arc<Transmission>,
    pub plan: CapturePlan,
    pub pipeline: Pipeline,
    pub background: Option<Aligned>,
}

/// Generates the waveform, checks every option, plans the instruments, reads the background and
/// builds the pipeline. Touches no instrument.
pub async fn prepare(
    bench: &Bench,
    catalog: &Catalog,
    request: &CaptureRequest,
) -> Result<Prepared, MeasureError> {
    let spec = request.waveform;
    let payload = request.payload.clone();
    let seed = request.seed;
    let tx = off_runtime(move || {
        Transmission::new(&spec, payload.as_deref(), seed, Dac::default()).map(Arc::new)
    })
    .await??;
    super::pipeline::validate(&tx, &request.options)?;
    let plan = station::plan(
        &bench.file,
        catalog,
        &tx,
        &request.options,
        request.tx_off,
        request.wait_s,
    )?;
    let options = request.options.clone();
    let background = request.background.clone();
    let fs = tx.sample_rate_hz();
    let rate = plan.scope.sample_rate_hz;
    let geometry = RecordGeometry::for_capture(plan.period, fs, &options);
    let tx2 = tx.clone();
    let (pipeline, background) = off_runtime(move || {
        let mut pipeline = Pipeline::new(tx2, options, geometry)?;
        pipeline.prepare_capture_rate(rate)?;
        let background = match background {
            Some(path) => Some(read_background(&mut pipeline, &path, rate)?),
            None => None,
        };
        Ok::<_, MeasureError>((pipeline, background))
    })
    .await??;
    Ok(Prepared {
        tx,
        plan,
        pipeline,
        background,
    })
}

/// Reads and aligns a background capture, checking that it fits this measurement.
fn read_background(
    pipeline: &mut Pipeline,
    path: &std::path::Path,
    capture_rate_hz: f64,
) -> Result<Aligned, MeasureError> {
    use crate::storage::recording::{read_sigmf, SampleUnit};
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
    let raw = RawIq {
        samples: rec.samples,
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

/// Runs one prepared capture on the bench and processes it.
pub async fn run(
    bench: &Bench,
    catalog: &Catalog,
    prepared: Prepared,
    permit: &RfPermit,
    journal: Option<Journal>,
    interrupt: &Interrupt,
) -> Result<Measurement, MeasureError> {
    let Prepared {
        tx,
        plan,
        mut pipeline,
        background,
    } = prepared;
    let mut station = Station::connect(&bench.file, catalog, journal).await?;
    station.install_panic_hook();
    let (result, report) = station.capture(&tx, &plan, permit, interrupt).await;
    if !report.is_safe() {
        eprintln!(
            "WARNING: the safe state did not complete: {report}; switch the bench off by hand"
        );
    }
    let captured = result?;
    pipeline.set_awg_amplitude(captured.applied.awg.i_amplitude_vpp)?;
    let raw = captured.raw();
    let (pipeline, processed) = off_runtime(move || {
        let processed = pipeline
            .align(&raw)
            .and_then(|aligned| pipeline.process(aligned, background.as_ref()));
        (pipeline, processed)
    })
    .await?;
    let processed = processed?;
    let ground_truth = bench.ground_truth().await;
    Ok(Measurement {
        tx,
        plan,
        captured,
        processed,
        options: pipeline.options().clone(),
        identities: station.identities.clone(),
        ground_truth,
        safe_state: report,
    })
}

/// [`prepare`], then [`run`].
pub async fn measure(
    bench: &Bench,
    request: &CaptureRequest,
    permit: &RfPermit,
    journal: Option<Journal>,
    interrupt: &Interrupt,
) -> Result<Measurement, MeasureError> {
    let catalog = Catalog::embedded()?;
    let prepared = prepare(bench, &catalog, request).await?;
    run(bench, &catalog, prepared, permit, journal, interrupt).await
}
