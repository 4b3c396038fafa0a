//! The built-in mock lab's capture of a scene, made in-process without instruments or sockets
//! (`radbench simulate run --scene`): what `radbench capture --allow-rf --scene FILE` records and
//! reports, from the same code.
//!
//! - the transmission: [`Transmission::new`] with the request's waveform, seed or payload and the
//!   AWG's 8-bit DAC, as [`crate::measure::capture::prepare`] makes it;
//! - the instrument settings: [`station::plan`] on the built-in lab's models (its bench file
//!   names no attenuation and no V/div, so the catalog's defaults apply), the AWG's
//!   plan (`driver::open::plan_awg`) for the padded segment and where the marker is high;
//! - the numbers as the instruments hold them: every setting the drivers send goes through the
//!   driver's [`number`] formatting and is parsed back; the scope's horizontal scale and trigger
//!   delay are derived from the planned record as `driver::lecroy` derives them;
//! - the physics and the scope: [`OfflineScope`], the lab's `Synthesizer` seeded with the scene's
//!   `seed`, and the emulated LabMaster's record length, first point and 8-bit ADC;
//! - the processing: the capture's [`Pipeline`] through [`process_repetitions`], the ADC's rails
//!   counted, the AWG amplitude as applied.
//!
//! So [`SceneCapture::acquire`] gives the scope words of the lab's first capture of the scene
//! (then its second, ...), and the detections the capture reports. Not modelled: the transfer
//! (no WAVEDESC, no `.trc`), the wall-clock trigger time stamps, and a scene changed between
//! captures through the control channel.

use super::bench_file::{BenchCalibration, BenchFile};
use super::station::{self, CapturePlan};
use crate::catalog::Catalog;
use crate::driver::open::plan_awg;
use crate::driver::scpi::number;
use crate::driver::DigitizerSettings;
use crate::measure::capture::{process_repetitions, read_background, CaptureRequest};
use crate::measure::error::MeasureError;
use crate::measure::processing::clipping::ScopeAdc;
use crate::measure::processing::pipeline::{
    Aligned, Pipeline, Processed, RawWords, RecordGeometry,
};
use crate::measure::processing::transmit::{Dac, Transmission};
use mock_lab::offline::{OfflineScope, ScopeSettings};
use mock_lab::scene::{AwgPlayback, FrontEnds, Scene};
use std::path::Path;
use std::sync::Arc;

/// The models the built-in mock lab serves (as `mock-lab serve` writes its bench file); the
/// resources are never opened.
const BUILT_IN_BENCH: &str = r#"
[awg]
model = "keysight-m8195a"
resource = "TCPIP::127.0.0.1::hislip0::INSTR"

[scope]
model = "lecroy-labmaster10zi-a"
resource = "VICP::127.0.0.1"
"#;

/// The built-in lab, planned and loaded, its scope ready to acquire.
pub(crate) struct SceneCapture {
    tx: Arc<Transmission>,
    plan: CapturePlan,
    segment: AwgSegment,
    scope_settings: ScopeSettings,
    scope: OfflineScope,
    pipeline: Pipeline,
    background: Option<Aligned>,
    front: FrontEnds,
    adc: ScopeAdc,
}

impl SceneCapture {
    /// Everything `capture --scene` prepares for `request` on a lab started with `scene`: the
    /// request's options get the lab's calibration (its nominal system delay), as the built-in
    /// bench file has it, and its scope's trigger jitter (the scene's, as the built-in bench
    /// states it).
    pub(crate) fn prepare(
        scene: &Scene,
        request: &CaptureRequest,
    ) -> Result<SceneCapture, MeasureError> {
        let mut options = request.options.clone();
        options.system_delay_s = scene.system_delay_s;
        options.trigger_jitter_s = Some(scene.trigger_jitter_s);
        let tx = Arc::new(Transmission::new(
            &request.waveform,
            request.payload.as_deref(),
            request.seed,
            Dac::default(),
        )?);
        crate::measure::processing::pipeline::validate(&tx, &options)?;
        let mut bench = BenchFile::parse(BUILT_IN_BENCH, Path::new("<built-in mock lab>"))?;
        bench.calibration = Some(BenchCalibration {
            system_delay_s: scene.system_delay_s,
            reference_range_m: None,
            measured_at: None,
            response: None,
        });
        let catalog = Catalog::embedded()?;
        let plan = station::plan(
            &bench,
            &catalog,
            &tx,
            &options,
            request.tx_off,
            request.wait_s,
        )?;
        let segment = AwgSegment::of(&bench, &catalog, &tx, &plan)?;
        let scope_settings = scope_settings(&bench, &catalog, &tx, &plan)?;
        let scope = OfflineScope::new(scene.seed)
            .map_err(|e| MeasureError::Lab(mock_lab::lab::LabError::Catalog(e)))?;
        let rate = scope.sample_rate();
        let geometry = RecordGeometry::for_capture(plan.period, tx.sample_rate_hz(), &options);
        let mut pipeline = Pipeline::new(tx.clone(), options, geometry)?;
        pipeline.prepare_capture_rate(rate)?;
        pipeline.set_awg_amplitude(segment.amplitude_vpp[0])?;
        let background = match &request.background {
            Some(path) => Some(read_background(&mut pipeline, path, rate)?),
            None => None,
        };
        let front = FrontEnds {
            tx_enabled: !request.tx_off,
            tx_attenuation_db: plan.tx.attenuation_db,
            rx_enabled: true,
            rx_attenuation_db: plan.rx.attenuation_db,
        };
        let adc = plan.scope_adc();
        Ok(SceneCapture {
            tx,
            plan,
            segment,
            scope_settings,
            scope,
            pipeline,
            background,
            front,
            adc,
        })
    }

    /// The next acquisition of `scene` (the lab's first, then second, ... capture), processed
    /// as the capture processes one repetition.
    pub(crate) fn acquire(&mut self, scene: &Scene) -> Result<Processed, MeasureError> {
        let s = &self.segment;
        let awg = AwgPlayback {
            i: &s.i,
            q: &s.q,
            sample_rate: s.sample_rate,
            amplitude_vpp: s.amplitude_vpp,
            marker_index: s.marker_index,
            playing: true,
            marker_out: true,
        };
        let record = self
            .scope
            .acquire(scene, &awg, self.front, &self.scope_settings)?;
        let raw = RawWords {
            i: record.i,
            q: record.q,
            gain: record.vertical_gain,
            offset: record.vertical_offset,
            sample_rate_hz: record.sample_rate,
            first_point_s: record.first_point_s,
        };
        let clipped = raw.clipping(&self.adc);
        let (processed, _, _) = process_repetitions(
            &mut self.pipeline,
            std::slice::from_ref(&raw),
            self.background.as_ref(),
            self.tx.bandwidth_hz(),
            &[Some(clipped)],
        )?;
        Ok(processed)
    }

    /// The pipeline's options as used (the lab's system delay, the AWG amplitude applied).
    pub(crate) fn options(&self) -> &crate::measure::processing::options::ProcessOptions {
        self.pipeline.options()
    }

    /// The transmission.
    pub(crate) fn transmission(&self) -> &Transmission {
        &self.tx
    }

    /// The scope's sample rate, Sa/s.
    pub(crate) fn capture_rate_hz(&self) -> f64 {
        self.scope.sample_rate()
    }

    /// Samples of one repetition at the waveform rate (the AWG's padded segment).
    pub(crate) fn period(&self) -> usize {
        self.plan.period
    }
}

/// A setting as the instrument holds it: the driver's text, parsed back.
fn sent(value: f64) -> f64 {
    number(value).parse().unwrap_or(value)
}

/// The AWG's segment as the upload leaves it in the lab's AWG.
struct AwgSegment {
    i: Vec<i8>,
    q: Vec<i8>,
    /// The AWG's playback rate: its DAC raster over its divider.
    sample_rate: f64,
    amplitude_vpp: [f64; 2],
    /// Sample of the marker's first rising edge.
    marker_index: usize,
}

impl AwgSegment {
    fn of(
        bench: &BenchFile,
        catalog: &Catalog,
        tx: &Transmission,
        plan: &CapturePlan,
    ) -> Result<AwgSegment, MeasureError> {
        let model = catalog.get(&bench.awg.model)?;
        let not_awg = || MeasureError::DoesNotFit {
            waveform: tx.name(),
            instrument: bench.awg.model.clone(),
            reason: "the built-in lab's AWG model has no [awg] section".into(),
        };
        model.awg.as_ref().ok_or_else(not_awg)?;
        let download = plan_awg(model, &plan.awg, &tx.iq)?;
        // The segment as the upload leaves it: zeros past the waveform, the marker high on the
        // first samples.
        let padded = |codes: &[i8]| -> Vec<i8> {
            (0..download.padded_samples as usize)
                .map(|n| codes.get(n).copied().unwrap_or(0))
                .collect()
        };
        let markers: Vec<u8> = (0..download.padded_samples)
            .map(|n| u8::from(n < download.marker_high_samples))
            .collect();
        Ok(AwgSegment {
            i: padded(&tx.iq.i),
            q: padded(&tx.iq.q),
            sample_rate: sent(download.dac_rate_hz) / f64::from(download.divider),
            amplitude_vpp: [
                sent(plan.awg.i_amplitude_vpp),
                sent(plan.awg.q_amplitude_vpp),
            ],
            marker_index: first_rising_edge(&markers),
        })
    }
}

/// Index of the first 0 -> 1 transition of marker bit 0 of a looped segment (0 when none), as
/// the lab's wiring finds the trigger edge.
fn first_rising_edge(markers: &[u8]) -> usize {
    let n = markers.len();
    (0..n)
        .find(|&k| markers[k] & 1 != 0 && markers[(k + n - 1) % n] & 1 == 0)
        .unwrap_or(0)
}

/// The scope's settings after `driver::lecroy` configures it for one repetition of the padded
/// segment: the horizontal scale it sends (record over divisions) and reads back, the trigger
/// delay that puts the first point `pre_trigger_s` before the trigger, the vertical scales.
fn scope_settings(
    bench: &BenchFile,
    catalog: &Catalog,
    tx: &Transmission,
    plan: &CapturePlan,
) -> Result<ScopeSettings, MeasureError> {
    let model = catalog.get(&bench.scope.model)?;
    let limits = model
        .digitizer
        .as_ref()
        .ok_or_else(|| MeasureError::DoesNotFit {
            waveform: tx.name(),
            instrument: bench.scope.model.clone(),
            reason: "the built-in lab's scope model has no [digitizer] section".into(),
        })?;
    let divisions = f64::from(limits.horizontal_divisions);
    let settings = DigitizerSettings {
        repetition_s: plan.period as f64 / tx.sample_rate_hz(),
        segments: 1,
        ..plan.scope.clone()
    };
    let hor_scale_s = sent(settings.record_s() / divisions);
    Ok(ScopeSettings {
        hor_scale_s,
        trigger_delay_s: sent(settings.pre_trigger_s - divisions / 2.0 * hor_scale_s),
        volts_per_div: [
            sent(settings.i_volts_per_div),
            sent(settings.q_volts_per_div),
        ],
        offset_v: [sent(settings.i_offset_v), sent(settings.q_offset_v)],
    })
}
