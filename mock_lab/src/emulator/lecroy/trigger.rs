//! What the scope's inputs see: a pluggable source that says whether a marker edge arrives and what
//! the channels see for that acquisition. The bench wiring (AWG marker -> scope EXT, the scene's
//! echoes on C1/C2) implements [`TriggerSource`]; [`TestSignal`] is a simple, configurable stand-in.

use std::sync::{Condvar, Mutex};
use std::time::Instant;

use super::wavedesc::TriggerTimestamp;

/// Trigger edge slope.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Slope {
    Positive,
    Negative,
    Either,
}

/// The trigger setup at arming time.
#[derive(Debug, Clone, PartialEq)]
pub struct TriggerSetup {
    /// `EX`, `EX10`, `C1`..`C4`, `LINE`.
    pub source: String,
    pub level_v: f64,
    pub slope: Slope,
}

/// What one acquisition records.
#[derive(Debug, Clone, PartialEq)]
pub struct AcquisitionRequest {
    pub sample_rate: f64,
    /// Points per channel.
    pub points: usize,
    /// Time of the first point relative to the trigger edge, in seconds (WAVEDESC HORIZ_OFFSET).
    pub first_point_s: f64,
    pub trigger: TriggerSetup,
    /// Channels switched on (index 0 = C1).
    pub channels_on: Vec<bool>,
}

impl AcquisitionRequest {
    /// Time of point `i` relative to the trigger edge.
    pub(crate) fn time_of(&self, i: usize) -> f64 {
        self.first_point_s + i as f64 / self.sample_rate
    }
}

/// What the channels saw in one acquisition.
#[derive(Debug, Clone, PartialEq)]
pub struct Capture {
    /// Volts at the inputs per channel (index 0 = C1), `points` long; `None` = input not driven (0 V).
    pub channels: Vec<Option<Vec<f32>>>,
    /// When the trigger happened (written to WAVEDESC TRIGGER_TIME).
    pub trigger_time: TriggerTimestamp,
    /// Time between one trigger edge and the next (the AWG's repetition period), when edges
    /// repeat; a sequence-mode acquisition records one segment per edge it can catch.
    pub edge_period_s: Option<f64>,
}

/// The scope's view of the bench.
pub trait TriggerSource: Send + Sync + 'static {
    /// Waits until a trigger edge matching `request.trigger` arrives, but not past `deadline`; returns
    /// what the channels saw for the acquisition at that edge, or `None` when no edge arrived in time.
    /// Called with a deadline already past to poll without blocking.
    fn acquire(&self, request: &AcquisitionRequest, deadline: Instant) -> Option<Capture>;

    /// What the channels see without a trigger edge (forced trigger `FRTR`, AUTO mode).
    fn force(&self, request: &AcquisitionRequest) -> Capture;
}

/// A configurable test signal: a complex tone `I = A cos(2 pi f t + phi)`, `Q = A sin(...)` on C1/C2,
/// and a marker edge on the external input that can be switched on and off (waking any waiter).
pub struct TestSignal {
    settings: Mutex<TestSettings>,
    changed: Condvar,
}

/// Settings of [`TestSignal`].
#[derive(Debug, Clone, PartialEq)]
pub struct TestSettings {
    /// A marker edge arrives on every acquisition while true.
    pub marker: bool,
    pub tone_hz: f64,
    pub amplitude_v: f64,
    pub phase_rad: f64,
    /// Acquisitions so far (advances the trigger time stamp by one second each).
    pub acquisitions: u64,
}

impl Default for TestSignal {
    fn default() -> Self {
        TestSignal::new(true, 1e9, 0.1)
    }
}

impl TestSignal {
    pub fn new(marker: bool, tone_hz: f64, amplitude_v: f64) -> TestSignal {
        TestSignal {
            settings: Mutex::new(TestSettings {
                marker,
                tone_hz,
                amplitude_v,
                phase_rad: 0.0,
                acquisitions: 0,
            }),
            changed: Condvar::new(),
        }
    }

    /// Switches the marker on or off; a waiting acquisition sees the change at once.
    pub fn set_marker(&self, present: bool) {
        self.lock().marker = present;
        self.changed.notify_all();
    }

    pub fn settings(&self) -> TestSettings {
        self.lock().clone()
    }

    fn lock(&self) -> std::sync::MutexGuard<'_, TestSettings> {
        self.settings.lock().unwrap_or_else(|e| e.into_inner())
    }

    fn capture(&self, s: &mut TestSettings, request: &AcquisitionRequest) -> Capture {
        let seconds = s.acquisitions as f64;
        s.acquisitions += 1;
        let w = 2.0 * std::f64::consts::PI * s.tone_hz;
        let tone = |f: fn(f64) -> f64| -> Vec<f32> {
            (0..request.points)
                .map(|i| (s.amplitude_v * f(w * request.time_of(i) + s.phase_rad)) as f32)
                .collect()
        };
        let mut channels: Vec<Option<Vec<f32>>> = vec![None; request.channels_on.len()];
        if let Some(c1) = channels.get_mut(0) {
            *c1 = Some(tone(f64::cos));
        }
        if let Some(c2) = channels.get_mut(1) {
            *c2 = Some(tone(f64::sin));
        }
        Capture {
            channels,
            trigger_time: TriggerTimestamp {
                seconds: seconds % 60.0,
                minutes: ((seconds / 60.0) as u64 % 60) as u8,
                hours: 0,
                day: 1,
                month: 1,
                year: 2026,
            },
            edge_period_s: None,
        }
    }
}

impl TriggerSource for TestSignal {
    fn acquire(&self, request: &AcquisitionRequest, deadline: Instant) -> Option<Capture> {
        let mut s = self.lock();
        loop {
            if s.marker {
                return Some(self.capture(&mut s, request));
            }
            let now = Instant::now();
            if now >= deadline {
                return None;
            }
            s = self
                .changed
                .wait_timeout(s, deadline - now)
                .unwrap_or_else(|e| e.into_inner())
                .0;
        }
    }

    fn force(&self, request: &AcquisitionRequest) -> Capture {
        let mut s = self.lock();
        self.capture(&mut s, request)
    }
}
