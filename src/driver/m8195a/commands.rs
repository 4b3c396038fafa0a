//! Every SCPI spelling the M8195A driver sends, in one place (instruments.md section 1.4).

use crate::driver::scpi::number;

pub(crate) const ABORT: &str = ":ABOR";
pub(crate) const RUN: &str = ":INIT:IMM";
/// Answers `1` once pending operations (a download) are complete.
pub(crate) const OPC: &str = "*OPC?";
pub(crate) const FUNCTION_ARB: &str = ":FUNC:MODE ARB";
pub(crate) const CONTINUOUS: &str = ":INIT:CONT 1";
pub(crate) const GATE_OFF: &str = ":INIT:GATE 0";
pub(crate) const DAC_MODE_QUERY: &str = ":INST:DACM?";
pub(crate) const DIVIDER_QUERY: &str = ":INST:MEM:EXT:RDIV?";
pub(crate) const RASTER_QUERY: &str = ":FREQ:RAST?";
pub(crate) const REFERENCE_INTERNAL: &str = ":ROSC:SOUR INT";
pub(crate) const REFERENCE_EXTERNAL: &str = ":ROSC:SOUR EXT";
pub(crate) const REFERENCE_QUERY: &str = ":ROSC:SOUR?";

pub(crate) fn reference_frequency(hz: f64) -> String {
    format!(":ROSC:FREQ {}", number(hz))
}

pub(crate) fn dac_mode(keyword: &str) -> String {
    format!(":INST:DACM {keyword}")
}

pub(crate) fn divider(keyword: &str) -> String {
    format!(":INST:MEM:EXT:RDIV {keyword}")
}

pub(crate) fn extended_memory(channel: u8) -> String {
    format!(":TRAC{channel}:MMOD EXT")
}

pub(crate) fn raster(dac_rate_hz: f64) -> String {
    format!(":FREQ:RAST {}", number(dac_rate_hz))
}

pub(crate) fn delete_all(channel: u8) -> String {
    format!(":TRAC{channel}:DEL:ALL")
}

pub(crate) fn define(channel: u8, segment: u32, samples: u64) -> String {
    format!(":TRAC{channel}:DEF {segment},{samples}")
}

/// The header of a chunk; the block follows it directly.
pub(crate) fn data_header(channel: u8, segment: u32, offset_samples: u64) -> String {
    format!(":TRAC{channel}:DATA {segment},{offset_samples},")
}

pub(crate) fn select(channel: u8, segment: u32) -> String {
    format!(":TRAC{channel}:SEL {segment}")
}

pub(crate) fn catalog_query(channel: u8) -> String {
    format!(":TRAC{channel}:CAT?")
}

pub(crate) fn amplitude(channel: u8, vpp: f64) -> String {
    format!(":VOLT{channel} {}", number(vpp))
}

pub(crate) fn amplitude_query(channel: u8) -> String {
    format!(":VOLT{channel}?")
}

pub(crate) fn offset(channel: u8, volts: f64) -> String {
    format!(":VOLT{channel}:OFFS {}", number(volts))
}

pub(crate) fn marker_amplitude(channel: u8, volts: f64) -> String {
    format!(":VOLT{channel}:AMPL {}", number(volts))
}

pub(crate) fn marker_amplitude_query(channel: u8) -> String {
    format!(":VOLT{channel}:AMPL?")
}

pub(crate) fn offset_query(channel: u8) -> String {
    format!(":VOLT{channel}:OFFS?")
}

pub(crate) fn output(channel: u8, on: bool) -> String {
    format!(":OUTP{channel} {}", if on { "ON" } else { "OFF" })
}

pub(crate) fn output_query(channel: u8) -> String {
    format!(":OUTP{channel}?")
}
