//! Every SCPI spelling the M8195A driver sends, in one place (instruments.md section 1.4).

use crate::driver::scpi::number;

pub const ABORT: &str = ":ABOR";
pub const RUN: &str = ":INIT:IMM";
/// Answers `1` once pending operations (a download) are complete.
pub const OPC: &str = "*OPC?";
pub const FUNCTION_ARB: &str = ":FUNC:MODE ARB";
pub const CONTINUOUS: &str = ":INIT:CONT 1";
pub const GATE_OFF: &str = ":INIT:GATE 0";
pub const DAC_MODE_QUERY: &str = ":INST:DACM?";
pub const DIVIDER_QUERY: &str = ":INST:MEM:EXT:RDIV?";
pub const RASTER_QUERY: &str = ":FREQ:RAST?";
pub const REFERENCE_INTERNAL: &str = ":ROSC:SOUR INT";
pub const REFERENCE_EXTERNAL: &str = ":ROSC:SOUR EXT";
pub const REFERENCE_QUERY: &str = ":ROSC:SOUR?";

pub fn reference_frequency(hz: f64) -> String {
    format!(":ROSC:FREQ {}", number(hz))
}

pub fn dac_mode(keyword: &str) -> String {
    format!(":INST:DACM {keyword}")
}

pub fn divider(keyword: &str) -> String {
    format!(":INST:MEM:EXT:RDIV {keyword}")
}

pub fn extended_memory(channel: u8) -> String {
    format!(":TRAC{channel}:MMOD EXT")
}

pub fn raster(dac_rate_hz: f64) -> String {
    format!(":FREQ:RAST {}", number(dac_rate_hz))
}

pub fn delete_all(channel: u8) -> String {
    format!(":TRAC{channel}:DEL:ALL")
}

pub fn define(channel: u8, segment: u32, samples: u64) -> String {
    format!(":TRAC{channel}:DEF {segment},{samples}")
}

/// The header of a chunk; the block follows it directly.
pub fn data_header(channel: u8, segment: u32, offset_samples: u64) -> String {
    format!(":TRAC{channel}:DATA {segment},{offset_samples},")
}

pub fn select(channel: u8, segment: u32) -> String {
    format!(":TRAC{channel}:SEL {segment}")
}

pub fn catalog_query(channel: u8) -> String {
    format!(":TRAC{channel}:CAT?")
}

pub fn amplitude(channel: u8, vpp: f64) -> String {
    format!(":VOLT{channel} {}", number(vpp))
}

pub fn amplitude_query(channel: u8) -> String {
    format!(":VOLT{channel}?")
}

pub fn offset(channel: u8, volts: f64) -> String {
    format!(":VOLT{channel}:OFFS {}", number(volts))
}

pub fn marker_amplitude(channel: u8, volts: f64) -> String {
    format!(":VOLT{channel}:AMPL {}", number(volts))
}

pub fn marker_amplitude_query(channel: u8) -> String {
    format!(":VOLT{channel}:AMPL?")
}

pub fn offset_query(channel: u8) -> String {
    format!(":VOLT{channel}:OFFS?")
}

pub fn output(channel: u8, on: bool) -> String {
    format!(":OUTP{channel} {}", if on { "ON" } else { "OFF" })
}

pub fn output_query(channel: u8) -> String {
    format!(":OUTP{channel}?")
}
