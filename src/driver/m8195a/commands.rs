//! Every M8195A command spelling the driver sends, in one place (instruments.md section 1.4).

pub const ABORT: &str = ":ABOR";
pub const FUNCTION_ARB: &str = ":FUNC:MODE ARB";
pub const CONTINUOUS_ON: &str = ":INIT:CONT 1";
pub const GATE_OFF: &str = ":INIT:GATE 0";
pub const RUN: &str = ":INIT:IMM";
pub const DAC_MODE_QUERY: &str = ":INST:DACM?";
pub const DIVIDER_QUERY: &str = ":INST:MEM:EXT:RDIV?";
pub const RASTER_QUERY: &str = ":FREQ:RAST?";

pub fn dac_mode(keyword: &str) -> String {
    format!(":INST:DACM {keyword}")
}

pub fn divider(keyword: &str) -> String {
    format!(":INST:MEM:EXT:RDIV {keyword}")
}

pub fn memory_extended(channel: u8) -> String {
    format!(":TRAC{channel}:MMOD EXT")
}

/// Raster in Sa/s, written in full precision (`6.4E10`).
pub fn raster(rate: f64) -> String {
    format!(":FREQ:RAST {rate:E}")
}

pub fn amplitude(channel: u8, vpp: f64) -> String {
    format!(":VOLT{channel} {vpp}")
}

pub fn amplitude_query(channel: u8) -> String {
    format!(":VOLT{channel}?")
}

pub fn marker_amplitude(channel: u8, volts: f64) -> String {
    format!(":VOLT{channel}:AMPL {volts}")
}

pub fn marker_offset(channel: u8, volts: f64) -> String {
    format!(":VOLT{channel}:OFFS {volts}")
}

pub fn delete_all(channel: u8) -> String {
    format!(":TRAC{channel}:DEL:ALL")
}

pub fn define(channel: u8, segment: u32, samples: u64) -> String {
    format!(":TRAC{channel}:DEF {segment},{samples}")
}

/// The header of a `:TRAC:DATA` block write; the block follows directly.
pub fn data_header(channel: u8, segment: u32, offset: u64) -> String {
    format!(":TRAC{channel}:DATA {segment},{offset},")
}

pub fn select(channel: u8, segment: u32) -> String {
    format!(":TRAC{channel}:SEL {segment}")
}

pub fn catalog_query(channel: u8) -> String {
    format!(":TRAC{channel}:CAT?")
}

pub fn output(channel: u8, on: bool) -> String {
    format!(":OUTP{channel} {}", if on { "ON" } else { "OFF" })
}

pub fn output_query(channel: u8) -> String {
    format!(":OUTP{channel}?")
}
