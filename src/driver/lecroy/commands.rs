//! Every LeCroy command spelling the driver sends, in one place (instruments.md sections 2.3-2.4).

/// Replies without headers, 16-bit words, LSB first, the whole record.
pub const TRANSFER_SETUP: [&str; 4] = [
    "CHDR OFF",
    "CFMT DEF9,WORD,BIN",
    "CORD LO",
    "WFSU SP,0,NP,0,FP,0,SN,0",
];
pub const FIXED_SAMPLE_RATE: &str =
    "VBS 'app.Acquisition.Horizontal.Maximize = \"FixedSampleRate\"'";
pub const EDGE_ON_EXT: &str = "TRSE EDGE,SR,EX,HT,OFF";
pub const SLOPE_POSITIVE: &str = "EX:TRSL POS";
pub const SAMPLING_RATE_QUERY: &str = "VBS? 'return = app.Acquisition.Horizontal.SamplingRate'";
pub const NUM_POINTS_QUERY: &str = "VBS? 'return = app.Acquisition.Horizontal.NumPoints'";
pub const COMMAND_ERROR_QUERY: &str = "CMR?";
pub const EXECUTION_ERROR_QUERY: &str = "EXR?";
pub const INR_QUERY: &str = "INR?";

pub fn sample_rate(rate: f64) -> String {
    format!("VBS 'app.Acquisition.Horizontal.SampleRate = {rate:e}'")
}

pub fn hor_scale(seconds_per_div: f64) -> String {
    format!("VBS 'app.Acquisition.Horizontal.HorScale = {seconds_per_div:e}'")
}

pub fn trigger_delay(seconds: f64) -> String {
    format!("TRDL {seconds:e}")
}

pub fn trace_on(channel: u8) -> String {
    format!("C{channel}:TRA ON")
}

pub fn volts_per_div(channel: u8, volts: f64) -> String {
    format!("C{channel}:VDIV {volts}")
}

pub fn ext_level(volts: f64) -> String {
    format!("EX:TRLV {volts}V")
}

/// Single shot: arm, block until the acquisition completes or `timeout_s` passes, then `*OPC?`.
pub fn single_shot(timeout_s: f64) -> String {
    format!("TRMD SINGLE;ARM;WAIT {timeout_s};*OPC?")
}

pub fn waveform_query(channel: u8) -> String {
    format!("C{channel}:WF? ALL")
}

/// Texts of the legacy CMR/EXR codes [I: WM-RCM-E manual, not verified on hardware].
pub fn error_text(code: i64) -> &'static str {
    match code {
        1 => "unrecognized command/query header",
        2 => "illegal header path",
        3 => "illegal number",
        4 => "illegal number suffix",
        5 => "unrecognized keyword",
        6 => "string error",
        10 => "arbitrary data block expected",
        11 => "non-digit character in byte count field of arbitrary data block",
        21 => "permission error",
        22 => "environment error",
        23 => "option error",
        24 => "unresolved parsing error",
        25 => "parameter error",
        26 => "command not implemented",
        27 => "parameter missing",
        31 => "waveform error",
        _ => "instrument error",
    }
}
