//! Layer 3: capability traits and the concrete instrument drivers.
//!
//! Drivers talk to instruments only through a [`Session`](crate::session::Session); they keep every
//! command spelling in one `commands` module per instrument, check values against the catalog's
//! limits before sending anything, and read back what the instrument applied.
//!
//! | driver | capability |
//! |---|---|
//! | [`m8195a::M8195a`] | [`Awg`]: I/Q + marker at 16 GSa/s from extended memory |
//! | [`lecroy::Lecroy`] | [`Digitizer`]: marker-triggered single shots at 80 GSa/s, `WF? ALL` decoded |
//! | [`gotmic::Gotmic`] | [`RfFrontEnd`]: E-band Tx/Rx over the project-defined register protocol |

mod error;
pub mod gotmic;
pub mod lecroy;
pub mod m8195a;

use std::future::Future;
use std::time::Duration;

use crate::catalog::{pattern_matches, InstrumentModel};
use crate::session::Identity;

pub use error::DriverError;

/// `true` when an `*IDN?` reply names `model` (vendor patterns or its mock_lab emulator).
pub fn identity_matches(model: &InstrumentModel, idn: &Identity) -> bool {
    let id = &model.identity;
    let vendor = id
        .manufacturer
        .iter()
        .any(|p| pattern_matches(p, &idn.manufacturer))
        && id.model.iter().any(|p| pattern_matches(p, &idn.model));
    let emulator = id
        .emulator
        .manufacturer
        .eq_ignore_ascii_case(&idn.manufacturer)
        && id.emulator.model.eq_ignore_ascii_case(&idn.model);
    vendor || emulator
}

/// What the AWG should generate: memory sample rate, I/Q amplitude and marker levels.
#[derive(Debug, Clone, PartialEq)]
pub struct AwgSetup {
    /// Samples per second read from memory (e.g. 16e9); the driver picks raster and divider.
    pub sample_rate: f64,
    /// Peak-to-peak amplitude of the I and Q outputs, in volts.
    pub amplitude_vpp: f64,
    /// Marker output low and high levels, in volts.
    pub marker_low_v: f64,
    pub marker_high_v: f64,
}

/// One repetition of a baseband I/Q waveform as DAC codes, with the marker bits per sample.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct IqWaveform {
    pub i: Vec<i8>,
    pub q: Vec<i8>,
    /// Marker level per sample (true = high); drives the scope's trigger.
    pub marker: Vec<bool>,
}

impl IqWaveform {
    /// A waveform whose marker is high on the first `marker_samples` samples of each repetition.
    pub fn with_leading_marker(i: Vec<i8>, q: Vec<i8>, marker_samples: usize) -> Self {
        let marker = (0..i.len()).map(|k| k < marker_samples).collect();
        IqWaveform { i, q, marker }
    }
}

/// What the AWG reports it applied.
#[derive(Debug, Clone, PartialEq)]
pub struct AwgApplied {
    pub dac_mode: String,
    pub divider: u32,
    pub dac_rate: f64,
    pub sample_rate: f64,
    /// Samples in the playing segment (after padding to the granularity), 0 when none.
    pub segment_samples: u64,
    pub amplitude_vpp: [f64; 2],
    /// Output state of channels 1..=4.
    pub outputs: [bool; 4],
}

/// An arbitrary waveform generator playing I/Q with a trigger marker.
pub trait Awg {
    /// Applies the setup (mode, rates, levels); refuses values outside the catalog limits.
    fn configure(
        &mut self,
        setup: &AwgSetup,
    ) -> impl Future<Output = Result<AwgApplied, DriverError>> + Send;
    /// Downloads one repetition (padded to the granularity) and selects it; returns the padded length.
    fn load(
        &mut self,
        waveform: &IqWaveform,
    ) -> impl Future<Output = Result<u64, DriverError>> + Send;
    /// Switches the I, Q and marker outputs.
    fn set_outputs(&mut self, on: bool) -> impl Future<Output = Result<(), DriverError>> + Send;
    /// Starts playing (continuously repeating).
    fn run(&mut self) -> impl Future<Output = Result<(), DriverError>> + Send;
    /// Stops playing.
    fn stop(&mut self) -> impl Future<Output = Result<(), DriverError>> + Send;
    /// Reads back what the instrument applied.
    fn applied(&mut self) -> impl Future<Output = Result<AwgApplied, DriverError>> + Send;
}

/// What the digitizer should record.
#[derive(Debug, Clone, PartialEq)]
pub struct DigitizerSetup {
    /// Samples per second (must be one of the catalog's rates).
    pub sample_rate: f64,
    /// Seconds recorded after the trigger: one repetition plus the longest echo.
    pub record_seconds: f64,
    /// Level of the marker edge on the external trigger input, in volts.
    pub trigger_level_v: f64,
    /// Vertical scale of the I and Q channels.
    pub volts_per_div: f64,
}

/// What the digitizer reports it applied.
#[derive(Debug, Clone, PartialEq)]
pub struct DigitizerApplied {
    pub sample_rate: f64,
    /// Points per channel per acquisition.
    pub points: u64,
}

/// A digitizer that records I and Q after a marker edge.
pub trait Digitizer {
    fn configure(
        &mut self,
        setup: &DigitizerSetup,
    ) -> impl Future<Output = Result<DigitizerApplied, DriverError>> + Send;
    /// Arms a single acquisition and waits for the marker edge, at most `timeout`.
    fn acquire(
        &mut self,
        timeout: Duration,
    ) -> impl Future<Output = Result<(), DriverError>> + Send;
    /// Reads one channel of the last acquisition.
    fn read(
        &mut self,
        channel: u8,
    ) -> impl Future<Output = Result<lecroy::Trace, DriverError>> + Send;
    fn applied(&mut self) -> impl Future<Output = Result<DigitizerApplied, DriverError>> + Send;
}

/// Explicit permission to enable an RF output. Constructing one is the deliberate act: code that
/// may radiate takes `&RfPermit`, so it cannot be called by accident.
#[derive(Debug)]
pub struct RfPermit {
    reason: String,
}

impl RfPermit {
    /// Grants a permit; `reason` is logged (who or what allowed RF, e.g. the campaign file).
    pub fn grant(reason: impl Into<String>) -> RfPermit {
        let reason = reason.into();
        tracing::warn!(%reason, "RF permit granted");
        RfPermit { reason }
    }

    pub fn reason(&self) -> &str {
        &self.reason
    }
}

/// An RF front end's read-back.
#[derive(Debug, Clone, PartialEq)]
pub struct RfStatus {
    pub lo_locked: bool,
    pub rf_enabled: bool,
    pub over_temperature: bool,
    pub interlock_open: bool,
    pub temperature_c: f64,
    pub attenuation_db: f64,
    /// Latched faults (bit meanings in the catalog's register map).
    pub fault_latch: u16,
}

/// An up- or down-converter module.
pub trait RfFrontEnd {
    fn status(&mut self) -> impl Future<Output = Result<RfStatus, DriverError>> + Send;
    /// Sets the attenuation; returns what was applied (rounded to the step).
    fn set_attenuation_db(
        &mut self,
        db: f64,
    ) -> impl Future<Output = Result<f64, DriverError>> + Send;
    /// Enables RF: maximum attenuation first, enable, verify STATUS, then the requested attenuation.
    fn enable(
        &mut self,
        permit: &RfPermit,
        attenuation_db: f64,
    ) -> impl Future<Output = Result<RfStatus, DriverError>> + Send;
    /// Disables RF and verifies it is off (the safe state).
    fn disable(&mut self) -> impl Future<Output = Result<(), DriverError>> + Send;
    /// Clears latched faults; returns the bits that were latched.
    fn clear_faults(&mut self) -> impl Future<Output = Result<u16, DriverError>> + Send;
}
