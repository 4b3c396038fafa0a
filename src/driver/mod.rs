//! Layer 3: capability traits and the concrete instrument drivers.
//!
//! Drivers talk to instruments only through a [`Session`](crate::session::Session); they keep every
//! command spelling in one `commands` module per instrument, check values against the catalog's
//! limits before sending anything, and read back what the instrument applied.
//!
//! | driver | capability |
//! |---|---|
//! | [`m8195a::M8195a`] | [`Awg`]: I/Q + marker at 16 GSa/s from extended memory |

mod error;
pub mod m8195a;

use std::future::Future;

pub use error::DriverError;

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
