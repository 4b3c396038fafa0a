//! One small function per form of each M8195A command (the tree in `commands` names them):
//! setters parse their parameters against the catalog's limits and change the state; getters
//! answer in the instrument's format. Errors are the instrument's SCPI codes.

use super::inner::Inner;
use super::state::{AwgState, Memory};
use crate::catalog::AwgModel;
use crate::emulator::scpi::error_queue::ScpiError;
use crate::emulator::scpi::message::{unquote, Param};
use crate::emulator::scpi::numeric::{self, nr3, NumericSpec};

/// What a command form runs with.
pub(super) struct Call<'a> {
    pub model: &'a AwgModel,
    /// The channel of a suffixed node (`TRAC2` -> 2), 1 otherwise.
    pub channel: u8,
    /// The header as sent, for messages.
    pub header: &'a str,
    pub params: &'a [Param],
}

/// A command form.
pub(super) type Set = fn(&mut Inner, &Call) -> Result<(), ScpiError>;
/// A query form: the reply without terminator.
pub(super) type Get = fn(&mut Inner, &Call) -> Result<String, ScpiError>;

impl Call<'_> {
    /// The one parameter, unquoted.
    fn one(&self) -> Result<&str, ScpiError> {
        match self.params {
            [p] => text(p),
            [] => Err(ScpiError::new(
                -109,
                format!("{} needs a parameter", self.header),
            )),
            _ => Err(ScpiError::new(
                -108,
                format!("{} takes one parameter", self.header),
            )),
        }
    }

    fn none(&self) -> Result<(), ScpiError> {
        if self.params.is_empty() {
            Ok(())
        } else {
            Err(ScpiError::new(
                -108,
                format!("{} takes no parameter", self.header),
            ))
        }
    }

    fn keyword(&self, choices: &[(&'static str, &'static str)]) -> Result<&'static str, ScpiError> {
        numeric::keyword(self.one()?, choices)
    }

    fn boolean(&self) -> Result<bool, ScpiError> {
        numeric::boolean(self.one()?)
    }

    fn unsigned(&self) -> Result<u64, ScpiError> {
        numeric::unsigned(self.one()?)
    }

    fn numeric(&self, spec: NumericSpec) -> Result<f64, ScpiError> {
        numeric::numeric(self.one()?, spec)
    }
}

pub(super) fn text(param: &Param) -> Result<&str, ScpiError> {
    param
        .text()
        .map(unquote)
        .ok_or_else(|| ScpiError::new(-104, "a block is not allowed here"))
}

fn flag(on: bool) -> String {
    u8::from(on).to_string()
}

// ---------------------------------------------------------------- clock and modes

pub(super) fn set_dac_mode(inner: &mut Inner, call: &Call) -> Result<(), ScpiError> {
    let choices: Vec<(&str, &str)> = call
        .model
        .limits
        .dac_modes
        .iter()
        .map(|m| (m.keyword.as_str(), m.long.as_str()))
        .collect();
    let keyword = numeric::keyword(call.one()?, &choices)?;
    inner.state.set_dac_mode(call.model, keyword)
}

pub(super) fn get_dac_mode(inner: &mut Inner, _: &Call) -> Result<String, ScpiError> {
    Ok(inner.state.dac_mode.clone())
}

pub(super) fn set_divider(inner: &mut Inner, call: &Call) -> Result<(), ScpiError> {
    let text = call.one()?;
    let dividers = &call.model.limits.dividers;
    let divider = dividers
        .iter()
        .find(|d| d.keyword.eq_ignore_ascii_case(text.trim()))
        .ok_or_else(|| {
            let allowed: Vec<_> = dividers.iter().map(|d| d.keyword.as_str()).collect();
            ScpiError::new(
                -224,
                format!("{text:?} is not one of {}", allowed.join("|")),
            )
        })?;
    inner.state.set_divider(divider.divider)
}

pub(super) fn get_divider(inner: &mut Inner, _: &Call) -> Result<String, ScpiError> {
    Ok(format!("DIV{}", inner.state.divider))
}

pub(super) fn set_memory_mode(inner: &mut Inner, call: &Call) -> Result<(), ScpiError> {
    let memory = match call.keyword(&[("INT", "INTERNAL"), ("EXT", "EXTENDED")])? {
        "EXT" => Memory::Extended,
        _ => Memory::Internal,
    };
    inner.state.set_memory(call.model, call.channel, memory)
}

pub(super) fn get_memory_mode(inner: &mut Inner, call: &Call) -> Result<String, ScpiError> {
    Ok(inner
        .state
        .channel(call.channel)
        .memory
        .keyword()
        .to_string())
}

pub(super) fn set_raster(inner: &mut Inner, call: &Call) -> Result<(), ScpiError> {
    let limits = &call.model.limits;
    let rate = call.numeric(NumericSpec {
        unit: numeric::Unit::Hertz,
        min: limits.dac_rate_min,
        max: limits.dac_rate_max,
        default: limits.dac_rate_default,
    })?;
    inner.state.set_raster(rate);
    Ok(())
}

/// `:FREQ:RAST?`, or with `MIN`, `MAX` or `DEF` the catalog's limit (what `doctor
/// --verify-catalog` asks).
pub(super) fn get_raster(inner: &mut Inner, call: &Call) -> Result<String, ScpiError> {
    if call.params.is_empty() {
        return Ok(nr3(inner.state.raster));
    }
    let limits = &call.model.limits;
    let rate = match call.keyword(&[("MIN", "MINIMUM"), ("MAX", "MAXIMUM"), ("DEF", "DEFAULT")])? {
        "MIN" => limits.dac_rate_min,
        "MAX" => inner.raster_max.unwrap_or(limits.dac_rate_max),
        _ => limits.dac_rate_default,
    };
    Ok(nr3(rate))
}

pub(super) fn set_function_mode(inner: &mut Inner, call: &Call) -> Result<(), ScpiError> {
    let keyword = call.keyword(&[
        ("ARB", "ARBITRARY"),
        ("STS", "STSEQUENCE"),
        ("STSC", "STSCENARIO"),
    ])?;
    if keyword != "ARB" && !call.model.limits.options.iter().any(|o| o == "SEQ") {
        return Err(ScpiError::new(
            -241,
            format!("function mode {keyword} needs option SEQ, which is not installed"),
        ));
    }
    inner.state.refuse_running_change(keyword)
}

pub(super) fn get_function_mode(inner: &mut Inner, _: &Call) -> Result<String, ScpiError> {
    Ok(inner.state.function_mode.to_string())
}

pub(super) fn set_reference_source(inner: &mut Inner, call: &Call) -> Result<(), ScpiError> {
    inner.state.ref_source =
        call.keyword(&[("INT", "INTERNAL"), ("EXT", "EXTERNAL"), ("AXI", "AXI")])?;
    Ok(())
}

pub(super) fn get_reference_source(inner: &mut Inner, _: &Call) -> Result<String, ScpiError> {
    Ok(inner.state.ref_source.to_string())
}

pub(super) fn set_reference_frequency(inner: &mut Inner, call: &Call) -> Result<(), ScpiError> {
    inner.state.ref_frequency = call.numeric(NumericSpec {
        unit: numeric::Unit::Hertz,
        min: 10e6,
        max: 300e6,
        default: 100e6,
    })?;
    Ok(())
}

pub(super) fn get_reference_frequency(inner: &mut Inner, _: &Call) -> Result<String, ScpiError> {
    Ok(nr3(inner.state.ref_frequency))
}

// ---------------------------------------------------------------- run control

pub(super) fn set_continuous(inner: &mut Inner, call: &Call) -> Result<(), ScpiError> {
    inner.state.continuous = call.boolean()?;
    Ok(())
}

pub(super) fn get_continuous(inner: &mut Inner, _: &Call) -> Result<String, ScpiError> {
    Ok(flag(inner.state.continuous))
}

pub(super) fn set_gate(inner: &mut Inner, call: &Call) -> Result<(), ScpiError> {
    inner.state.gate = call.boolean()?;
    Ok(())
}

pub(super) fn get_gate(inner: &mut Inner, _: &Call) -> Result<String, ScpiError> {
    Ok(flag(inner.state.gate))
}

/// `:INIT:IMM`: starts playback (refused without a waveform).
pub(super) fn start(inner: &mut Inner, call: &Call) -> Result<(), ScpiError> {
    call.none()?;
    inner.state.start(call.model)
}

/// `:ABOR`: stops playback.
pub(super) fn abort(inner: &mut Inner, call: &Call) -> Result<(), ScpiError> {
    call.none()?;
    inner.state.stop();
    Ok(())
}

// ---------------------------------------------------------------- segments

pub(super) fn define_segment(inner: &mut Inner, call: &Call) -> Result<(), ScpiError> {
    let (id, length, fill) = match call.params {
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
    let limits = &call.model.limits;
    let id = numeric::unsigned(text(id)?)?;
    let length = numeric::unsigned(text(length)?)?;
    let fill = fill
        .map(|f| sample_value(text(f)?, limits.sample_min, limits.sample_max))
        .transpose()?;
    inner
        .state
        .define(call.model, call.channel, id, length, fill)
}

/// `:TRAC:DATA id,offset,<block or values>`.
pub(super) fn write_data(inner: &mut Inner, call: &Call) -> Result<(), ScpiError> {
    let [id, offset, data @ ..] = call.params else {
        return Err(ScpiError::new(
            -109,
            ":TRAC:DATA needs <id>,<offset>,<block or values>",
        ));
    };
    let id = numeric::unsigned(text(id)?)?;
    let offset = numeric::unsigned(text(offset)?)?;
    let bytes = data_bytes(data)?;
    let limits = &call.model.limits;
    let st = &mut inner.state;
    let interleaved = st.channel_interleaved(call.model, call.channel);
    let (samples, markers) = split_data(&bytes, interleaved, limits.sample_min, limits.sample_max)?;
    st.write(
        call.model,
        call.channel,
        id,
        offset,
        &samples,
        markers.as_deref(),
    )
}

/// `:TRAC:DATA? id,offset,length`.
pub(super) fn read_data(inner: &mut Inner, call: &Call) -> Result<String, ScpiError> {
    let [id, offset, count] = call.params else {
        return Err(ScpiError::new(
            -109,
            ":TRAC:DATA? needs <id>,<offset>,<length>",
        ));
    };
    let st = &inner.state;
    st.read(
        call.channel,
        numeric::unsigned(text(id)?)?,
        numeric::unsigned(text(offset)?)?,
        numeric::unsigned(text(count)?)?,
        st.channel_interleaved(call.model, call.channel),
    )
}

pub(super) fn get_catalog(inner: &mut Inner, call: &Call) -> Result<String, ScpiError> {
    Ok(inner.state.catalog(call.channel))
}

pub(super) fn delete_segment(inner: &mut Inner, call: &Call) -> Result<(), ScpiError> {
    let id = call.unsigned()?;
    inner.state.delete(call.model, call.channel, Some(id))
}

pub(super) fn delete_all_segments(inner: &mut Inner, call: &Call) -> Result<(), ScpiError> {
    call.none()?;
    inner.state.delete(call.model, call.channel, None)
}

pub(super) fn select_segment(inner: &mut Inner, call: &Call) -> Result<(), ScpiError> {
    let id = call.unsigned()?;
    inner.state.select(call.model, call.channel, id)
}

pub(super) fn get_selected_segment(inner: &mut Inner, call: &Call) -> Result<String, ScpiError> {
    Ok(inner.state.channel(call.channel).selected.to_string())
}

pub(super) fn get_free(inner: &mut Inner, call: &Call) -> Result<String, ScpiError> {
    Ok(inner.state.free(call.model, call.channel))
}

// ---------------------------------------------------------------- levels and outputs

/// A level setting's range on this channel (amplitude or offset) and its default.
fn level_spec(st: &AwgState, call: &Call, amplitude: bool) -> NumericSpec {
    let ((amin, amax), (omin, omax)) = st.level_limits(call.model, call.channel);
    let (min, max, default) = if amplitude {
        let default = call.model.limits.amplitude_vpp_default.clamp(amin, amax);
        (amin, amax, default)
    } else {
        (omin, omax, 0.0f64.clamp(omin, omax))
    };
    NumericSpec {
        unit: numeric::Unit::Volt,
        min,
        max,
        default,
    }
}

pub(super) fn set_amplitude(inner: &mut Inner, call: &Call) -> Result<(), ScpiError> {
    let value = call.numeric(level_spec(&inner.state, call, true))?;
    inner.state.set_amplitude(call.channel, value);
    Ok(())
}

pub(super) fn get_amplitude(inner: &mut Inner, call: &Call) -> Result<String, ScpiError> {
    Ok(nr3(inner.state.channel(call.channel).amplitude_vpp))
}

pub(super) fn set_offset(inner: &mut Inner, call: &Call) -> Result<(), ScpiError> {
    let value = call.numeric(level_spec(&inner.state, call, false))?;
    inner.state.set_offset(call.channel, value);
    Ok(())
}

pub(super) fn get_offset(inner: &mut Inner, call: &Call) -> Result<String, ScpiError> {
    Ok(nr3(inner.state.channel(call.channel).offset_v))
}

pub(super) fn get_high(inner: &mut Inner, call: &Call) -> Result<String, ScpiError> {
    let c = inner.state.channel(call.channel);
    Ok(nr3(c.offset_v + c.amplitude_vpp / 2.0))
}

pub(super) fn get_low(inner: &mut Inner, call: &Call) -> Result<String, ScpiError> {
    let c = inner.state.channel(call.channel);
    Ok(nr3(c.offset_v - c.amplitude_vpp / 2.0))
}

pub(super) fn set_output(inner: &mut Inner, call: &Call) -> Result<(), ScpiError> {
    let on = call.boolean()?;
    inner.state.set_output(call.model, call.channel, on)
}

pub(super) fn get_output(inner: &mut Inner, call: &Call) -> Result<String, ScpiError> {
    Ok(flag(inner.state.channel(call.channel).output))
}

// ---------------------------------------------------------------- error queue

/// `:SYST:ERR?`: the oldest entry, `0,"No error"` when empty.
pub(super) fn next_error(inner: &mut Inner, _: &Call) -> Result<String, ScpiError> {
    Ok(inner.errors.pop().reply())
}

pub(super) fn error_count(inner: &mut Inner, _: &Call) -> Result<String, ScpiError> {
    Ok(inner.errors.len().to_string())
}

// ---------------------------------------------------------------- sample data

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

/// The bytes of `:TRAC:DATA`: one block, or comma-separated values (0..255 or -128..127).
fn data_bytes(data: &[Param]) -> Result<Vec<i16>, ScpiError> {
    match data {
        [Param::Block(block)] => Ok(block.iter().map(|b| i16::from(*b as i8)).collect()),
        [] => Err(ScpiError::new(
            -109,
            ":TRAC:DATA needs data after the offset",
        )),
        values => values
            .iter()
            .map(|v| {
                let v = text(v)?;
                let n = numeric::parse_with_unit(&v.to_ascii_uppercase(), numeric::Unit::None)?;
                if n.fract() != 0.0 || !(-128.0..=255.0).contains(&n) {
                    return Err(ScpiError::new(-222, format!("value {v} is not a byte")));
                }
                Ok(n as i16)
            })
            .collect(),
    }
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
