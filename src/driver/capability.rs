//! Capability traits (what the measurement layer asks of an AWG, a digitizer, an RF front end) and
//! their plain-data settings and read-backs.
//!
//! The traits are object-safe (methods return [`BoxFuture`]) so a bench holds
//! `Box<dyn Awg>`, `Box<dyn Digitizer>` and `Box<dyn RfFrontEnd>` whatever the model. Settings are
//! plain data (serde) so a campaign plan can print them before anything moves; read-backs report
//! what the instrument actually applied, for the run manifest.

use serde::{Deserialize, Serialize};

use super::error::DriverError;
use super::io::BoxFuture;
use super::permit::RfPermit;
use super::trace::{ChannelTrace, IqCapture};
use crate::catalog::RfDirection;
use crate::session::Identity;

/// Where the AWG's sample clock reference comes from. Share a 10 MHz reference with the scope so
/// the 80 -> 16 GSa/s relationship stays phase-stable over long records (instruments.md section 8).
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case", tag = "source", deny_unknown_fields)]
pub enum ReferenceClock {
    #[default]
    Internal,
    External {
        frequency_hz: f64,
    },
}

/// I/Q playback settings of an AWG (I on one channel, Q on another, a marker each repetition).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct AwgSettings {
    /// The memory (playback) sample rate, e.g. 16e9; the driver picks the DAC raster and divider.
    pub sample_rate_hz: f64,
    pub i_amplitude_vpp: f64,
    pub q_amplitude_vpp: f64,
    pub i_offset_v: f64,
    pub q_offset_v: f64,
    /// Marker output swing (high - low), volts.
    pub marker_amplitude_v: f64,
    /// Marker output centre ((high + low) / 2), volts.
    pub marker_offset_v: f64,
    pub reference_clock: ReferenceClock,
}

impl Default for AwgSettings {
    fn default() -> Self {
        Self {
            sample_rate_hz: 16e9,
            i_amplitude_vpp: 0.5,
            q_amplitude_vpp: 0.5,
            i_offset_v: 0.0,
            q_offset_v: 0.0,
            marker_amplitude_v: 0.5,
            marker_offset_v: 0.25,
            reference_clock: ReferenceClock::Internal,
        }
    }
}

/// One repetition of the waveform as DAC codes, and its marker.
#[derive(Debug, Clone, PartialEq)]
pub struct IqWaveform {
    pub i: Vec<i8>,
    pub q: Vec<i8>,
    /// The marker is high on the first this-many samples of every repetition (one pulse per
    /// repetition: the scope's trigger).
    pub marker_high_samples: usize,
}

/// What a download put in the AWG's memory.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct LoadedSegment {
    pub segment_id: u32,
    /// Samples given by the caller.
    pub samples: u64,
    /// Samples in the segment after padding with zeros to the granularity and minimum length:
    /// the repetition period of the playback is `padded_samples / sample_rate`.
    pub padded_samples: u64,
    pub marker_high_samples: u64,
    /// `:TRAC:DATA` chunks sent per channel.
    pub chunks_per_channel: usize,
}

/// One segment as the AWG lists it (`:TRAC:CAT?`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
pub struct SegmentEntry {
    pub id: u32,
    pub samples: u64,
}

/// The state of one output.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
pub struct OutputState {
    pub channel: u8,
    pub on: bool,
}

/// What the AWG reports it applied.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct AwgApplied {
    pub dac_mode: String,
    pub divider: u32,
    pub dac_rate_hz: f64,
    /// `dac_rate_hz / divider`: the rate the segment plays at.
    pub sample_rate_hz: f64,
    pub segments: Vec<SegmentEntry>,
    pub i_amplitude_vpp: f64,
    pub q_amplitude_vpp: f64,
    pub marker_amplitude_v: f64,
    pub marker_offset_v: f64,
    /// The reference source as the AWG reports it (`INT`, `EXT`, `AXI`).
    pub reference_source: String,
    pub outputs: Vec<OutputState>,
}

/// An arbitrary waveform generator playing I/Q with a marker.
///
/// Order of use: [`configure`](Awg::configure), [`load`](Awg::load),
/// [`enable_outputs`](Awg::enable_outputs), [`run`](Awg::run); [`safe_state`](Awg::safe_state)
/// on every exit.
pub trait Awg: Send {
    /// The `*IDN?` reply read when the driver connected.
    fn identity(&self) -> &Identity;
    /// Stops playback, sets DAC mode, sample clock, amplitudes and marker levels; checks the
    /// error queue after each batch and reads back the clock.
    fn configure<'a>(
        &'a mut self,
        settings: &'a AwgSettings,
    ) -> BoxFuture<'a, Result<AwgApplied, DriverError>>;
    /// Defines the segment and downloads I, Q and the marker.
    fn load<'a>(
        &'a mut self,
        waveform: &'a IqWaveform,
    ) -> BoxFuture<'a, Result<LoadedSegment, DriverError>>;
    /// Switches the I, Q and marker outputs on.
    fn enable_outputs<'a>(
        &'a mut self,
        permit: &'a RfPermit,
    ) -> BoxFuture<'a, Result<(), DriverError>>;
    /// Switches the marker output on and nothing else: the I and Q outputs stay off, so nothing
    /// reaches the transmitter's input. Needs no permit (the marker only feeds the scope's
    /// trigger); the bench doctor uses it to see the marker reach the scope.
    fn enable_marker(&mut self) -> BoxFuture<'_, Result<(), DriverError>>;
    /// Switches every output off.
    fn outputs_off(&mut self) -> BoxFuture<'_, Result<(), DriverError>>;
    /// Starts playback (the last command of a setup).
    fn run(&mut self) -> BoxFuture<'_, Result<(), DriverError>>;
    /// Stops playback.
    fn stop(&mut self) -> BoxFuture<'_, Result<(), DriverError>>;
    /// Reads back what the instrument applied.
    fn applied(&mut self) -> BoxFuture<'_, Result<AwgApplied, DriverError>>;
    /// Outputs off, then stop; tries every step even when one fails and returns the first error.
    fn safe_state(&mut self) -> BoxFuture<'_, Result<(), DriverError>>;
}

/// Edge direction of the trigger.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Slope {
    Positive,
    Negative,
}

/// Capture settings: I on the first channel, Q on the second, triggered by the AWG's marker on
/// the external trigger input.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct DigitizerSettings {
    /// Fixed sample rate, e.g. 80e9 (must be one of the catalog's rates).
    pub sample_rate_hz: f64,
    /// One repetition of the played waveform, seconds.
    pub repetition_s: f64,
    /// The longest echo delay to capture after one repetition (farthest target, cables), seconds.
    pub longest_echo_s: f64,
    /// Time captured before the trigger, seconds.
    pub pre_trigger_s: f64,
    pub i_volts_per_div: f64,
    pub q_volts_per_div: f64,
    pub i_offset_v: f64,
    pub q_offset_v: f64,
    /// External trigger level, volts (the marker's mid level).
    pub trigger_level_v: f64,
    pub trigger_slope: Slope,
    /// Lock the timebase to the external 10 MHz reference shared with the AWG (`RCLK EXTERNAL`);
    /// when false the scope's reference setting is left as it is.
    pub external_reference: bool,
    /// Triggers recorded by one acquisition: 1 records one; more uses the scope's sequence mode
    /// (one segment per trigger), which the catalog must say the model has.
    pub segments: u32,
}

impl Default for DigitizerSettings {
    fn default() -> Self {
        Self {
            sample_rate_hz: 80e9,
            repetition_s: 10e-6,
            longest_echo_s: 100e-9,
            pre_trigger_s: 0.0,
            i_volts_per_div: 0.05,
            q_volts_per_div: 0.05,
            i_offset_v: 0.0,
            q_offset_v: 0.0,
            trigger_level_v: 0.2,
            trigger_slope: Slope::Positive,
            external_reference: false,
            segments: 1,
        }
    }
}

impl DigitizerSettings {
    /// The time the record must cover: pre-trigger, one repetition and the longest echo.
    pub fn record_s(&self) -> f64 {
        self.pre_trigger_s + self.repetition_s + self.longest_echo_s
    }
}

/// What the digitizer reports it applied.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct DigitizerApplied {
    pub sample_rate_hz: f64,
    /// Time per horizontal division, seconds.
    pub hor_scale_s: f64,
    /// The whole record (divisions x scale), seconds.
    pub record_s: f64,
    /// Points per channel (rate x record).
    pub points: u64,
    /// The trigger delay sent so the record starts `pre_trigger_s` before the trigger.
    pub trigger_delay_s: f64,
    pub trigger_source: String,
    pub trigger_level_v: f64,
    /// Segments per acquisition (1 unless in sequence mode).
    pub segments: u32,
}

/// A digitizer capturing I and Q on one external trigger.
pub trait Digitizer: Send {
    fn identity(&self) -> &Identity;
    /// Sets transfer format, channels, fixed sample rate, record length and trigger; checks the
    /// instrument's error registers and reads back what it applied.
    fn configure<'a>(
        &'a mut self,
        settings: &'a DigitizerSettings,
    ) -> BoxFuture<'a, Result<DigitizerApplied, DriverError>>;
    /// Arms a single acquisition (of every configured segment) and waits up to `wait_s` for
    /// its triggers.
    fn acquire(&mut self, wait_s: f64) -> BoxFuture<'_, Result<(), DriverError>>;
    /// Reads one channel (1-based) of the last acquisition, all its segments.
    fn fetch(&mut self, channel: u8) -> BoxFuture<'_, Result<ChannelTrace, DriverError>>;
    /// [`acquire`](Digitizer::acquire), then I (first channel) and Q (second channel), checked to
    /// hold the configured number of segments.
    fn capture_iq(&mut self, wait_s: f64) -> BoxFuture<'_, Result<IqCapture, DriverError>>;
    /// Disarms (no acquisition left pending).
    fn stop(&mut self) -> BoxFuture<'_, Result<(), DriverError>>;
    /// Where the timebase's reference comes from, as the instrument says it (`INTERNAL`,
    /// `EXTERNAL`, ...; the bench doctor compares it with the AWG's).
    fn reference_clock(&mut self) -> BoxFuture<'_, Result<String, DriverError>>;
}

/// Settings of an RF up- or down-converter.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct RfSettings {
    /// Attenuation once enabled, dB (the module starts at maximum attenuation).
    pub attenuation_db: f64,
    /// LO frequency to record in the module (informational register), Hz.
    pub lo_frequency_hz: Option<f64>,
}

impl Default for RfSettings {
    fn default() -> Self {
        Self {
            attenuation_db: 10.0,
            lo_frequency_hz: None,
        }
    }
}

/// What an RF module reports.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct RfStatus {
    pub powered: bool,
    pub lo_locked: bool,
    pub rf_enabled: bool,
    pub over_temperature: bool,
    pub interlock_open: bool,
    pub temperature_c: f64,
    pub attenuation_db: f64,
    /// Names of the latched faults.
    pub faults: Vec<String>,
    /// The raw CONTROL register.
    pub control: u16,
}

/// What [`RfFrontEnd::check_before_enable`] found: the module may be switched on with
/// [`RfFrontEnd::enable_checked`]. Only a driver makes one.
#[derive(Debug, Clone)]
pub struct ReadyToEnable {
    /// The checked instrument, so the check of one module cannot switch on another.
    pub(crate) instrument: String,
    /// The attenuation to apply once enabled, in the module's register code.
    pub(crate) attenuation_code: u16,
    /// The module as read by the check.
    pub(crate) before: RfStatus,
}

impl ReadyToEnable {
    /// The module as the check read it (maximum attenuation, RF still off).
    pub fn status(&self) -> &RfStatus {
        &self.before
    }
}

/// An RF front end (transmitter or receiver module).
pub trait RfFrontEnd: Send {
    fn identity(&self) -> &Identity;
    fn direction(&self) -> RfDirection;
    /// Reads status, LO lock, temperature, attenuation and latched faults.
    fn status(&mut self) -> BoxFuture<'_, Result<RfStatus, DriverError>>;
    /// Sets the attenuation (rounded to the module's step); returns what was applied, in dB.
    fn set_attenuation(&mut self, db: f64) -> BoxFuture<'_, Result<f64, DriverError>>;
    /// Maximum attenuation, enable, check lock and status, then the requested attenuation.
    fn enable<'a>(
        &'a mut self,
        permit: &'a RfPermit,
        settings: &'a RfSettings,
    ) -> BoxFuture<'a, Result<RfStatus, DriverError>>;
    /// The first half of [`enable`](Self::enable), radiating nothing: settings within limits,
    /// no latched fault, temperature and interlock fine, attenuation at maximum. Lets a caller
    /// check every module of the bench before it switches any of them on.
    fn check_before_enable<'a>(
        &'a mut self,
        settings: &'a RfSettings,
    ) -> BoxFuture<'a, Result<ReadyToEnable, DriverError>>;
    /// The second half: enable, check lock and status, then the requested attenuation; on any
    /// failure RF is switched off again.
    fn enable_checked<'a>(
        &'a mut self,
        permit: &'a RfPermit,
        ready: ReadyToEnable,
    ) -> BoxFuture<'a, Result<RfStatus, DriverError>>;
    /// Reads the module back after a capture (its status registers, each exchange within the
    /// link's own deadline) and checks it is still as [`enable_checked`](Self::enable_checked)
    /// left it: `enabled` is what that returned (RF on, CONTROL, the attenuation). A module that
    /// was reset or lost power during the capture radiated (or received) nothing since, and
    /// nothing else in the capture fails. Returns the module as read.
    ///
    /// # Errors
    ///
    /// [`DriverError::StateLost`] when it is not as it was left (back at its power-on state, RF
    /// off, other settings) or cannot be read back (silent, or answering as a module at power-on
    /// does); [`DriverError::RfNotReady`] when RF went off with a latched fault (interlock, LO,
    /// temperature: not a glitch).
    fn confirm_enabled<'a>(
        &'a mut self,
        enabled: &'a RfStatus,
    ) -> BoxFuture<'a, Result<RfStatus, DriverError>>;
    /// RF off and maximum attenuation; tries both even when one fails.
    fn disable(&mut self) -> BoxFuture<'_, Result<(), DriverError>>;
    /// Clears the latched faults (an explicit user action: the driver never clears them itself).
    fn clear_faults(&mut self) -> BoxFuture<'_, Result<(), DriverError>>;
}
