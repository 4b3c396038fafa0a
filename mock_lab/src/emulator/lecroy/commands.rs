//! The legacy (IEEE 488.2-style) LeCroy commands, long and short forms, with sticky header paths.
//!
//! A hand-written dispatcher: header echo in replies, sticky `C1:`/`EX:` paths and `VBS` strings do not
//! fit a SCPI tree (instruments.md section 6).

use std::time::{Duration, Instant};

use super::state::{HeaderMode, ScopeState, TriggerMode};
use super::trigger::Slope;
use super::wavedesc::{SampleWidth, WAVEDESC_LEN};
use super::{Fault, Lecroy, WAVEDESC_INSTRUMENT_NAME};
use crate::emulator::scpi::message::{unquote, Param, Unit};
use crate::emulator::scpi::numeric::{parse_with_unit, Unit as NumUnit};

/// `(long, short)` names of every legacy command the emulator knows.
const COMMANDS: &[(&str, &str)] = &[
    ("COMM_HEADER", "CHDR"),
    ("COMM_FORMAT", "CFMT"),
    ("COMM_ORDER", "CORD"),
    ("WAVEFORM_SETUP", "WFSU"),
    ("TRIG_SELECT", "TRSE"),
    ("TRIG_LEVEL", "TRLV"),
    ("TRIG_SLOPE", "TRSL"),
    ("TRIG_MODE", "TRMD"),
    ("TRIG_DELAY", "TRDL"),
    ("ARM_ACQUISITION", "ARM"),
    ("WAIT", "WAIT"),
    ("FORCE_TRIGGER", "FRTR"),
    ("STOP", "STOP"),
    ("INR", "INR"),
    ("CMR", "CMR"),
    ("EXR", "EXR"),
    ("TIME_DIV", "TDIV"),
    ("VOLT_DIV", "VDIV"),
    ("OFFSET", "OFST"),
    ("TRACE", "TRA"),
    ("WAVEFORM", "WF"),
    ("MEMORY_SIZE", "MSIZ"),
    ("VBS", "VBS"),
];

fn cmd_err(code: u8, text: impl Into<String>) -> Fault {
    Fault::Command(code, text.into())
}

fn exe_err(code: u8, text: impl Into<String>) -> Fault {
    Fault::Execution(code, text.into())
}

/// LeCroy-style number with unit: `2.00E-01 V`.
pub(super) fn number(value: f64, unit: &str) -> String {
    let s = format!("{value:.2E}");
    let formatted = match s.split_once('E') {
        Some((m, e)) => {
            let e: i32 = e.parse().unwrap_or(0);
            format!("{m}E{}{:02}", if e < 0 { '-' } else { '+' }, e.abs())
        }
        None => s,
    };
    if unit.is_empty() {
        formatted
    } else {
        format!("{formatted} {unit}")
    }
}

fn text(p: &Param) -> Result<&str, Fault> {
    p.text()
        .map(str::trim)
        .ok_or_else(|| cmd_err(10, "a block is not allowed here"))
}

fn one<'a>(params: &'a [Param], name: &str) -> Result<&'a str, Fault> {
    match params {
        [p] => text(p),
        [] => Err(exe_err(27, format!("{name} needs a parameter"))),
        _ => Err(exe_err(25, format!("{name} takes one parameter"))),
    }
}

fn value(text: &str, unit: NumUnit) -> Result<f64, Fault> {
    parse_with_unit(&text.to_ascii_uppercase(), unit)
        .map_err(|_| cmd_err(3, format!("{text:?} is not a number")))
}

/// Clamps into `min..=max`, flagging VAB when the value had to be adapted.
fn adapt(st: &mut ScopeState, v: f64, min: f64, max: f64) -> f64 {
    let clamped = v.clamp(min, max);
    if clamped != v {
        st.value_adapted = true;
    }
    clamped
}

impl Lecroy {
    fn reply(
        &self,
        st: &ScopeState,
        path: Option<&str>,
        names: (&str, &str),
        body: &str,
    ) -> Vec<u8> {
        let prefix = path.map(|p| format!("{p}:")).unwrap_or_default();
        match st.header {
            HeaderMode::Off => body.as_bytes().to_vec(),
            HeaderMode::Short => format!("{prefix}{} {body}", names.1).into_bytes(),
            HeaderMode::Long => format!("{prefix}{} {body}", names.0).into_bytes(),
        }
    }

    fn valid_path(&self, path: &str) -> bool {
        let channels = self.model.limits.channels;
        let channel_ok = path
            .strip_prefix('C')
            .and_then(|n| n.parse::<u8>().ok())
            .is_some_and(|n| (1..=channels).contains(&n));
        channel_ok || matches!(path, "EX" | "EX10" | "LINE")
    }

    fn channel_index(path: &str) -> Option<usize> {
        path.strip_prefix('C')
            .and_then(|n| n.parse::<usize>().ok())
            .and_then(|n| n.checked_sub(1))
    }

    pub(super) fn run_unit(&self, unit: &Unit) -> Result<Option<Vec<u8>>, Fault> {
        let header = unit.header.to_ascii_uppercase();
        let query = header.ends_with('?');
        let body = header.trim_end_matches('?');
        if body.starts_with('*') {
            return self.common(body, query, &unit.params);
        }
        let (path, name) = match body.split(':').collect::<Vec<_>>()[..] {
            [name] => (None, name),
            [path, name] => (Some(path), name),
            _ => {
                return Err(cmd_err(
                    2,
                    format!("illegal header path in {}", unit.header),
                ))
            }
        };
        if let Some(p) = path {
            if !self.valid_path(p) {
                return Err(cmd_err(2, format!("illegal header path {p}")));
            }
            self.lock().path = p.to_string();
        }
        let names = COMMANDS
            .iter()
            .find(|(long, short)| name == *long || name == *short)
            .copied()
            .ok_or_else(|| cmd_err(1, format!("unrecognized command header {}", unit.header)))?;
        self.legacy(names, query, &unit.params)
    }

    fn common(&self, name: &str, query: bool, params: &[Param]) -> Result<Option<Vec<u8>>, Fault> {
        let names = (name, name);
        let mut st = self.lock();
        let reply = |st: &ScopeState, body: String| Some(self.reply(st, None, names, &body));
        match (name, query) {
            ("*IDN", true) => Ok(reply(&st, self.model.identity.idn())),
            ("*RST", false) => {
                let remote = st.remote;
                *st = ScopeState::reset(&self.model, remote);
                Ok(None)
            }
            ("*CLS", false) => {
                st.esr = 0;
                st.cmr = 0;
                st.exr = 0;
                st.value_adapted = false;
                st.new_acquisition = false;
                Ok(None)
            }
            ("*STB", true) => Ok(reply(&st, st.status_byte().to_string())),
            ("*OPC", true) => {
                drop(st);
                self.settle(Instant::now());
                let st = self.lock();
                Ok(reply(&st, "1".into()))
            }
            ("*OPC", false) => {
                st.esr |= 1;
                Ok(None)
            }
            ("*ESR", true) => {
                let v = st.esr;
                st.esr = 0;
                Ok(reply(&st, v.to_string()))
            }
            ("*ESE", true) => Ok(reply(&st, st.ese.to_string())),
            ("*SRE", true) => Ok(reply(&st, st.sre.to_string())),
            ("*ESE", false) | ("*SRE", false) => {
                let v = value(one(params, name)?, NumUnit::None)?;
                if !(0.0..=255.0).contains(&v) {
                    return Err(exe_err(25, format!("{name} takes 0..=255")));
                }
                if name == "*ESE" {
                    st.ese = v as u8;
                } else {
                    st.sre = v as u8;
                }
                Ok(None)
            }
            ("*TST", true) => Ok(reply(&st, "0".into())),
            ("*WAI", false) => Ok(None),
            ("*TRG", false) => {
                drop(st);
                self.force();
                Ok(None)
            }
            _ => Err(cmd_err(1, format!("unrecognized command header {name}"))),
        }
    }

    fn legacy(
        &self,
        names: (&'static str, &'static str),
        query: bool,
        params: &[Param],
    ) -> Result<Option<Vec<u8>>, Fault> {
        let short = names.1;
        match short {
            "ARM" | "FRTR" | "STOP" | "WAIT" if query => {
                Err(cmd_err(1, format!("{short} has no query form")))
            }
            "INR" | "CMR" | "EXR" if !query => Err(cmd_err(1, format!("{short} is a query only"))),
            "ARM" => {
                self.lock().arm();
                Ok(None)
            }
            "FRTR" => {
                self.force();
                Ok(None)
            }
            "STOP" => {
                let mut st = self.lock();
                st.trigger_mode = TriggerMode::Stop;
                st.armed = false;
                Ok(None)
            }
            "WAIT" => {
                let limit = match params {
                    [] => self.wait_cap(),
                    [p] => {
                        let seconds = value(text(p)?, NumUnit::Second)?;
                        if seconds.is_nan() || seconds < 0.0 {
                            return Err(exe_err(25, "WAIT takes a non-negative timeout"));
                        }
                        Duration::from_secs_f64(seconds.min(self.wait_cap().as_secs_f64()))
                    }
                    _ => return Err(exe_err(25, "WAIT takes at most one parameter")),
                };
                self.settle(Instant::now() + limit);
                Ok(None)
            }
            "INR" => {
                self.settle(Instant::now());
                let mut st = self.lock();
                let v = st.read_inr();
                Ok(Some(self.reply(&st, None, names, &v.to_string())))
            }
            "CMR" | "EXR" => {
                let mut st = self.lock();
                let v = if short == "CMR" {
                    std::mem::take(&mut st.cmr)
                } else {
                    std::mem::take(&mut st.exr)
                };
                Ok(Some(self.reply(&st, None, names, &v.to_string())))
            }
            "WF" => self.waveform_query(names, query, params),
            "VBS" => {
                let statement = unquote(one(params, "VBS")?).to_string();
                let result = self.vbs(&statement, query)?;
                let st = self.lock();
                Ok(result.map(|body| self.reply(&st, None, names, &body)))
            }
            _ => self.setting(names, query, params),
        }
    }

    fn waveform_query(
        &self,
        names: (&'static str, &'static str),
        query: bool,
        params: &[Param],
    ) -> Result<Option<Vec<u8>>, Fault> {
        if !query {
            return Err(exe_err(
                26,
                "waveform upload to the scope is not implemented",
            ));
        }
        let part = match params {
            [] => "ALL".to_string(),
            [p] => text(p)?.to_ascii_uppercase(),
            _ => return Err(exe_err(25, "WF? takes one of ALL, DESC, DAT1")),
        };
        if !matches!(part.as_str(), "ALL" | "DESC" | "DAT1") {
            return Err(exe_err(
                26,
                format!("WF? {part} is not implemented; use ALL, DESC or DAT1"),
            ));
        }
        self.settle(Instant::now());
        let st = self.lock();
        let path = st.path.clone();
        let Some(index) = Self::channel_index(&path) else {
            return Err(exe_err(
                22,
                format!(
                    "{path} is not a channel; use C1..C{}",
                    self.model.limits.channels
                ),
            ));
        };
        let full = st.waveform(&self.model, index, WAVEDESC_INSTRUMENT_NAME);
        let content = &full[11..];
        let payload: &[u8] = match part.as_str() {
            "DESC" => &content[..WAVEDESC_LEN],
            "DAT1" => &content[WAVEDESC_LEN..],
            _ => content,
        };
        let mut out = match st.header {
            HeaderMode::Off => format!("{part},"),
            HeaderMode::Short => format!("{path}:{} {part},", names.1),
            HeaderMode::Long => format!("{path}:{} {part},", names.0),
        }
        .into_bytes();
        out.extend_from_slice(format!("#9{:09}", payload.len()).as_bytes());
        out.extend_from_slice(payload);
        Ok(Some(out))
    }

    /// Commands that set or read one setting.
    fn setting(
        &self,
        names: (&'static str, &'static str),
        query: bool,
        params: &[Param],
    ) -> Result<Option<Vec<u8>>, Fault> {
        let short = names.1;
        if query && short == "TRMD" {
            self.settle(Instant::now());
        }
        let mut st = self.lock();
        let path = st.path.clone();
        let limits = &self.model.limits;
        if query {
            let (path_shown, body) = match short {
                "CHDR" => (
                    None,
                    match st.header {
                        HeaderMode::Off => "OFF",
                        HeaderMode::Short => "SHORT",
                        HeaderMode::Long => "LONG",
                    }
                    .to_string(),
                ),
                "CFMT" => (
                    None,
                    format!(
                        "DEF9,{},BIN",
                        if st.width == SampleWidth::Word {
                            "WORD"
                        } else {
                            "BYTE"
                        }
                    ),
                ),
                "CORD" => (
                    None,
                    match st.order {
                        super::wavedesc::ByteOrder::HiFirst => "HI",
                        super::wavedesc::ByteOrder::LoFirst => "LO",
                    }
                    .to_string(),
                ),
                "WFSU" => {
                    let w = st.window;
                    (
                        None,
                        format!(
                            "SP,{},NP,{},FP,{},SN,{}",
                            w.sparsing, w.points, w.first, w.segment
                        ),
                    )
                }
                "TRSE" => (
                    None,
                    format!("{},SR,{},HT,OFF", st.trigger_type, st.trigger_source),
                ),
                "TRLV" => (Some(path.as_str()), number(st.level(&path), "V")),
                "TRSL" => (
                    Some(path.as_str()),
                    match st.slope(&path) {
                        Slope::Positive => "POS",
                        Slope::Negative => "NEG",
                        Slope::Either => "WINDOW",
                    }
                    .to_string(),
                ),
                "TRMD" => (None, st.trigger_mode.keyword().to_string()),
                "TRDL" => (None, number(st.trigger_delay_s, "S")),
                "TDIV" => (None, number(st.hor_scale, "S")),
                "MSIZ" => (None, number(st.max_samples as f64, "")),
                "VDIV" | "OFST" | "TRA" => {
                    let index = Self::channel_index(&path).ok_or_else(|| {
                        exe_err(22, format!("{short} needs a channel path (C1:..)"))
                    })?;
                    let c = &st.channels[index];
                    let body = match short {
                        "VDIV" => number(c.volts_per_div, "V"),
                        "OFST" => number(c.offset_v, "V"),
                        _ => if c.on { "ON" } else { "OFF" }.to_string(),
                    };
                    (Some(path.as_str()), body)
                }
                _ => return Err(cmd_err(1, format!("{short} has no query form"))),
            };
            return Ok(Some(self.reply(&st, path_shown, names, &body)));
        }
        match short {
            "CHDR" => {
                st.header = match one(params, short)?.to_ascii_uppercase().as_str() {
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
            }
            "CFMT" => {
                let words: Vec<String> = params
                    .iter()
                    .map(|p| text(p).map(str::to_ascii_uppercase))
                    .collect::<Result<_, _>>()?;
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
                    Some(other) => {
                        return Err(cmd_err(5, format!("CFMT width {other}: use BYTE or WORD")))
                    }
                }
            }
            "CORD" => {
                st.order = match one(params, short)?.to_ascii_uppercase().as_str() {
                    "HI" => super::wavedesc::ByteOrder::HiFirst,
                    "LO" => super::wavedesc::ByteOrder::LoFirst,
                    other => return Err(cmd_err(5, format!("CORD takes HI or LO, not {other}"))),
                };
            }
            "WFSU" => {
                if params.is_empty() || params.len() % 2 != 0 {
                    return Err(exe_err(
                        27,
                        "WFSU takes name,value pairs: SP,n,NP,n,FP,n,SN,n",
                    ));
                }
                let mut window = st.window;
                for pair in params.chunks_exact(2) {
                    let key = text(&pair[0])?.to_ascii_uppercase();
                    let v = value(text(&pair[1])?, NumUnit::None)?;
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
            }
            "TRSE" => {
                let words: Vec<String> = params
                    .iter()
                    .map(|p| text(p).map(str::to_ascii_uppercase))
                    .collect::<Result<_, _>>()?;
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
                for pair in pairs.chunks_exact(2) {
                    match pair[0].as_str() {
                        "SR" => {
                            if !limits.trigger_sources.iter().any(|s| s == &pair[1]) {
                                return Err(exe_err(
                                    25,
                                    format!(
                                        "trigger source {} is not one of {}",
                                        pair[1],
                                        limits.trigger_sources.join(", ")
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
            }
            "TRLV" => {
                let v = value(one(params, short)?, NumUnit::Volt)?;
                let (min, max) = match path.as_str() {
                    "EX" => (
                        limits.ext_trigger_level_v_min,
                        limits.ext_trigger_level_v_max,
                    ),
                    "EX10" => (
                        limits.ext_trigger_level_v_min * 10.0,
                        limits.ext_trigger_level_v_max * 10.0,
                    ),
                    p => match Self::channel_index(p) {
                        Some(i) => {
                            let span = st.channels[i].volts_per_div
                                * f64::from(limits.vertical_divisions)
                                / 2.0;
                            (-span, span)
                        }
                        None => return Err(exe_err(22, format!("{p} has no trigger level"))),
                    },
                };
                let v = adapt(&mut st, v, min, max);
                st.set_level(&path, v);
            }
            "TRSL" => {
                let slope = match one(params, short)?.to_ascii_uppercase().as_str() {
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
                st.set_slope(&path, slope);
            }
            "TRMD" => {
                let mode = match one(params, short)?.to_ascii_uppercase().as_str() {
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
                set_trigger_mode(&mut st, mode);
            }
            "TRDL" => {
                let v = value(one(params, short)?, NumUnit::Second)?;
                let max = st.hor_scale * f64::from(limits.horizontal_divisions) / 2.0;
                let min = -st.hor_scale * 10_000.0;
                st.trigger_delay_s = adapt(&mut st, v, min, max);
            }
            "TDIV" => {
                let v = value(one(params, short)?, NumUnit::Second)?;
                let v = adapt(&mut st, v, 1e-12, 1e3);
                st.hor_scale = v;
                let wanted = f64::from(limits.horizontal_divisions)
                    * v
                    * ScopeState::sample_rate(&self.model);
                if wanted.round() as u64 > st.record_points(&self.model) {
                    st.value_adapted = true;
                }
            }
            "MSIZ" => {
                let t = one(params, short)?.to_ascii_uppercase();
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
                let v = value(&digits, NumUnit::None)? * mult;
                let max = limits.max_points_per_channel as f64;
                st.max_samples = adapt(&mut st, v, 1.0, max).round() as u64;
            }
            "VDIV" | "OFST" | "TRA" => {
                let index = Self::channel_index(&path)
                    .ok_or_else(|| exe_err(22, format!("{short} needs a channel path (C1:..)")))?;
                let arg = one(params, short)?;
                match short {
                    "VDIV" => {
                        let v = value(arg, NumUnit::Volt)?;
                        let v = adapt(
                            &mut st,
                            v,
                            limits.volts_per_div_min,
                            limits.volts_per_div_max,
                        );
                        st.channels[index].volts_per_div = v;
                    }
                    "OFST" => {
                        let v = value(arg, NumUnit::Volt)?;
                        let v = adapt(&mut st, v, limits.offset_v_min, limits.offset_v_max);
                        st.channels[index].offset_v = v;
                    }
                    _ => {
                        st.channels[index].on = match arg.to_ascii_uppercase().as_str() {
                            "ON" => true,
                            "OFF" => false,
                            other => {
                                return Err(cmd_err(5, format!("TRA takes ON or OFF, not {other}")))
                            }
                        }
                    }
                }
            }
            _ => return Err(cmd_err(1, format!("{short} takes no parameters here"))),
        }
        Ok(None)
    }
}

/// Changing the trigger mode arms (SINGLE, NORM, AUTO) or stops the acquisition system.
pub(super) fn set_trigger_mode(st: &mut ScopeState, mode: TriggerMode) {
    st.trigger_mode = mode;
    if mode == TriggerMode::Stop {
        st.armed = false;
    } else {
        st.arm();
    }
}

#[cfg(test)]
mod tests {
    use super::number;

    #[test]
    fn lecroy_number_format() {
        assert_eq!(number(0.2, "V"), "2.00E-01 V");
        assert_eq!(number(-5e-8, "S"), "-5.00E-08 S");
        assert_eq!(number(32e6, ""), "3.20E+07");
    }
}
