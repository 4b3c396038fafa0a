//! Keysight M8195A emulator: the SCPI command tree a driver uses and its common neighbours, the
//! instrument's rules (raster range, granularity and minimum length per divider, amplitude ranges,
//! no output or run without a waveform), real SCPI error codes, and the played waveform for the scene.
//!
//! Parsing: IEEE 488.2 messages are split by [`scpi::message`](super::scpi::message) (block-aware),
//! headers matched against the manual-style table in `commands` (see there why not the `scpi` crate).
//! Command errors (`-1xx`) abandon the rest of the program message, as IEEE 488.2 requires; execution
//! errors (`-2xx`) are queued and the following units still run. Several queries in one message are
//! answered in one response, separated by `;`.

mod commands;
mod state;

use std::sync::Mutex;

pub use state::{
    AwgState, Channel, ChannelPlayback, Memory, Playback, Segment, EMULATOR_MAX_SEGMENT_SAMPLES,
};

use self::commands::{Command, Forms};
use super::received_log::ReceivedLog;
use super::scpi::error_queue::{ErrorQueue, ScpiError};
use super::scpi::header::{Header, PathContext, Pattern};
use super::scpi::message::{parse_unit, split_units, unquote, Param, Unit};
use super::scpi::numeric::{self, nr3, NumericSpec};
use crate::catalog::{self, AwgModel, CatalogError};
use crate::server::Handler;

/// Entries kept in the received-message log.
const LOG_CAPACITY: usize = 1000;
/// Entries kept in the SCPI error queue.
const ERROR_QUEUE_CAPACITY: usize = 30;

/// IEEE 488.2 standard event status register bits.
mod esr {
    pub const OPC: u8 = 0x01;
    pub const QUERY_ERROR: u8 = 0x04;
    pub const DEVICE_ERROR: u8 = 0x08;
    pub const EXECUTION_ERROR: u8 = 0x10;
    pub const COMMAND_ERROR: u8 = 0x20;
}

struct Inner {
    state: AwgState,
    errors: ErrorQueue,
    esr: u8,
    ese: u8,
    sre: u8,
}

/// The emulated M8195A.
pub struct M8195a {
    model: AwgModel,
    tree: Vec<(Pattern, Command, Forms)>,
    inner: Mutex<Inner>,
    log: ReceivedLog,
}

impl M8195a {
    /// An emulator with the limits of `model`, in its power-on state. Refuses a model the emulator
    /// cannot work with (no dividers, channels out of range).
    pub fn new(model: AwgModel) -> Result<M8195a, CatalogError> {
        catalog::check_awg(&model)?;
        let state = AwgState::reset(&model);
        Ok(M8195a {
            tree: commands::compiled(),
            inner: Mutex::new(Inner {
                state,
                errors: ErrorQueue::new(ERROR_QUEUE_CAPACITY),
                esr: 0,
                ese: 0,
                sre: 0,
            }),
            log: ReceivedLog::new("m8195a", LOG_CAPACITY),
            model,
        })
    }

    /// An emulator with the limits of the built-in catalog file.
    pub fn embedded() -> Result<M8195a, CatalogError> {
        M8195a::new(catalog::m8195a()?)
    }

    pub fn model(&self) -> &AwgModel {
        &self.model
    }

    /// What the emulator received, newest last.
    pub fn log(&self) -> &ReceivedLog {
        &self.log
    }

    /// What the AWG plays now (for the scene physics and tests).
    pub fn playback(&self) -> Playback {
        let inner = self.lock();
        inner.state.playback(&self.model)
    }

    /// A copy of the full settings and memory.
    pub fn state(&self) -> AwgState {
        self.lock().state.clone()
    }

    /// The queued errors, oldest first, without removing them.
    pub fn pending_errors(&self) -> Vec<ScpiError> {
        self.lock().errors.peek_all()
    }

    fn lock(&self) -> std::sync::MutexGuard<'_, Inner> {
        self.inner.lock().unwrap_or_else(|e| e.into_inner())
    }

    /// Runs one program message; returns the response text (without terminator) if it had queries.
    pub fn execute(&self, message: &[u8]) -> Option<String> {
        self.log.record(message);
        let mut inner = self.lock();
        let mut responses = Vec::new();
        let units = match split_units(message) {
            Ok(units) => units,
            Err(e) => {
                push_error(&mut inner, e);
                return None;
            }
        };
        let mut path = PathContext::default();
        for raw in units {
            let result =
                parse_unit(raw).and_then(|unit| self.run_unit(&mut inner, &mut path, &unit));
            match result {
                Ok(Some(reply)) => responses.push(reply),
                Ok(None) => {}
                Err(e) => {
                    let abort = e.is_command_error();
                    push_error(&mut inner, e);
                    if abort {
                        break;
                    }
                }
            }
        }
        (!responses.is_empty()).then(|| responses.join(";"))
    }

    fn run_unit(
        &self,
        inner: &mut Inner,
        path: &mut PathContext,
        unit: &Unit,
    ) -> Result<Option<String>, ScpiError> {
        if unit.header.starts_with('*') {
            return self.common(inner, unit);
        }
        let header = Header::parse(&unit.header)?;
        for nodes in path.candidates(&header) {
            for (pattern, command, forms) in &self.tree {
                let Some(suffixes) = pattern.matches(&nodes) else {
                    continue;
                };
                path.matched(&nodes);
                let allowed = match forms {
                    Forms::SetAndQuery => true,
                    Forms::SetOnly => !header.query,
                    Forms::QueryOnly => header.query,
                };
                if !allowed {
                    let form = if header.query { "query" } else { "command" };
                    return Err(ScpiError::new(
                        -113,
                        format!("{} has no {form} form", unit.header),
                    ));
                }
                let channel = match suffixes.first() {
                    Some(&n) if n == 0 || n > u32::from(self.model.limits.channels) => {
                        return Err(ScpiError::new(
                            -114,
                            format!(
                                "channel {n} does not exist (1..={})",
                                self.model.limits.channels
                            ),
                        ))
                    }
                    Some(&n) => n as u8,
                    None => 1,
                };
                return self.run(inner, *command, channel, &unit.header, &unit.params);
            }
        }
        Err(ScpiError::new(-113, unit.header.clone()))
    }

    fn common(&self, inner: &mut Inner, unit: &Unit) -> Result<Option<String>, ScpiError> {
        let name = unit.header.to_ascii_uppercase();
        let params = &unit.params;
        let no_params = |reply: Option<String>| {
            if params.is_empty() {
                Ok(reply)
            } else {
                Err(ScpiError::new(
                    -108,
                    format!("{} takes no parameter", unit.header),
                ))
            }
        };
        match name.as_str() {
            "*IDN?" => no_params(Some(self.model.identity.idn())),
            "*RST" => {
                let generation = inner.state.generation;
                inner.state = AwgState::reset(&self.model);
                inner.state.generation = generation + 1;
                no_params(None)
            }
            "*CLS" => {
                inner.errors.clear();
                inner.esr = 0;
                no_params(None)
            }
            "*OPC?" => no_params(Some("1".into())),
            "*OPC" => {
                inner.esr |= esr::OPC;
                no_params(None)
            }
            "*WAI" => no_params(None),
            "*TST?" => no_params(Some("0".into())),
            "*OPT?" => no_params(Some(self.model.limits.options.join(","))),
            "*ESR?" => {
                let value = inner.esr;
                inner.esr = 0;
                no_params(Some(value.to_string()))
            }
            "*ESE?" => no_params(Some(inner.ese.to_string())),
            "*SRE?" => no_params(Some(inner.sre.to_string())),
            "*STB?" => no_params(Some(status_byte(inner).to_string())),
            "*ESE" | "*SRE" => {
                let value = one_text(params, &unit.header)?;
                let value = numeric::unsigned(value)?;
                let value = u8::try_from(value)
                    .map_err(|_| ScpiError::new(-222, "the register value must be 0..=255"))?;
                if name == "*ESE" {
                    inner.ese = value;
                } else {
                    inner.sre = value;
                }
                Ok(None)
            }
            _ => Err(ScpiError::new(-113, unit.header.clone())),
        }
    }

    fn run(
        &self,
        inner: &mut Inner,
        command: Command,
        ch: u8,
        header: &str,
        params: &[Param],
    ) -> Result<Option<String>, ScpiError> {
        if header.ends_with('?') {
            return self.query(inner, command, ch, header, params).map(Some);
        }
        let model = &self.model;
        let limits = &model.limits;
        let st = &mut inner.state;
        match command {
            Command::DacMode => {
                let choices: Vec<(&str, &str)> = limits
                    .dac_modes
                    .iter()
                    .map(|m| (m.keyword.as_str(), m.long.as_str()))
                    .collect();
                let keyword = numeric::keyword(one_text(params, header)?, &choices)?;
                st.set_dac_mode(model, keyword)?;
            }
            Command::ExtRateDivider => {
                let text = one_text(params, header)?;
                let divider = limits
                    .dividers
                    .iter()
                    .find(|d| d.keyword.eq_ignore_ascii_case(text.trim()))
                    .ok_or_else(|| {
                        let allowed: Vec<_> =
                            limits.dividers.iter().map(|d| d.keyword.as_str()).collect();
                        ScpiError::new(
                            -224,
                            format!("{text:?} is not one of {}", allowed.join("|")),
                        )
                    })?;
                st.set_divider(divider.divider)?;
            }
            Command::MemoryMode => {
                let keyword = numeric::keyword(
                    one_text(params, header)?,
                    &[("INT", "INTERNAL"), ("EXT", "EXTENDED")],
                )?;
                let memory = if keyword == "EXT" {
                    Memory::Extended
                } else {
                    Memory::Internal
                };
                st.set_memory(model, ch, memory)?;
            }
            Command::Raster => {
                let rate = numeric::numeric(
                    one_text(params, header)?,
                    NumericSpec {
                        unit: numeric::Unit::Hertz,
                        min: limits.dac_rate_min,
                        max: limits.dac_rate_max,
                        default: limits.dac_rate_default,
                    },
                )?;
                st.set_raster(rate);
            }
            Command::FunctionMode => {
                let keyword = numeric::keyword(
                    one_text(params, header)?,
                    &[
                        ("ARB", "ARBITRARY"),
                        ("STS", "STSEQUENCE"),
                        ("STSC", "STSCENARIO"),
                    ],
                )?;
                if keyword != "ARB" && !limits.options.iter().any(|o| o == "SEQ") {
                    return Err(ScpiError::new(
                        -241,
                        format!("function mode {keyword} needs option SEQ, which is not installed"),
                    ));
                }
                st.refuse_running_change(keyword)?;
            }
            Command::InitContinuous => st.continuous = numeric::boolean(one_text(params, header)?)?,
            Command::InitGate => st.gate = numeric::boolean(one_text(params, header)?)?,
            Command::InitImmediate => {
                no_params(params, header)?;
                st.start(model)?;
            }
            Command::Abort => {
                no_params(params, header)?;
                st.stop();
            }
            Command::TraceDefine => {
                let (id, length, fill) = match params {
                    [id, len] => (id, len, None),
                    [id, len, fill] => (id, len, Some(fill)),
                    [] | [_] => {
                        return Err(ScpiError::new(
                            -109,
                            ":TRAC:DEF needs <id>,<length>[,<init value>]",
                        ))
                    }
                    _ => {
                        return Err(ScpiError::new(
                            -108,
                            ":TRAC:DEF takes <id>,<length>[,<init value>]",
                        ))
                    }
                };
                let id = numeric::unsigned(text(id)?)?;
                let length = numeric::unsigned(text(length)?)?;
                let fill = fill
                    .map(|f| sample_value(text(f)?, limits.sample_min, limits.sample_max))
                    .transpose()?;
                st.define(model, ch, id, length, fill)?;
            }
            Command::TraceData => {
                let [id, offset, data @ ..] = params else {
                    return Err(ScpiError::new(
                        -109,
                        ":TRAC:DATA needs <id>,<offset>,<block or values>",
                    ));
                };
                let id = numeric::unsigned(text(id)?)?;
                let offset = numeric::unsigned(text(offset)?)?;
                let interleaved = st.channel_interleaved(model, ch);
                let bytes: Vec<i16> = match data {
                    [Param::Block(block)] => block.iter().map(|b| i16::from(*b as i8)).collect(),
                    [] => {
                        return Err(ScpiError::new(
                            -109,
                            ":TRAC:DATA needs data after the offset",
                        ))
                    }
                    values => values
                        .iter()
                        .map(|v| {
                            let v = text(v)?;
                            let n = numeric::parse_with_unit(
                                &v.to_ascii_uppercase(),
                                numeric::Unit::None,
                            )?;
                            if n.fract() != 0.0 || !(-128.0..=255.0).contains(&n) {
                                return Err(ScpiError::new(
                                    -222,
                                    format!("value {v} is not a byte"),
                                ));
                            }
                            Ok(n as i16)
                        })
                        .collect::<Result<_, _>>()?,
                };
                let (samples, markers) =
                    split_data(&bytes, interleaved, limits.sample_min, limits.sample_max)?;
                st.write(model, ch, id, offset, &samples, markers.as_deref())?;
            }
            Command::TraceDelete => {
                let id = numeric::unsigned(one_text(params, header)?)?;
                st.delete(model, ch, Some(id))?;
            }
            Command::TraceDeleteAll => {
                no_params(params, header)?;
                st.delete(model, ch, None)?;
            }
            Command::TraceSelect => {
                let id = numeric::unsigned(one_text(params, header)?)?;
                st.select(model, ch, id)?;
            }
            Command::Amplitude | Command::Offset => {
                let ((amin, amax), (omin, omax)) = st.level_limits(model, ch);
                let (min, max, default) = if command == Command::Amplitude {
                    (amin, amax, limits.amplitude_vpp_default.clamp(amin, amax))
                } else {
                    (omin, omax, 0.0f64.clamp(omin, omax))
                };
                let value = numeric::numeric(
                    one_text(params, header)?,
                    NumericSpec {
                        unit: numeric::Unit::Volt,
                        min,
                        max,
                        default,
                    },
                )?;
                if command == Command::Amplitude {
                    st.set_amplitude(ch, value);
                } else {
                    st.set_offset(ch, value);
                }
            }
            Command::Output => {
                let on = numeric::boolean(one_text(params, header)?)?;
                st.set_output(model, ch, on)?;
            }
            Command::RefSource => {
                let keyword = numeric::keyword(
                    one_text(params, header)?,
                    &[("INT", "INTERNAL"), ("EXT", "EXTERNAL"), ("AXI", "AXI")],
                )?;
                st.ref_source = keyword;
            }
            Command::RefFrequency => {
                st.ref_frequency = numeric::numeric(
                    one_text(params, header)?,
                    NumericSpec {
                        unit: numeric::Unit::Hertz,
                        min: 10e6,
                        max: 300e6,
                        default: 100e6,
                    },
                )?;
            }
            Command::TraceCatalog
            | Command::TraceFree
            | Command::High
            | Command::Low
            | Command::SystemError
            | Command::SystemErrorCount => unreachable_form(command)?,
        }
        Ok(None)
    }

    fn query(
        &self,
        inner: &mut Inner,
        command: Command,
        ch: u8,
        header: &str,
        params: &[Param],
    ) -> Result<String, ScpiError> {
        let model = &self.model;
        let st = &inner.state;
        if command != Command::TraceData && !params.is_empty() {
            return Err(ScpiError::new(-108, format!("{header} takes no parameter")));
        }
        let reply = match command {
            Command::DacMode => st.dac_mode.clone(),
            Command::ExtRateDivider => format!("DIV{}", st.divider),
            Command::MemoryMode => st.channel(ch).memory.keyword().to_string(),
            Command::Raster => nr3(st.raster),
            Command::FunctionMode => st.function_mode.to_string(),
            Command::InitContinuous => u8::from(st.continuous).to_string(),
            Command::InitGate => u8::from(st.gate).to_string(),
            Command::TraceData => {
                let [id, offset, count] = params else {
                    return Err(ScpiError::new(
                        -109,
                        ":TRAC:DATA? needs <id>,<offset>,<length>",
                    ));
                };
                st.read(
                    ch,
                    numeric::unsigned(text(id)?)?,
                    numeric::unsigned(text(offset)?)?,
                    numeric::unsigned(text(count)?)?,
                    st.channel_interleaved(model, ch),
                )?
            }
            Command::TraceCatalog => st.catalog(ch),
            Command::TraceSelect => st.channel(ch).selected.to_string(),
            Command::TraceFree => st.free(model, ch),
            Command::Amplitude => nr3(st.channel(ch).amplitude_vpp),
            Command::Offset => nr3(st.channel(ch).offset_v),
            Command::High => {
                let c = st.channel(ch);
                nr3(c.offset_v + c.amplitude_vpp / 2.0)
            }
            Command::Low => {
                let c = st.channel(ch);
                nr3(c.offset_v - c.amplitude_vpp / 2.0)
            }
            Command::Output => u8::from(st.channel(ch).output).to_string(),
            Command::SystemError => inner.errors.pop().reply(),
            Command::SystemErrorCount => inner.errors.len().to_string(),
            Command::RefSource => st.ref_source.to_string(),
            Command::RefFrequency => nr3(st.ref_frequency),
            Command::InitImmediate
            | Command::Abort
            | Command::TraceDefine
            | Command::TraceDelete
            | Command::TraceDeleteAll => return Err(unreachable_form(command).unwrap_err()),
        };
        Ok(reply)
    }
}

impl AwgState {
    fn refuse_running_change(&mut self, function_mode: &'static str) -> Result<(), ScpiError> {
        if self.running && self.function_mode != function_mode {
            return Err(ScpiError::new(
                -221,
                "changing the function mode is not allowed while the output runs; send :ABOR first",
            ));
        }
        self.function_mode = function_mode;
        Ok(())
    }
}

/// The table's `Forms` already rejected this form; kept as an error rather than a panic.
fn unreachable_form(command: Command) -> Result<(), ScpiError> {
    Err(ScpiError::new(
        -113,
        format!("{command:?} has no such form"),
    ))
}

fn push_error(inner: &mut Inner, error: ScpiError) {
    inner.esr |= match error.code {
        -199..=-100 => esr::COMMAND_ERROR,
        -299..=-200 => esr::EXECUTION_ERROR,
        -499..=-400 => esr::QUERY_ERROR,
        _ => esr::DEVICE_ERROR,
    };
    inner.errors.push(error);
}

/// IEEE 488.2 status byte: bit2 error/event queue not empty, bit5 ESB, bit6 MSS.
fn status_byte(inner: &Inner) -> u8 {
    let mut stb = 0u8;
    if !inner.errors.is_empty() {
        stb |= 0x04;
    }
    if inner.esr & inner.ese != 0 {
        stb |= 0x20;
    }
    if stb & inner.sre & !0x40 != 0 {
        stb |= 0x40;
    }
    stb
}

fn text(param: &Param) -> Result<&str, ScpiError> {
    param
        .text()
        .map(unquote)
        .ok_or_else(|| ScpiError::new(-104, "a block is not allowed here"))
}

fn one_text<'a>(params: &'a [Param], header: &str) -> Result<&'a str, ScpiError> {
    match params {
        [p] => text(p),
        [] => Err(ScpiError::new(-109, format!("{header} needs a parameter"))),
        _ => Err(ScpiError::new(
            -108,
            format!("{header} takes one parameter"),
        )),
    }
}

fn no_params(params: &[Param], header: &str) -> Result<(), ScpiError> {
    if params.is_empty() {
        Ok(())
    } else {
        Err(ScpiError::new(-108, format!("{header} takes no parameter")))
    }
}

fn sample_value(text: &str, min: i32, max: i32) -> Result<i8, ScpiError> {
    let v = numeric::parse_with_unit(&text.to_ascii_uppercase(), numeric::Unit::None)?;
    if v.fract() != 0.0 || v < f64::from(min) || v > f64::from(max) {
        return Err(ScpiError::new(
            -222,
            format!("sample {text} is outside {min}..={max}"),
        ));
    }
    Ok(v as i8)
}

/// Splits download bytes into samples and (interleaved mode) marker bytes.
#[allow(clippy::type_complexity)]
fn split_data(
    bytes: &[i16],
    interleaved: bool,
    min: i32,
    max: i32,
) -> Result<(Vec<i8>, Option<Vec<u8>>), ScpiError> {
    let sample = |v: i16| -> Result<i8, ScpiError> {
        // Block bytes arrive as two's complement; ASCII values may be written 0..255 or -128..127.
        let s = if v > 127 { v - 256 } else { v };
        if i32::from(s) < min || i32::from(s) > max {
            return Err(ScpiError::new(
                -222,
                format!("sample {v} is outside {min}..={max}"),
            ));
        }
        Ok(s as i8)
    };
    if !interleaved {
        return Ok((
            bytes.iter().map(|b| sample(*b)).collect::<Result<_, _>>()?,
            None,
        ));
    }
    if bytes.len() % 2 != 0 {
        return Err(ScpiError::new(
            -161,
            format!(
                "channel 1 data in a marker DAC mode is [sample, marker] byte pairs; got an odd {} bytes",
                bytes.len()
            ),
        ));
    }
    let mut samples = Vec::with_capacity(bytes.len() / 2);
    let mut markers = Vec::with_capacity(bytes.len() / 2);
    for pair in bytes.chunks_exact(2) {
        samples.push(sample(pair[0])?);
        markers.push((pair[1] & 0xff) as u8);
    }
    Ok((samples, Some(markers)))
}

impl Handler for M8195a {
    fn message(&self, data: &[u8]) -> Vec<Vec<u8>> {
        self.execute(data)
            .map(|reply| vec![reply.into_bytes()])
            .unwrap_or_default()
    }

    fn device_clear(&self) {
        tracing::debug!(instrument = "m8195a", "device clear");
    }

    fn status_byte(&self) -> u8 {
        status_byte(&self.lock())
    }
}
