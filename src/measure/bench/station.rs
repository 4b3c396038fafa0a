//! The connected bench: its drivers behind the capability traits, the safe state, and the steps of
//! a capture (upload, RF on, acquire) with everything checkable checked before RF goes on.
//!
//! [`plan`] is pure: from the bench file, the catalog and the transmission it derives every
//! instrument setting (the AWG clock and segment padding, the scope's rate, scale and record) and
//! fails before any instrument is touched when something does not fit.

use super::bench_file::{BenchFile, InstrumentEntry};
use super::interrupt::Interrupt;
use crate::address::Resource;
use crate::catalog::{Catalog, DigitizerLimits, InstrumentModel};
use crate::driver::open;
use crate::driver::safe_state::{self, Shared};
use crate::driver::{
    Awg, AwgApplied, AwgSettings, ChannelTrace, Digitizer, DigitizerApplied, DigitizerSettings,
    Identity, IqCapture, Journal, LoadedSegment, Outcome, ReadyToEnable, RfFrontEnd, RfPermit,
    RfSettings, RfStatus, SafeState, SafeStateReport, SegmentTiming,
};
use crate::dsp::C0;
use crate::measure::error::MeasureError;
use crate::measure::processing::clipping::{Rails, ScopeAdc};
use crate::measure::processing::options::ProcessOptions;
use crate::measure::processing::pipeline::{RawIq, RawWords};
use crate::measure::processing::transmit::Transmission;
use num_complex::Complex64;
use serde::Serialize;
use std::time::Duration;

/// Time allowed for enabling the front ends (serial register writes and read-backs) and starting
/// the AWG, seconds.
const RF_SETUP_S: f64 = 30.0;

/// Bound on each step of the safe-state sequence.
const SAFE_STEP_TIMEOUT: Duration = Duration::from_secs(5);

/// `*IDN?` of every instrument, for the run's files.
#[derive(Debug, Clone, Serialize, Default, PartialEq)]
pub struct Identities {
    pub awg: String,
    pub scope: String,
    pub tx: Option<String>,
    pub rx: Option<String>,
}

fn idn(i: &Identity) -> String {
    format!("{},{},{},{}", i.manufacturer, i.model, i.serial, i.firmware)
}

fn resource(text: &str, section: &'static str) -> Result<Resource, MeasureError> {
    text.parse().map_err(|source| MeasureError::Resource {
        section,
        text: text.to_string(),
        source,
    })
}

/// How to drive the bench for one capture; plain data, derived by `plan`.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct CapturePlan {
    pub awg: AwgSettings,
    pub scope: DigitizerSettings,
    pub tx: RfSettings,
    pub rx: RfSettings,
    /// Leave the transmitter off (noise floor / leakage checks); the receiver still runs.
    pub tx_off: bool,
    /// Longest wait for the marker-triggered acquisition, seconds.
    pub wait_s: f64,
    /// Samples of one repetition after the AWG pads the segment (the repetition period).
    pub period: usize,
    /// Capture samples per waveform sample (scope rate / AWG rate).
    pub decimation: usize,
    /// Longest time RF may stay on for one repetition: the acquisition wait plus fetching both
    /// channels at the catalog's slowest healthy rate, seconds. Past it the capture is failing
    /// and the safe state runs at once, whatever the links would still allow.
    pub rf_seconds_per_repetition: f64,
    /// Enabling the front ends and starting the AWG, seconds allowed.
    pub rf_setup_s: f64,
    /// Most repetitions one acquisition can record in the scope's sequence mode (the catalog's
    /// `max_sequence_segments`, limited by the memory); 1 when the model has no sequence mode.
    pub max_sequence_segments: u32,
    /// Bits of the scope's ADC code, in the upper bits of each word (the catalog's `adc_bits`):
    /// where its rails are.
    pub adc_bits: u8,
    /// The largest vertical scale the catalog allows, V/div (for a clipped capture's advice).
    pub volts_per_div_max: f64,
}

impl CapturePlan {
    /// The RF-on deadline of `repetitions` repetitions, seconds.
    pub(crate) fn rf_deadline_s(&self, repetitions: usize) -> f64 {
        self.rf_setup_s + repetitions.max(1) as f64 * self.rf_seconds_per_repetition
    }

    /// The scope's ADC and vertical scale as planned.
    pub(crate) fn scope_adc(&self) -> ScopeAdc {
        ScopeAdc {
            rails: Rails::word(self.adc_bits),
            volts_per_div: [self.scope.i_volts_per_div, self.scope.q_volts_per_div],
            volts_per_div_max: self.volts_per_div_max,
        }
    }

    /// Segments per acquisition for `repetitions`: 1 (one acquisition each) without sequence
    /// mode, else as few acquisitions as the sequence allows, split evenly.
    pub(crate) fn sequence_segments(&self, repetitions: usize) -> u32 {
        let max = self.max_sequence_segments as usize;
        if repetitions < 2 || max < 2 {
            return 1;
        }
        let acquisitions = repetitions.div_ceil(max);
        u32::try_from(repetitions.div_ceil(acquisitions)).unwrap_or(1)
    }
}

/// Derives every instrument setting of a capture and checks it against the catalog; touches no
/// instrument.
pub(crate) fn plan(
    bench: &BenchFile,
    catalog: &Catalog,
    tx: &Transmission,
    options: &ProcessOptions,
    tx_off: bool,
    wait_s: f64,
) -> Result<CapturePlan, MeasureError> {
    if !(wait_s.is_finite() && wait_s > 0.0 && wait_s <= 3600.0) {
        return Err(MeasureError::option(
            "wait",
            wait_s,
            "0 < seconds <= 3600 (the longest wait for the marker-triggered acquisition)",
        ));
    }
    let awg_model = catalog.get(&bench.awg.model)?;
    let scope_model = catalog.get(&bench.scope.model)?;
    awg_model
        .awg
        .as_ref()
        .ok_or_else(|| not_kind(&bench.awg, "awg", "an AWG"))?;
    let scope_limits = scope_model
        .digitizer
        .as_ref()
        .ok_or_else(|| not_kind(&bench.scope, "scope", "a digitizer"))?;
    let awg = AwgSettings {
        sample_rate_hz: tx.sample_rate_hz(),
        // The bench file's: a shared 10 MHz stays shared (never switched back to internal).
        reference_clock: bench
            .awg
            .reference_clock_hz
            .map_or(crate::driver::ReferenceClock::Internal, |frequency_hz| {
                crate::driver::ReferenceClock::External { frequency_hz }
            }),
        ..AwgSettings::default()
    };
    let name = &awg_model.instrument.model;
    let fit = |e: crate::driver::DriverError| MeasureError::DoesNotFit {
        waveform: tx.name(),
        instrument: name.clone(),
        reason: e.to_string(),
    };
    let download = open::plan_awg(awg_model, &awg, &tx.iq).map_err(fit)?;
    let period = download.padded_samples as usize;
    let fs = tx.sample_rate_hz();
    let rate = capture_rate(scope_limits, fs)?;
    let vdiv = bench
        .scope
        .volts_per_div
        .unwrap_or(scope_limits.volts_per_div_default);
    let repetition_s = period as f64 / fs;
    let scope = DigitizerSettings {
        sample_rate_hz: rate,
        repetition_s,
        // One repetition holds every echo of the looped segment (they wrap around).
        longest_echo_s: 0.0,
        pre_trigger_s: 0.0,
        i_volts_per_div: vdiv,
        q_volts_per_div: vdiv,
        trigger_level_v: awg.marker_offset_v,
        ..DigitizerSettings::default()
    };
    let points = (scope.record_s() * rate).ceil();
    if points > scope_limits.max_points_per_channel as f64 {
        return Err(MeasureError::DoesNotFit {
            waveform: tx.name(),
            instrument: scope_model.instrument.model.clone(),
            reason: format!(
                "one repetition of {repetition_s} s is {points} points at {rate} Sa/s; the scope \
                 records at most {} per channel",
                scope_limits.max_points_per_channel
            ),
        });
    }
    check_unambiguous(options, repetition_s)?;
    let front = |e: &Option<InstrumentEntry>| RfSettings {
        attenuation_db: e.as_ref().and_then(|t| t.attenuation_db).unwrap_or(0.0),
        lo_frequency_hz: None,
    };
    // Fetching one channel: the read timeout plus its bytes at the catalog's slowest rate.
    let t = &scope_model.timeouts;
    let channel_bytes = 2.0 * points + 1e6;
    let max_sequence_segments = if scope_limits.max_sequence_segments > 1 {
        let fit = (scope_limits.max_points_per_channel as f64 / points).floor();
        fit.min(f64::from(scope_limits.max_sequence_segments)) as u32
    } else {
        1
    };
    let fetch_s = t.read_ms as f64 / 1e3 + channel_bytes / 1e6 * t.per_megabyte_ms as f64 / 1e3;
    Ok(CapturePlan {
        awg,
        scope,
        tx: front(&bench.tx),
        rx: front(&bench.rx),
        tx_off,
        wait_s,
        period,
        decimation: (rate / fs).round() as usize,
        rf_seconds_per_repetition: wait_s + 2.0 * fetch_s,
        rf_setup_s: RF_SETUP_S,
        max_sequence_segments,
        adc_bits: scope_limits.adc_bits,
        volts_per_div_max: scope_limits.volts_per_div_max,
    })
}

/// The fastest rate the catalog lists that is a whole multiple of the waveform's.
pub(in crate::measure) fn capture_rate(
    scope: &DigitizerLimits,
    waveform_hz: f64,
) -> Result<f64, MeasureError> {
    scope
        .sample_rates
        .iter()
        .copied()
        .filter(|r| {
            let k = r / waveform_hz;
            k >= 1.0 && (k - k.round()).abs() < 1e-9 * k
        })
        .fold(None, |best: Option<f64>, r| {
            Some(best.map_or(r, |b| b.max(r)))
        })
        .ok_or_else(|| MeasureError::RateNotMultiple {
            capture_hz: scope.sample_rates.first().copied().unwrap_or(0.0),
            waveform_hz,
        })
}

/// A target beyond one repetition would alias onto a nearer range: the range window must end
/// within it.
fn check_unambiguous(options: &ProcessOptions, repetition_s: f64) -> Result<(), MeasureError> {
    let unambiguous_m = C0 * repetition_s / 2.0;
    if options.max_range_m > unambiguous_m {
        return Err(MeasureError::option(
            "max-range",
            options.max_range_m,
            format!(
                "at most {unambiguous_m:.1} m: farther echoes wrap into the next repetition of \
                 this waveform"
            ),
        ));
    }
    Ok(())
}

fn not_kind(entry: &InstrumentEntry, section: &'static str, what: &str) -> MeasureError {
    MeasureError::BenchFile(super::bench_file::BenchFileError::Invalid {
        path: "bench file".into(),
        message: format!(
            "[{section}] model = {:?} is not {what} in the instrument catalog",
            entry.model
        ),
    })
}

/// What the instruments did for a capture.
#[derive(Debug, Clone, Serialize, PartialEq)]
pub struct Applied {
    pub awg: AwgApplied,
    pub segment: LoadedSegment,
    pub scope: DigitizerApplied,
    pub tx: Option<RfStatus>,
    pub rx: Option<RfStatus>,
}

/// The raw captures of one measurement and how they were made.
pub struct Captured {
    /// The scope's acquisitions in order: one per repetition, or in sequence mode one per
    /// `segments` repetitions (the last may hold more segments than are used).
    pub acquisitions: Vec<IqCapture>,
    /// Repetitions asked for (and held).
    repetitions: usize,
    pub applied: Applied,
    /// What the AWG and scope held (kept to skip the next upload of the same waveform).
    pub uploaded: Uploaded,
}

/// Where one repetition sits in the scope's acquisitions.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RepetitionSource {
    /// 0-based acquisition.
    pub acquisition: usize,
    /// 0-based segment of that acquisition (0 unless in sequence mode).
    pub segment: usize,
    pub timing: SegmentTiming,
}

impl Captured {
    /// `acquisitions` hold at least `repetitions` segments in all (checked by the caller).
    pub fn new(
        acquisitions: Vec<IqCapture>,
        repetitions: usize,
        applied: Applied,
        uploaded: Uploaded,
    ) -> Captured {
        Captured {
            acquisitions,
            repetitions,
            applied,
            uploaded,
        }
    }

    /// Where repetition `k` (0-based) was recorded.
    pub fn source(&self, k: usize) -> RepetitionSource {
        let mut rest = k;
        for (a, iq) in self.acquisitions.iter().enumerate() {
            if rest < iq.segments() {
                return RepetitionSource {
                    acquisition: a,
                    segment: rest,
                    timing: iq.i.timing(rest),
                };
            }
            rest -= iq.segments();
        }
        RepetitionSource {
            acquisition: 0,
            segment: 0,
            timing: self.acquisitions[0].i.timing(0),
        }
    }

    /// Repetition `k`'s I and Q codes (equal lengths).
    fn codes(&self, k: usize) -> (&ChannelTrace, &ChannelTrace, &[i16], &[i16]) {
        let at = self.source(k);
        let iq = &self.acquisitions[at.acquisition];
        let (i, q) = (
            iq.i.segment_codes(at.segment),
            iq.q.segment_codes(at.segment),
        );
        let n = i.len().min(q.len());
        (&iq.i, &iq.q, &i[..n], &q[..n])
    }

    /// Repetition `k` as I + jQ in volts with the time of its first point after the trigger.
    pub fn raw(&self, k: usize) -> RawIq {
        let (i, q, ci, cq) = self.codes(k);
        let (gi, oi) = (i.volts_per_code, i.offset_v);
        let (gq, oq) = (q.volts_per_code, q.offset_v);
        RawIq {
            samples: ci
                .iter()
                .zip(cq)
                .map(|(&a, &b)| Complex64::new(gi * f64::from(a) - oi, gq * f64::from(b) - oq))
                .collect(),
            // The scope's own interval may be stored in single precision: take the rate the
            // scope reported applying.
            sample_rate_hz: self.applied.scope.sample_rate_hz,
            first_point_s: self.source(k).timing.first_sample_s,
        }
    }

    /// Repetition `k` as the scope's words and their scaling: [`raw`](Self::raw) without the
    /// record in volts (the pipeline converts as it decimates).
    pub(crate) fn raw_words(&self, k: usize) -> RawWords {
        let (i, q, ci, cq) = self.codes(k);
        RawWords {
            i: ci.to_vec(),
            q: cq.to_vec(),
            gain: [i.volts_per_code, q.volts_per_code],
            offset: [i.offset_v, q.offset_v],
            sample_rate_hz: self.applied.scope.sample_rate_hz,
            first_point_s: self.source(k).timing.first_sample_s,
        }
    }

    /// Repetitions captured.
    pub fn repetitions(&self) -> usize {
        self.repetitions
    }

    /// The first acquisition (its native files are the ones saved).
    pub fn first(&self) -> &IqCapture {
        &self.acquisitions[0]
    }
}

/// What the upload left in the instruments.
#[derive(Debug, Clone, Serialize, PartialEq)]
pub struct Uploaded {
    pub awg: AwgApplied,
    pub segment: LoadedSegment,
    pub scope: DigitizerApplied,
}

/// The pre-enable check of a front end, when the bench has it.
async fn check_before_enable(
    front: Option<&Shared<dyn RfFrontEnd>>,
    settings: &RfSettings,
) -> Result<Option<ReadyToEnable>, MeasureError> {
    match front {
        Some(front) => Ok(Some(
            front.lock().await.check_before_enable(settings).await?,
        )),
        None => Ok(None),
    }
}

/// A front end switched on for a capture (`enabled`: what its enable returned), read back after
/// it: still as it was left, or a [`DriverError::StateLost`](crate::driver::DriverError).
async fn confirm_enabled(
    front: Option<&Shared<dyn RfFrontEnd>>,
    enabled: Option<&RfStatus>,
) -> Result<(), MeasureError> {
    if let (Some(front), Some(enabled)) = (front, enabled) {
        front.lock().await.confirm_enabled(enabled).await?;
    }
    Ok(())
}

/// The bench's drivers, shared with the safe state.
pub(crate) struct Station {
    awg: Shared<dyn Awg>,
    scope: Box<dyn Digitizer>,
    tx: Option<Shared<dyn RfFrontEnd>>,
    rx: Option<Shared<dyn RfFrontEnd>>,
    pub identities: Identities,
    safe: SafeState,
}

impl Station {
    /// Opens every instrument of the bench file (front ends optional) and builds the safe state.
    /// The four are connected side by side (each on its own link; connecting sends no RF
    /// command); when several fail, the error reported is the first in the order AWG, scope,
    /// Tx, Rx, as when they were connected one after another.
    pub(crate) async fn connect(
        bench: &BenchFile,
        catalog: &Catalog,
        journal: Option<Journal>,
    ) -> Result<Station, MeasureError> {
        let awg_model = catalog.get(&bench.awg.model)?;
        let scope_model = catalog.get(&bench.scope.model)?;
        let awg_resource = resource(&bench.awg.resource, "awg")?;
        let scope_resource = resource(&bench.scope.resource, "scope")?;
        let (awg, scope, tx, rx) = tokio::join!(
            open::open_awg(awg_resource, awg_model, journal.clone(), "awg"),
            open::open_digitizer(scope_resource, scope_model, journal.clone(), "scope"),
            open_front(catalog, &bench.tx, "tx", journal.clone()),
            open_front(catalog, &bench.rx, "rx", journal),
        );
        let (awg, scope, tx, rx) = (awg?, scope?, tx?, rx?);
        let mut identities = Identities {
            awg: idn(awg.identity()),
            scope: idn(scope.identity()),
            ..Identities::default()
        };
        identities.tx = tx.as_ref().map(|g| idn(g.identity()));
        identities.rx = rx.as_ref().map(|g| idn(g.identity()));
        for m in &bench.manual {
            // Recorded as what it is: not asked, set by the operator.
            let slot = if m.section == "tx" {
                &mut identities.tx
            } else {
                &mut identities.rx
            };
            *slot = Some(format!(
                "manual,{},not connected,set by the operator",
                m.model.as_deref().unwrap_or("front end")
            ));
        }
        let awg: Shared<dyn Awg> = safe_state::share(awg);
        let tx: Option<Shared<dyn RfFrontEnd>> = tx.map(safe_state::share);
        let rx: Option<Shared<dyn RfFrontEnd>> = rx.map(safe_state::share);
        crate::driver::rf_state::connected("awg");
        for (name, front) in [("tx", &tx), ("rx", &rx)] {
            if front.is_some() {
                crate::driver::rf_state::connected(name);
            }
        }
        let safe = SafeState::new(
            safe_state::Bench {
                tx: tx.clone(),
                rx: rx.clone(),
                awg: Some(awg.clone()),
            },
            SAFE_STEP_TIMEOUT,
        );
        Ok(Station {
            awg,
            scope,
            tx,
            rx,
            identities,
            safe,
        })
    }

    /// The safe-state sequence of this bench (for a panic hook or an explicit call).
    pub(crate) fn safe_state(&self) -> &SafeState {
        &self.safe
    }

    /// Makes a panic run this bench's safe state (it replaces the state of a bench connected
    /// earlier in the process).
    pub(crate) fn install_panic_hook(&self) {
        crate::driver::set_panic_safe_state(self.safe.clone());
    }

    /// Configures the AWG, downloads the waveform and configures the scope. Nothing radiates.
    pub(crate) async fn upload(
        &mut self,
        tx: &Transmission,
        plan: &CapturePlan,
        segments: u32,
    ) -> Result<Uploaded, MeasureError> {
        let (awg, segment) = {
            let mut awg = self.awg.lock().await;
            let applied = awg.configure(&plan.awg).await?;
            let segment = awg.load(&tx.iq).await?;
            (applied, segment)
        };
        let scope = self.configure_scope(tx, plan, &segment, segments).await?;
        Ok(Uploaded {
            awg,
            segment,
            scope,
        })
    }

    /// The scope set for one repetition of the loaded segment, `segments` triggers per
    /// acquisition.
    async fn configure_scope(
        &mut self,
        tx: &Transmission,
        plan: &CapturePlan,
        loaded: &LoadedSegment,
        segments: u32,
    ) -> Result<DigitizerApplied, MeasureError> {
        let settings = DigitizerSettings {
            repetition_s: loaded.padded_samples as f64 / tx.sample_rate_hz(),
            segments,
            ..plan.scope.clone()
        };
        Ok(self.scope.configure(&settings).await?)
    }

    /// What the AWG reports now: clock, levels, outputs and its segment table (read before each
    /// measurement of a campaign, so a lost waveform is noticed and uploaded again).
    pub(crate) async fn awg_applied(&mut self) -> Result<AwgApplied, MeasureError> {
        Ok(self.awg.lock().await.applied().await?)
    }

    /// Enables the receiver, the transmitter (unless `tx_off`) and the AWG outputs with the
    /// user's permit, starts playback and captures `repetitions` marker-triggered repetitions.
    /// The caller's guard puts the bench back in its safe state.
    pub(crate) async fn acquire(
        &mut self,
        plan: &CapturePlan,
        permit: &RfPermit,
        repetitions: usize,
    ) -> Result<Acquired, MeasureError> {
        // Both modules are checked (on their own serial lines, side by side) before either is
        // switched on, so a transmitter that is not ready stops the measurement with nothing
        // radiating; then the receiver, then the transmitter.
        let tx = self.tx.as_ref().filter(|_| !plan.tx_off);
        let (rx_ready, tx_ready) = tokio::join!(
            check_before_enable(self.rx.as_ref(), &plan.rx),
            check_before_enable(tx, &plan.tx),
        );
        let (rx_ready, tx_ready) = (rx_ready?, tx_ready?);
        let mut rx_status = None;
        let mut tx_status = None;
        if let (Some(rx), Some(ready)) = (&self.rx, rx_ready) {
            rx_status = Some(rx.lock().await.enable_checked(permit, ready).await?);
        }
        if let (Some(txm), Some(ready)) = (tx, tx_ready) {
            tx_status = Some(txm.lock().await.enable_checked(permit, ready).await?);
        }
        {
            let mut awg = self.awg.lock().await;
            awg.enable_outputs(permit).await?;
            awg.run().await?;
        }
        // One acquisition per repetition, or in sequence mode one per `segments` of them.
        let mut captures = Vec::new();
        let mut held = 0;
        while held < repetitions.max(1) {
            let capture = self.scope.capture_iq(plan.wait_s).await?;
            held += capture.segments().max(1);
            captures.push(capture);
        }
        // A module reset or powered off during the acquisition (RF off since, settings at their
        // power-on values) leaves a capture without echo in which nothing failed: both are read
        // back (side by side, each exchange within its link's deadline) before it counts.
        let (rx_now, tx_now) = tokio::join!(
            confirm_enabled(self.rx.as_ref(), rx_status.as_ref()),
            confirm_enabled(tx, tx_status.as_ref()),
        );
        tx_now?;
        rx_now?;
        if tx_status.is_none() {
            if let Some(txm) = &self.tx {
                tx_status = Some(txm.lock().await.status().await?);
            }
        }
        Ok(Acquired {
            captures,
            tx: tx_status,
            rx: rx_status,
        })
    }

    /// Upload (unless `loaded` says the AWG still holds this waveform) and acquire under the
    /// safe-state guard: the bench ends in its safe state whatever happens, also when
    /// `interrupt` fires first. `fresh`: `loaded` was uploaded just before, for this capture
    /// (see `Rig::upload_ahead`), and is used as it is; otherwise the AWG is asked first.
    #[allow(clippy::too_many_arguments)]
    pub(crate) async fn capture(
        &mut self,
        tx: &Transmission,
        plan: &CapturePlan,
        loaded: Option<&Uploaded>,
        fresh: bool,
        repetitions: usize,
        permit: &RfPermit,
        interrupt: &Interrupt,
    ) -> (Result<Captured, MeasureError>, SafeStateReport) {
        let safe = self.safe.clone();
        let segments = plan.sequence_segments(repetitions);
        let work = async {
            let mut up = match loaded {
                Some(up) if fresh => up.clone(),
                Some(up) => {
                    // The AWG may have been power-cycled or reset since: look before trusting it.
                    let now = self.awg_applied().await?;
                    let wanted = crate::driver::SegmentEntry {
                        id: up.segment.segment_id,
                        samples: up.segment.padded_samples,
                    };
                    if now.segments.contains(&wanted) && now.dac_rate_hz == up.awg.dac_rate_hz {
                        Uploaded {
                            awg: now,
                            ..up.clone()
                        }
                    } else {
                        tracing::warn!("the AWG no longer holds the waveform: uploading it again");
                        self.upload(tx, plan, segments).await?
                    }
                }
                None => self.upload(tx, plan, segments).await?,
            };
            if up.scope.segments != segments {
                // Another number of repetitions than the last measurement: only the scope's
                // sequence changes (still before any RF).
                up.scope = self
                    .configure_scope(tx, plan, &up.segment, segments)
                    .await?;
            }
            let deadline = plan.rf_deadline_s(repetitions);
            let acquired = tokio::time::timeout(
                std::time::Duration::from_secs_f64(deadline),
                self.acquire(plan, permit, repetitions),
            )
            .await
            .map_err(|_| MeasureError::RfDeadline { seconds: deadline })??;
            let applied = Applied {
                awg: up.awg.clone(),
                segment: up.segment.clone(),
                scope: up.scope.clone(),
                tx: acquired.tx,
                rx: acquired.rx,
            };
            Ok(Captured::new(
                acquired.captures,
                repetitions.max(1),
                applied,
                up,
            ))
        };
        let (outcome, report) = crate::driver::run_guarded(&safe, work, interrupt.wait()).await;
        let result = match outcome {
            Outcome::Finished(r) => r.map_err(|e| with_safe_state(e, &report)),
            Outcome::Interrupted => Err(MeasureError::Interrupted {
                signal: interrupt
                    .received()
                    .unwrap_or(super::interrupt::StopSignal::Interrupt),
                report: report.to_string(),
            }),
        };
        (result, report)
    }
}

impl Drop for Station {
    fn drop(&mut self) {
        // The panic hook must not keep this bench's links (a serial port) open after it closes.
        crate::driver::clear_panic_safe_state(&self.safe);
    }
}

/// A stop while RF was on says what the safe state then switched off (a missing marker edge:
/// the operator is at the bench, wondering whether it still radiates).
fn with_safe_state(e: MeasureError, report: &SafeStateReport) -> MeasureError {
    match e {
        MeasureError::Driver(crate::driver::DriverError::NoTrigger {
            instrument,
            source_name,
            waited_s,
            ..
        }) => MeasureError::Driver(crate::driver::DriverError::NoTrigger {
            instrument,
            source_name,
            waited_s,
            safe_state: Some(report.clone()),
        }),
        other => other,
    }
}

/// What one acquisition brought back.
pub(crate) struct Acquired {
    /// The scope's acquisitions: one per repetition, or sequences holding several.
    pub captures: Vec<IqCapture>,
    pub tx: Option<RfStatus>,
    pub rx: Option<RfStatus>,
}

async fn open_front(
    catalog: &Catalog,
    entry: &Option<InstrumentEntry>,
    name: &'static str,
    journal: Option<Journal>,
) -> Result<Option<Box<dyn RfFrontEnd>>, MeasureError> {
    let Some(e) = entry else {
        return Ok(None);
    };
    let model: &InstrumentModel = catalog.get(&e.model)?;
    let g = open::open_rf(resource(&e.resource, name)?, model, journal, name).await?;
    Ok(Some(g))
}
