//! The simulated bench wired together: the M8195A's marker drives the scope's external trigger, its
//! channels 1 and 2 go through the Gotmic Tx, the scene and the Gotmic Rx to the scope's C1 and C2.
//!
//! [`Bench`] owns the four emulators and the shared scene; [`BenchSource`] is the scope's view of
//! the bench (a [`TriggerSource`]): an acquisition completes only when the AWG runs with its marker
//! output on and a marker pulse in the segment, as on the real bench.

use crate::catalog::CatalogError;
use crate::control::SharedScene;
use crate::emulator::gotmic::Gotmic;
use crate::emulator::lecroy::trigger::{AcquisitionRequest, Capture, TriggerSource};
use crate::emulator::lecroy::wavedesc::TriggerTimestamp;
use crate::emulator::lecroy::Lecroy;
use crate::emulator::m8195a::M8195a;
use crate::emulator::m8195a::{ChannelPlayback, Playback};
use crate::scene::{AwgPlayback, FrontEnds, Scene, Synthesizer};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

/// The emulated instruments and the scene between them.
pub struct Bench {
    pub awg: Arc<M8195a>,
    pub scope: Arc<Lecroy>,
    /// The scope inputs (the marker, channels 1 and 2), for the scope the lab serves when it is
    /// not the LeCroy (`crate::emulator::SCOPES`).
    inputs: Arc<BenchSource>,
    pub tx: Arc<Gotmic>,
    pub rx: Arc<Gotmic>,
    pub scene: Arc<SharedScene>,
    /// Whether the marker cable reaches the scope's external trigger input (tests unplug it).
    pub marker_cable: Arc<AtomicBool>,
}

impl Bench {
    /// The bench with the built-in instrument models and `scene` in front of the antennas.
    pub fn new(scene: Scene) -> Result<Bench, CatalogError> {
        Bench::with_front_ends(
            scene,
            crate::catalog::gotmic_tx()?,
            crate::catalog::gotmic_rx()?,
        )
    }

    /// The bench with Tx and Rx modules of the given models (their line protocol and register
    /// map as a catalog file describes them).
    pub(crate) fn with_front_ends(
        scene: Scene,
        tx: crate::catalog::RfModel,
        rx: crate::catalog::RfModel,
    ) -> Result<Bench, CatalogError> {
        let seed = scene.seed;
        let scene = SharedScene::new(scene);
        let awg = Arc::new(M8195a::embedded()?);
        let tx = Arc::new(Gotmic::new(tx)?);
        let rx = Arc::new(Gotmic::new(rx)?);
        let marker_cable = Arc::new(AtomicBool::new(true));
        let source = Arc::new(BenchSource {
            marker_cable: marker_cable.clone(),
            awg: awg.clone(),
            tx: tx.clone(),
            rx: rx.clone(),
            scene: scene.clone(),
            synth: Mutex::new(Synthesizer::new(seed)),
            at_next_trigger: Mutex::new(None),
        });
        let scope = Arc::new(Lecroy::embedded_with(source.clone())?);
        Ok(Bench {
            awg,
            scope,
            inputs: source,
            tx,
            rx,
            scene,
            marker_cable,
        })
    }

    /// The scope inputs, for another scope emulator on the same bench.
    pub(crate) fn inputs(&self) -> Arc<dyn TriggerSource> {
        self.inputs.clone()
    }

    /// Runs `strike` once, when the next marker edge triggers an acquisition, before the scope
    /// records what the channels see: a fault that lands during a capture (a module power-cycled
    /// with RF on), at a moment the tests choose without timing it. Replaces one not yet run.
    pub fn at_next_trigger(&self, strike: impl FnOnce() + Send + 'static) {
        *lock(&self.inputs.at_next_trigger) = Some(Box::new(strike));
    }

    /// Whether anything could radiate or drive an output now: Tx RF on, or an AWG output on, or the
    /// AWG running. Tests use it to check the safe state.
    pub fn is_safe(&self) -> bool {
        let pb = self.awg.playback();
        !self.tx.front_end().rf_enabled && !pb.running && pb.channels.iter().all(|c| !c.output_on)
    }
}

/// The scope's inputs on the bench.
pub struct BenchSource {
    marker_cable: Arc<AtomicBool>,
    awg: Arc<M8195a>,
    tx: Arc<Gotmic>,
    rx: Arc<Gotmic>,
    scene: Arc<SharedScene>,
    synth: Mutex<Synthesizer>,
    /// What to do at the next triggered acquisition ([`Bench::at_next_trigger`]).
    at_next_trigger: Mutex<Option<Box<dyn FnOnce() + Send>>>,
}

fn lock<T>(m: &Mutex<T>) -> std::sync::MutexGuard<'_, T> {
    // Plain data: a panic elsewhere leaves it consistent.
    m.lock().unwrap_or_else(|p| p.into_inner())
}

/// How often a waiting acquisition looks at the AWG again (the AWG may start while the scope waits).
const POLL: Duration = Duration::from_millis(2);

impl BenchSource {
    /// Whether a marker edge that satisfies the trigger setup reaches the scope's external input.
    fn marker_triggers(pb: &Playback, request: &AcquisitionRequest) -> bool {
        let external = matches!(request.trigger.source.as_str(), "EX" | "EX10" | "EXT");
        if !external || !pb.marker_active() {
            return false;
        }
        // The marker is a pulse, so either slope finds an edge (a negative slope would trigger one
        // pulse width later; the model ignores that), provided the level lies between the marker's
        // low and high (EX10 divides the input by ten).
        let Some(marker) = pb.marker_channels.first().and_then(|&ch| pb.channel(ch)) else {
            return false;
        };
        let high = marker.offset_v + marker.amplitude_vpp / 2.0;
        let low = marker.offset_v - marker.amplitude_vpp / 2.0;
        let divider = if request.trigger.source == "EX10" {
            10.0
        } else {
            1.0
        };
        let level = request.trigger.level_v * divider;
        low < level && level < high
    }

    fn synthesise(&self, pb: &Playback, request: &AcquisitionRequest) -> Capture {
        let mut scene = self.scene.snapshot();
        let ch1 = pb.channel(1);
        let ch2 = pb.channel(2);
        let len = ch1.map_or(0, |c| c.samples.len());
        let codes = |c: Option<&ChannelPlayback>| {
            c.filter(|c| c.output_on && c.samples.len() == len)
                .map(|c| c.samples.clone())
        };
        let i = codes(ch1);
        let q = codes(ch2);
        let zeros: Arc<[i8]> = vec![0i8; len].into();
        let i = i.unwrap_or_else(|| zeros.clone());
        let q = q.unwrap_or_else(|| zeros.clone());
        let tx = self.tx.front_end();
        let rx = self.rx.front_end();
        let front = FrontEnds {
            tx_enabled: tx.rf_enabled,
            tx_attenuation_db: tx.attenuation_db,
            rx_enabled: rx.rf_enabled,
            rx_attenuation_db: rx.attenuation_db,
        };
        let awg = AwgPlayback {
            i: &i,
            q: &q,
            sample_rate: ch1.map_or(0.0, |c| c.sample_rate),
            amplitude_vpp: [
                ch1.map_or(0.0, |c| c.amplitude_vpp),
                ch2.map_or(0.0, |c| c.amplitude_vpp),
            ],
            marker_index: first_rising_edge(&pb.markers),
            playing: pb.running && len > 0,
            marker_out: true,
        };
        let mut synth = self.synth.lock().unwrap_or_else(|p| p.into_inner());
        if let Some(seed) = self.scene.take_reseed() {
            synth.reseed(seed);
        }
        let n = request.channels_on.len();
        let mut channels: Vec<Option<Vec<f32>>> = vec![None; n];
        match synth.volts(
            &scene,
            &awg,
            front,
            request.sample_rate,
            request.points,
            request.first_point_s,
        ) {
            Ok((y, _)) => {
                if n > 0 {
                    channels[0] = Some(y.iter().map(|v| v.re as f32).collect());
                }
                if n > 1 {
                    channels[1] = Some(y.iter().map(|v| v.im as f32).collect());
                }
            }
            Err(e) => tracing::warn!(error = %e, "bench: no signal synthesised"),
        }
        // The ground truth holds the simulated clock this capture was made at (the drift's).
        scene.clock_s = synth.last_clock_s();
        drop(synth);
        self.scene.record_capture(scene);
        let rate = ch1.map_or(0.0, |c| c.sample_rate);
        Capture {
            channels,
            trigger_time: now_timestamp(),
            // The marker repeats with the looped segment.
            edge_period_s: (len > 0 && rate > 0.0).then(|| len as f64 / rate),
        }
    }
}

impl TriggerSource for BenchSource {
    fn acquire(&self, request: &AcquisitionRequest, deadline: Instant) -> Option<Capture> {
        loop {
            let pb = self.awg.playback();
            if self.marker_cable.load(Ordering::Relaxed) && Self::marker_triggers(&pb, request) {
                let strike = lock(&self.at_next_trigger).take();
                if let Some(strike) = strike {
                    strike();
                }
                return Some(self.synthesise(&pb, request));
            }
            let now = Instant::now();
            if now >= deadline {
                return None;
            }
            std::thread::sleep(POLL.min(deadline - now));
        }
    }

    fn force(&self, request: &AcquisitionRequest) -> Capture {
        self.synthesise(&self.awg.playback(), request)
    }
}

/// Index of the first 0 -> 1 transition of marker bit 0 (the segment loops, so index 0 counts when
/// the last byte is low); 0 when there is none.
fn first_rising_edge(markers: &[u8]) -> usize {
    let n = markers.len();
    (0..n)
        .find(|&k| markers[k] & 1 != 0 && markers[(k + n - 1) % n] & 1 == 0)
        .unwrap_or(0)
}

fn now_timestamp() -> TriggerTimestamp {
    let secs = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .unwrap_or_default()
        .as_secs_f64();
    let days = (secs / 86_400.0).floor() as i64;
    let rem = secs - days as f64 * 86_400.0;
    let (year, month, day) = civil_from_days(days);
    TriggerTimestamp {
        seconds: rem % 60.0,
        minutes: ((rem / 60.0) as u32 % 60) as u8,
        hours: (rem / 3600.0) as u8,
        day,
        month,
        year,
    }
}

/// Proleptic Gregorian date of a day count since 1970-01-01 (H. Hinnant's algorithm).
fn civil_from_days(days: i64) -> (i16, u8, u8) {
    let z = days + 719_468;
    let era = z.div_euclid(146_097);
    let doe = z.rem_euclid(146_097);
    let yoe = (doe - doe / 1460 + doe / 36_524 - doe / 146_096) / 365;
    let doy = doe - (365 * yoe + yoe / 4 - yoe / 100);
    let mp = (5 * doy + 2) / 153;
    let day = (doy - (153 * mp + 2) / 5 + 1) as u8;
    let month = if mp < 10 { mp + 3 } else { mp - 9 } as u8;
    let year = (yoe + era * 400 + i64::from(month <= 2)) as i16;
    (year, month, day)
}

#[cfg(test)]
mod tests;
