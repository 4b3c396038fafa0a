//! The legacy commands that set or report one setting: a setter and a reporter each, run on the
//! locked scope state by the dispatcher in `commands`. Out-of-range values adapt (and flag VAB),
//! as the scope does; words it does not know are command errors (CMR 5).

use super::params::{
    adapt, channel_index, cmd_err, exe_err, number, one, text, value, words, Call, Report,
};
use super::state::{ChannelSettings, HeaderMode, ScopeState, TriggerMode};
use super::trigger::Slope;
use super::wavedesc::{ByteOrder, SampleWidth};
use super::Fault;
use crate::emulator::scpi::numeric::Unit;

/// `COMM_HEADER`: whether replies repeat the command's header.
pub(super) fn get_header(st: &ScopeState, _: &Call) -> Result<Report, Fault> {
    Ok(Report::plain(match st.header {
        HeaderMode::Off => "OFF",
        HeaderMode::Short => "SHORT",
        HeaderMode::Long => "LONG",
    }))
}

pub(super) fn set_header(st: &mut ScopeState, call: &Call) -> Result<(), Fault> {
    st.header = match call.one()?.to_ascii_uppercase().as_str() {
        "OFF" => HeaderMode::Off,
        "SHORT" | "ON" => HeaderMode::Short,
        "LONG" => HeaderMode::Long,
        other => {
            return Err(cmd_err(
                5,
                format!("CHDR takes OFF, SHORT or LONG, not {other}"),
            ))
        }
    };
    Ok(())
}

/// `COMM_FORMAT`: block format, sample width, encoding.
pub(super) fn get_format(st: &ScopeState, _: &Call) -> Result<Report, Fault> {
    let width = match st.width {
        SampleWidth::Word => "WORD",
        SampleWidth::Byte => "BYTE",
    };
    Ok(Report::plain(format!("DEF9,{width},BIN")))
}

pub(super) fn set_format(st: &mut ScopeState, call: &Call) -> Result<(), Fault> {
    let words = words(call.params)?;
    let (block, width, encoding) = match words.as_slice() {
        [b] => (b.as_str(), None, "BIN"),
        [b, w] => (b.as_str(), Some(w.as_str()), "BIN"),
        [b, w, e] => (b.as_str(), Some(w.as_str()), e.as_str()),
        _ => return Err(exe_err(27, "CFMT takes DEF9,<BYTE|WORD>,BIN")),
    };
    if block != "DEF9" {
        return Err(exe_err(
            26,
            format!("block format {block} is not implemented; use DEF9"),
        ));
    }
    if encoding != "BIN" {
        return Err(exe_err(
            26,
            format!("encoding {encoding} is not implemented; use BIN"),
        ));
    }
    match width {
        None => {}
        Some("BYTE") => st.width = SampleWidth::Byte,
        Some("WORD") => st.width = SampleWidth::Word,
        Some(other) => return Err(cmd_err(5, format!("CFMT width {other}: use BYTE or WORD"))),
    }
    Ok(())
}

/// `COMM_ORDER`: byte order of 16-bit words.
pub(super) fn get_order(st: &ScopeState, _: &Call) -> Result<Report, Fault> {
    Ok(Report::plain(match st.order {
        ByteOrder::HiFirst => "HI",
        ByteOrder::LoFirst => "LO",
    }))
}

pub(super) fn set_order(st: &mut ScopeState, call: &Call) -> Result<(), Fault> {
    st.order = match call.one()?.to_ascii_uppercase().as_str() {
        "HI" => ByteOrder::HiFirst,
        "LO" => ByteOrder::LoFirst,
        other => return Err(cmd_err(5, format!("CORD takes HI or LO, not {other}"))),
    };
    Ok(())
}

/// `WAVEFORM_SETUP`: which points `WF?` transfers.
pub(super) fn get_window(st: &ScopeState, _: &Call) -> Result<Report, Fault> {
    let w = st.window;
    Ok(Report::plain(format!(
        "SP,{},NP,{},FP,{},SN,{}",
        w.sparsing, w.points, w.first, w.segment
    )))
}

pub(super) fn set_window(st: &mut ScopeState, call: &Call) -> Result<(), Fault> {
    let params = call.params;
    if params.is_empty() || params.len() % 2 != 0 {
        return Err(exe_err(
            27,
            "WFSU takes name,value pairs: SP,n,NP,n,FP,n,SN,n",
        ));
    }
    let mut window = st.window;
    for pair in params.chunks_exact(2) {
        let key = text(&pair[0])?.to_ascii_uppercase();
        let v = value(text(&pair[1])?, Unit::None)?;
        if !(v >= 0.0 && v.fract() == 0.0 && v <= f64::from(u32::MAX)) {
            return Err(exe_err(
                25,
                format!("WFSU {key} takes a non-negative integer"),
            ));
        }
        let v = v as u32;
        match key.as_str() {
            "SP" => window.sparsing = v,
            "NP" => window.points = v,
            "FP" => window.first = v,
            "SN" => window.segment = v,
            other => {
                return Err(cmd_err(
                    5,
                    format!("WFSU has no field {other}; use SP, NP, FP, SN"),
                ))
            }
        }
    }
    st.window = window;
    Ok(())
}

/// `TRIG_SELECT`: trigger type and source.
pub(super) fn get_trigger_select(st: &ScopeState, _: &Call) -> Result<Report, Fault> {
    Ok(Report::plain(format!(
        "{},SR,{},HT,OFF",
        st.trigger_type, st.trigger_source
    )))
}

pub(super) fn set_trigger_select(st: &mut ScopeState, call: &Call) -> Result<(), Fault> {
    let words = words(call.params)?;
    let Some((kind, pairs)) = words.split_first() else {
        return Err(exe_err(
            27,
            "TRSE needs a trigger type, e.g. TRSE EDGE,SR,EX",
        ));
    };
    if kind != "EDGE" {
        return Err(exe_err(
            26,
            format!("trigger type {kind} is not implemented; use EDGE"),
        ));
    }
    if pairs.len() % 2 != 0 {
        return Err(exe_err(27, "TRSE takes name,value pairs after the type"));
    }
    let sources = &call.model.limits.trigger_sources;
    for pair in pairs.chunks_exact(2) {
        match pair[0].as_str() {
            "SR" => {
                if !sources.iter().any(|s| s == &pair[1]) {
                    return Err(exe_err(
                        25,
                        format!(
                            "trigger source {} is not one of {}",
                            pair[1],
                            sources.join(", ")
                        ),
                    ));
                }
                st.trigger_source = pair[1].clone();
            }
            "HT" | "HV" | "HV2" => {}
            other => return Err(cmd_err(5, format!("TRSE has no field {other}"))),
        }
    }
    st.trigger_type = kind.clone();
    Ok(())
}

/// `<source>:TRIG_LEVEL`.
pub(super) fn get_trigger_level(st: &ScopeState, call: &Call) -> Result<Report, Fault> {
    Ok(Report::on_path(number(st.level(call.path), "V")))
}

pub(super) fn set_trigger_level(st: &mut ScopeState, call: &Call) -> Result<(), Fault> {
    let v = value(call.one()?, Unit::Volt)?;
    let limits = &call.model.limits;
    let (min, max) = match call.path {
        "EX" => (
            limits.ext_trigger_level_v_min,
            limits.ext_trigger_level_v_max,
        ),
        "EX10" => (
            limits.ext_trigger_level_v_min * 10.0,
            limits.ext_trigger_level_v_max * 10.0,
        ),
        p => match channel_index(p) {
            Some(i) => {
                let span =
                    st.channels[i].volts_per_div * f64::from(limits.vertical_divisions) / 2.0;
                (-span, span)
            }
            None => return Err(exe_err(22, format!("{p} has no trigger level"))),
        },
    };
    let v = adapt(st, v, min, max);
    st.set_level(call.path, v);
    Ok(())
}

/// `<source>:TRIG_SLOPE`.
pub(super) fn get_trigger_slope(st: &ScopeState, call: &Call) -> Result<Report, Fault> {
    Ok(Report::on_path(match st.slope(call.path) {
        Slope::Positive => "POS",
        Slope::Negative => "NEG",
        Slope::Either => "WINDOW",
    }))
}

pub(super) fn set_trigger_slope(st: &mut ScopeState, call: &Call) -> Result<(), Fault> {
    let slope = match call.one()?.to_ascii_uppercase().as_str() {
        "POS" | "POSITIVE" => Slope::Positive,
        "NEG" | "NEGATIVE" => Slope::Negative,
        "WINDOW" | "EITHER" => Slope::Either,
        other => {
            return Err(cmd_err(
                5,
                format!("TRSL takes POS, NEG or WINDOW, not {other}"),
            ))
        }
    };
    st.set_slope(call.path, slope);
    Ok(())
}

/// `TRIG_MODE` (its query runs in `commands`: it first completes a pending acquisition).
pub(super) fn get_trigger_mode(st: &ScopeState, _: &Call) -> Result<Report, Fault> {
    Ok(Report::plain(st.trigger_mode.keyword()))
}

pub(super) fn set_trigger_mode(st: &mut ScopeState, call: &Call) -> Result<(), Fault> {
    let mode = match call.one()?.to_ascii_uppercase().as_str() {
        "AUTO" => TriggerMode::Auto,
        "NORM" | "NORMAL" => TriggerMode::Normal,
        "SINGLE" => TriggerMode::Single,
        "STOP" => TriggerMode::Stop,
        other => {
            return Err(cmd_err(
                5,
                format!("TRMD takes AUTO, NORM, SINGLE or STOP, not {other}"),
            ))
        }
    };
    st.set_trigger_mode(mode);
    Ok(())
}

/// `TRIG_DELAY`: the trigger's position, relative to the grid's centre.
pub(super) fn get_trigger_delay(st: &ScopeState, _: &Call) -> Result<Report, Fault> {
    Ok(Report::plain(number(st.trigger_delay_s, "S")))
}

pub(super) fn set_trigger_delay(st: &mut ScopeState, call: &Call) -> Result<(), Fault> {
    let v = value(call.one()?, Unit::Second)?;
    let max = st.hor_scale * f64::from(call.model.limits.horizontal_divisions) / 2.0;
    let min = -st.hor_scale * 10_000.0;
    st.trigger_delay_s = adapt(st, v, min, max);
    Ok(())
}

/// `TIME_DIV`: the horizontal scale.
pub(super) fn get_time_div(st: &ScopeState, _: &Call) -> Result<Report, Fault> {
    Ok(Report::plain(number(st.hor_scale, "S")))
}

pub(super) fn set_time_div(st: &mut ScopeState, call: &Call) -> Result<(), Fault> {
    let v = value(call.one()?, Unit::Second)?;
    let v = adapt(st, v, 1e-12, 1e3);
    st.set_hor_scale(call.model, v);
    Ok(())
}

/// `MEMORY_SIZE`: the most points per channel.
pub(super) fn get_memory_size(st: &ScopeState, _: &Call) -> Result<Report, Fault> {
    Ok(Report::plain(number(st.max_samples as f64, "")))
}

pub(super) fn set_memory_size(st: &mut ScopeState, call: &Call) -> Result<(), Fault> {
    let t = call.one()?.to_ascii_uppercase();
    let (digits, mult) = match t.strip_suffix("MA").or_else(|| t.strip_suffix('M')) {
        Some(d) => (d.to_string(), 1e6),
        None => match t.strip_suffix('K') {
            Some(d) => (d.to_string(), 1e3),
            None => match t.strip_suffix('G') {
                Some(d) => (d.to_string(), 1e9),
                None => (t.clone(), 1.0),
            },
        },
    };
    let v = value(&digits, Unit::None)? * mult;
    let max = call.model.limits.max_points_per_channel as f64;
    st.max_samples = adapt(st, v, 1.0, max).round() as u64;
    Ok(())
}

/// `C<n>:VOLT_DIV`.
pub(super) fn get_volts_per_div(st: &ScopeState, call: &Call) -> Result<Report, Fault> {
    let c = &st.channels[call.channel()?];
    Ok(Report::on_path(number(c.volts_per_div, "V")))
}

pub(super) fn set_volts_per_div(st: &mut ScopeState, call: &Call) -> Result<(), Fault> {
    let limits = &call.model.limits;
    let (min, max) = (limits.volts_per_div_min, limits.volts_per_div_max);
    set_channel_volts(st, call, min, max, |c| &mut c.volts_per_div)
}

/// `C<n>:OFFSET`.
pub(super) fn get_offset(st: &ScopeState, call: &Call) -> Result<Report, Fault> {
    let c = &st.channels[call.channel()?];
    Ok(Report::on_path(number(c.offset_v, "V")))
}

pub(super) fn set_offset(st: &mut ScopeState, call: &Call) -> Result<(), Fault> {
    let limits = &call.model.limits;
    let (min, max) = (limits.offset_v_min, limits.offset_v_max);
    set_channel_volts(st, call, min, max, |c| &mut c.offset_v)
}

/// Sets a channel's value in volts, adapted into `min..=max`.
fn set_channel_volts(
    st: &mut ScopeState,
    call: &Call,
    min: f64,
    max: f64,
    field: fn(&mut ChannelSettings) -> &mut f64,
) -> Result<(), Fault> {
    let index = call.channel()?;
    let v = value(call.one()?, Unit::Volt)?;
    let v = adapt(st, v, min, max);
    *field(&mut st.channels[index]) = v;
    Ok(())
}

/// `C<n>:TRACE`: whether the channel is shown (and acquired).
pub(super) fn get_trace(st: &ScopeState, call: &Call) -> Result<Report, Fault> {
    let on = st.channels[call.channel()?].on;
    Ok(Report::on_path(if on { "ON" } else { "OFF" }))
}

pub(super) fn set_trace(st: &mut ScopeState, call: &Call) -> Result<(), Fault> {
    let index = call.channel()?;
    st.channels[index].on = match call.one()?.to_ascii_uppercase().as_str() {
        "ON" => true,
        "OFF" => false,
        other => return Err(cmd_err(5, format!("TRA takes ON or OFF, not {other}"))),
    };
    Ok(())
}

impl Call<'_> {
    /// The command's one parameter.
    pub(super) fn one(&self) -> Result<&str, Fault> {
        one(self.params, self.names.1)
    }

    /// The channel index of the current path, which must be `C<n>`.
    pub(super) fn channel(&self) -> Result<usize, Fault> {
        channel_index(self.path)
            .ok_or_else(|| exe_err(22, format!("{} needs a channel path (C1:..)", self.names.1)))
    }
}

/// `REFERENCE_CLOCK`: the timebase's reference, the scope's own or the 10 MHz on its rear input.
pub(super) fn get_reference_clock(st: &ScopeState, _: &Call) -> Result<Report, Fault> {
    Ok(Report::plain(st.reference_clock.clone()))
}

pub(super) fn set_reference_clock(st: &mut ScopeState, call: &Call) -> Result<(), Fault> {
    st.reference_clock = match call.one()?.to_ascii_uppercase().as_str() {
        "INT" | "INTERNAL" => "INTERNAL".into(),
        "EXT" | "EXTERNAL" => "EXTERNAL".into(),
        other => {
            return Err(cmd_err(
                5,
                format!("RCLK takes INTERNAL or EXTERNAL, not {other}"),
            ))
        }
    };
    Ok(())
}
