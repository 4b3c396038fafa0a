//! Every command spelling of the Infiniium driver (sources and certainty: instruments/README.md,
//! "Keysight Infiniium UXR").

use crate::driver::capability::Slope;
use crate::driver::scpi::number;

/// Response headers off, so queries answer bare values.
pub(crate) const HEADERS_OFF: &str = ":SYSTem:HEADer OFF";
/// 16-bit signed words, least significant byte first, one block per query.
pub(crate) const WORD_FORMAT: &str = ":WAVeform:FORMat WORD";
pub(crate) const LSB_FIRST: &str = ":WAVeform:BYTeorder LSBFirst";
pub(crate) const STREAMING_OFF: &str = ":WAVeform:STReaming OFF";
/// Real-time (one trigger per acquisition) or segmented memory (one segment per trigger).
pub(crate) const REAL_TIME: &str = ":ACQuire:MODE RTIMe";
pub(crate) const SEGMENTED: &str = ":ACQuire:MODE SEGMented";
pub(crate) const SEGMENTS_QUERY: &str = ":ACQuire:SEGMented:COUNt?";
/// Every segment in one `:WAVeform:DATA?` block.
pub(crate) const ALL_SEGMENTS: &str = ":WAVeform:SEGMented:ALL ON";
/// Trigger time tags of the segments, seconds from the first.
pub(crate) const TIME_TAGS: &str = ":WAVeform:SEGMented:XLISt? TTAG";
pub(crate) const SAMPLE_RATE_QUERY: &str = ":ACQuire:SRATe:ANALog?";
pub(crate) const POINTS_QUERY: &str = ":ACQuire:POINts:ANALog?";
pub(crate) const REFERENCE_LEFT: &str = ":TIMebase:REFerence LEFT";
pub(crate) const EXTERNAL_REFERENCE: &str = ":TIMebase:REFClock ON";
pub(crate) const REFERENCE_QUERY: &str = ":TIMebase:REFClock?";
pub(crate) const EDGE_MODE: &str = ":TRIGger:MODE EDGE";
pub(crate) const TRIGGERED_SWEEP: &str = ":TRIGger:SWEep TRIGgered";
pub(crate) const SINGLE: &str = ":SINGle";
pub(crate) const STOP: &str = ":STOP";
/// Acquisition Done Event Register: 1 once the armed acquisition completed (reading clears it).
pub(crate) const ACQUISITION_DONE: &str = ":ADER?";
pub(crate) const PREAMBLE: &str = ":WAVeform:PREamble?";
pub(crate) const DATA: &str = ":WAVeform:DATA?";

pub(crate) fn channel_on(ch: u8) -> String {
    format!(":CHANnel{ch}:DISPlay ON")
}

pub(crate) fn scale(ch: u8, volts_per_div: f64) -> String {
    format!(":CHANnel{ch}:SCALe {}", number(volts_per_div))
}

pub(crate) fn offset(ch: u8, volts: f64) -> String {
    format!(":CHANnel{ch}:OFFSet {}", number(volts))
}

pub(crate) fn segments(count: u32) -> String {
    format!(":ACQuire:SEGMented:COUNt {count}")
}

pub(crate) fn sample_rate(hz: f64) -> String {
    format!(":ACQuire:SRATe:ANALog {}", number(hz))
}

pub(crate) fn points(points: u64) -> String {
    format!(":ACQuire:POINts:ANALog {points}")
}

pub(crate) fn hor_scale(seconds_per_div: f64) -> String {
    format!(":TIMebase:SCALe {}", number(seconds_per_div))
}

/// With the reference at the left edge, the time from the trigger to the record's first point.
pub(crate) fn position(seconds: f64) -> String {
    format!(":TIMebase:POSition {}", number(seconds))
}

pub(crate) fn edge_source(source: &str) -> String {
    format!(":TRIGger:EDGE:SOURce {source}")
}

pub(crate) fn trigger_level(source: &str, volts: f64) -> String {
    format!(":TRIGger:LEVel {source},{}", number(volts))
}

pub(crate) fn trigger_slope(slope: Slope) -> String {
    let s = match slope {
        Slope::Positive => "POSitive",
        Slope::Negative => "NEGative",
    };
    format!(":TRIGger:EDGE:SLOPe {s}")
}

pub(crate) fn source(ch: u8) -> String {
    format!(":WAVeform:SOURce CHANnel{ch}")
}
