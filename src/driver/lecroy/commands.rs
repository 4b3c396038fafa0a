//! Every command the LeCroy driver sends, in one place (instruments.md sections 2.3 and 2.4).
//! The same spellings go over VICP and VXI-11.

use crate::driver::capability::Slope;
use crate::driver::scpi::number;

pub(crate) const HEADERS_OFF: &str = "CHDR OFF";
/// 16-bit words: BYTE would transfer only the upper 8 bits of the scope's internal values.
pub(crate) const WORD_FORMAT: &str = "CFMT DEF9,WORD,BIN";
pub(crate) const LSB_FIRST: &str = "CORD LO";
pub(crate) const WHOLE_RECORD: &str = "WFSU SP,0,NP,0,FP,0,SN,0";
pub(crate) const FIXED_RATE: &str =
    "VBS 'app.Acquisition.Horizontal.Maximize = \"FixedSampleRate\"'";
pub(crate) const SAMPLING_RATE_QUERY: &str =
    "VBS? 'return = app.Acquisition.Horizontal.SamplingRate'";
pub(crate) const HOR_SCALE_QUERY: &str = "VBS? 'return = app.Acquisition.Horizontal.HorScale'";
/// One record per trigger.
pub(crate) const REAL_TIME: &str = "VBS 'app.Acquisition.Horizontal.SampleMode = \"RealTime\"'";
/// One segment per trigger, `NumSegments` of them per acquisition, read in one `WF? ALL`.
pub(crate) const SEQUENCE: &str = "VBS 'app.Acquisition.Horizontal.SampleMode = \"Sequence\"'";
pub const SEGMENTS_QUERY: &str = "VBS? 'return = app.Acquisition.Horizontal.NumSegments'";
/// The command error register; its codes' texts are the session's
/// `register_error_text`.
pub const COMMAND_ERRORS: &str = "CMR?";
/// The execution error register (texts as for [`COMMAND_ERRORS`]).
pub(crate) const EXECUTION_ERRORS: &str = "EXR?";
pub const STATUS: &str = "INR?";
pub const STOP: &str = "STOP";
pub(crate) const EXTERNAL_REFERENCE: &str = "RCLK EXTERNAL";
/// The timebase's reference: `INTERNAL` or `EXTERNAL`.
pub(crate) const REFERENCE_QUERY: &str = "RCLK?";
/// The external trigger input, where the AWG's marker arrives.
pub(crate) const EXTERNAL: &str = "EX";

pub fn sample_rate(rate_hz: f64) -> String {
    format!(
        "VBS 'app.Acquisition.Horizontal.SampleRate = {}'",
        number(rate_hz)
    )
}

pub(crate) fn hor_scale(seconds_per_div: f64) -> String {
    format!(
        "VBS 'app.Acquisition.Horizontal.HorScale = {}'",
        number(seconds_per_div)
    )
}

pub fn segments(count: u32) -> String {
    format!("VBS 'app.Acquisition.Horizontal.NumSegments = {count}'")
}

pub(crate) fn trace_on(channel: u8) -> String {
    format!("C{channel}:TRA ON")
}

pub fn volts_per_div(channel: u8, volts: f64) -> String {
    format!("C{channel}:VDIV {}", number(volts))
}

pub fn offset(channel: u8, volts: f64) -> String {
    format!("C{channel}:OFST {}", number(volts))
}

pub(crate) fn edge_trigger(source: &str) -> String {
    format!("TRSE EDGE,SR,{source},HT,OFF")
}

pub(crate) fn trigger_level(source: &str, volts: f64) -> String {
    format!("{source}:TRLV {}", number(volts))
}

pub(crate) fn trigger_slope(source: &str, slope: Slope) -> String {
    let s = match slope {
        Slope::Positive => "POS",
        Slope::Negative => "NEG",
    };
    format!("{source}:TRSL {s}")
}

pub(crate) fn trigger_delay(seconds: f64) -> String {
    format!("TRDL {}", number(seconds))
}

/// Single shot: arm, block the parser until the acquisition completes or `wait_s` passes, then
/// answer `*OPC?` (so the reply comes when the scope is done either way).
pub(crate) fn single_shot(wait_s: f64) -> String {
    format!("TRMD SINGLE;ARM;WAIT {};*OPC?", number(wait_s))
}

pub fn waveform(channel: u8) -> String {
    format!("C{channel}:WF? ALL")
}
