//! The legacy (IEEE 488.2-style) LeCroy commands, long and short forms, with sticky header paths.
//!
//! A table of commands ([`COMMANDS`]), each form (set, query) a small function: settings run on the
//! locked state (`settings`), actions on the emulator (they wait, acquire, read registers and
//! waveforms). Header echo in replies, sticky `C1:`/`EX:` paths and `VBS` strings do not fit a SCPI
//! tree (instruments.md section 6), hence a table of its own.

use std::time::{Duration, Instant};

use super::params::{channel_index, cmd_err, exe_err, one, text, value, Call, Report};
use super::settings;
use super::state::{HeaderMode, ScopeState, TriggerMode};
use super::wavedesc::{ByteOrder, WAVEDESC_LEN};
use super::{Fault, Lecroy, WAVEDESC_INSTRUMENT_NAME};
use crate::emulator::scpi::message::{unquote, Param, Unit};
use crate::emulator::scpi::numeric::Unit as NumUnit;

type Set = fn(&mut ScopeState, &Call) -> Result<(), Fault>;
type Get = fn(&ScopeState, &Call) -> Result<Report, Fault>;
type Act = fn(&Lecroy, &Call) -> Result<Option<Vec<u8>>, Fault>;

/// How one form of a command runs.
#[derive(Clone, Copy)]
enum Run {
    /// Changes a setting on the locked state.
    Set(Set),
    /// Reports a setting from the locked state.
    Get(Get),
    /// Needs the emulator: waits, acquisitions, registers, waveforms, automation.
    Act(Act),
}

/// One legacy command: its names and its two forms (`None`: the form does not exist).
struct Command {
    long: &'static str,
    short: &'static str,
    set: Option<Run>,
    query: Option<Run>,
}

const fn setting(long: &'static str, short: &'static str, set: Set, get: Get) -> Command {
    Command {
        long,
        short,
        set: Some(Run::Set(set)),
        query: Some(Run::Get(get)),
    }
}

const fn action(long: &'static str, short: &'static str, act: Act) -> Command {
    Command {
        long,
        short,
        set: Some(Run::Act(act)),
        query: None,
    }
}

const fn register(long: &'static str, short: &'static str, read: Act) -> Command {
    Command {
        long,
        short,
        set: None,
        query: Some(Run::Act(read)),
    }
}

/// Every legacy command the emulator knows.
const COMMANDS: &[Command] = &[
    setting(
        "COMM_HEADER",
        "CHDR",
        settings::set_header,
        settings::get_header,
    ),
    setting(
        "COMM_FORMAT",
        "CFMT",
        settings::set_format,
        settings::get_format,
    ),
    setting(
        "COMM_ORDER",
        "CORD",
        settings::set_order,
        settings::get_order,
    ),
    setting(
        "WAVEFORM_SETUP",
        "WFSU",
        settings::set_window,
        settings::get_window,
    ),
    setting(
        "TRIG_SELECT",
        "TRSE",
        settings::set_trigger_select,
        settings::get_trigger_select,
    ),
    setting(
        "TRIG_LEVEL",
        "TRLV",
        settings::set_trigger_level,
        settings::get_trigger_level,
    ),
    setting(
        "TRIG_SLOPE",
        "TRSL",
        settings::set_trigger_slope,
        settings::get_trigger_slope,
    ),
    Command {
        long: "TRIG_MODE",
        short: "TRMD",
        set: Some(Run::Set(settings::set_trigger_mode)),
        query: Some(Run::Act(query_trigger_mode)),
    },
    setting(
        "TRIG_DELAY",
        "TRDL",
        settings::set_trigger_delay,
        settings::get_trigger_delay,
    ),
    action("ARM_ACQUISITION", "ARM", arm),
    action("WAIT", "WAIT", wait),
    action("FORCE_TRIGGER", "FRTR", force_trigger),
    action("STOP", "STOP", stop),
    register("INR", "INR", read_inr),
    register("CMR", "CMR", read_cmr),
    register("EXR", "EXR", read_exr),
    setting(
        "TIME_DIV",
        "TDIV",
        settings::set_time_div,
        settings::get_time_div,
    ),
    setting(
        "VOLT_DIV",
        "VDIV",
        settings::set_volts_per_div,
        settings::get_volts_per_div,
    ),
    setting("OFFSET", "OFST", settings::set_offset, settings::get_offset),
    setting(
        "REFERENCE_CLOCK",
        "RCLK",
        settings::set_reference_clock,
        settings::get_reference_clock,
    ),
    setting("TRACE", "TRA", settings::set_trace, settings::get_trace),
    Command {
        long: "WAVEFORM",
        short: "WF",
        set: Some(Run::Act(refuse_waveform_upload)),
        query: Some(Run::Act(query_waveform)),
    },
    setting(
        "MEMORY_SIZE",
        "MSIZ",
        settings::set_memory_size,
        settings::get_memory_size,
    ),
    Command {
        long: "VBS",
        short: "VBS",
        set: Some(Run::Act(automation)),
        query: Some(Run::Act(automation_query)),
    },
];

impl Lecroy {
    /// A reply in the current header mode: `body`, `TRMD body` or `C1:VDIV body`.
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
        let channel_ok = channel_index(path).is_some_and(|i| i < usize::from(channels));
        channel_ok || matches!(path, "EX" | "EX10" | "LINE")
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
        let command = COMMANDS
            .iter()
            .find(|c| name == c.long || name == c.short)
            .ok_or_else(|| cmd_err(1, format!("unrecognized command header {}", unit.header)))?;
        self.legacy(command, query, &unit.params)
    }

    fn legacy(
        &self,
        command: &Command,
        query: bool,
        params: &[Param],
    ) -> Result<Option<Vec<u8>>, Fault> {
        let short = command.short;
        let form = if query { command.query } else { command.set };
        let Some(run) = form else {
            return Err(cmd_err(
                1,
                if query {
                    format!("{short} has no query form")
                } else {
                    format!("{short} is a query only")
                },
            ));
        };
        let names = (command.long, command.short);
        let path = self.lock().path.clone();
        let call = Call {
            model: &self.model,
            path: &path,
            names,
            params,
        };
        match run {
            Run::Set(set) => set(&mut self.lock(), &call).map(|()| None),
            Run::Get(get) => {
                let st = self.lock();
                let report = get(&st, &call)?;
                let shown = report.on_path.then_some(path.as_str());
                Ok(Some(self.reply(&st, shown, names, &report.body)))
            }
            Run::Act(act) => act(self, &call),
        }
    }

    /// The IEEE 488.2 common commands (`*IDN?`, `*RST`, `*OPC?`, ...).
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
}

/// `TRMD?`: a pending acquisition completes first, so the mode reads as after it.
fn query_trigger_mode(scope: &Lecroy, call: &Call) -> Result<Option<Vec<u8>>, Fault> {
    scope.settle(Instant::now());
    let st = scope.lock();
    let report = settings::get_trigger_mode(&st, call)?;
    Ok(Some(scope.reply(&st, None, call.names, &report.body)))
}

/// `ARM`: arms the acquisition system.
fn arm(scope: &Lecroy, _: &Call) -> Result<Option<Vec<u8>>, Fault> {
    scope.lock().arm();
    Ok(None)
}

/// `FRTR`: one acquisition now, without a trigger.
fn force_trigger(scope: &Lecroy, _: &Call) -> Result<Option<Vec<u8>>, Fault> {
    scope.force();
    Ok(None)
}

/// `STOP`: disarms.
fn stop(scope: &Lecroy, _: &Call) -> Result<Option<Vec<u8>>, Fault> {
    let mut st = scope.lock();
    st.trigger_mode = TriggerMode::Stop;
    st.armed = false;
    Ok(None)
}

/// `WAIT [t]`: blocks the parser until the acquisition completes or `t` passes (capped).
fn wait(scope: &Lecroy, call: &Call) -> Result<Option<Vec<u8>>, Fault> {
    let limit = match call.params {
        [] => scope.wait_cap(),
        [p] => {
            let seconds = value(text(p)?, NumUnit::Second)?;
            if seconds.is_nan() || seconds < 0.0 {
                return Err(exe_err(25, "WAIT takes a non-negative timeout"));
            }
            Duration::from_secs_f64(seconds.min(scope.wait_cap().as_secs_f64()))
        }
        _ => return Err(exe_err(25, "WAIT takes at most one parameter")),
    };
    scope.settle(Instant::now() + limit);
    Ok(None)
}

/// `INR?`: the internal state change register (cleared by reading).
fn read_inr(scope: &Lecroy, call: &Call) -> Result<Option<Vec<u8>>, Fault> {
    scope.settle(Instant::now());
    let mut st = scope.lock();
    let v = st.read_inr();
    Ok(Some(scope.reply(&st, None, call.names, &v.to_string())))
}

/// `CMR?`: the command error register (cleared by reading).
fn read_cmr(scope: &Lecroy, call: &Call) -> Result<Option<Vec<u8>>, Fault> {
    let mut st = scope.lock();
    let v = std::mem::take(&mut st.cmr);
    Ok(Some(scope.reply(&st, None, call.names, &v.to_string())))
}

/// `EXR?`: the execution error register (cleared by reading).
fn read_exr(scope: &Lecroy, call: &Call) -> Result<Option<Vec<u8>>, Fault> {
    let mut st = scope.lock();
    let v = std::mem::take(&mut st.exr);
    Ok(Some(scope.reply(&st, None, call.names, &v.to_string())))
}

/// `VBS '<statement>'`.
fn automation(scope: &Lecroy, call: &Call) -> Result<Option<Vec<u8>>, Fault> {
    run_vbs(scope, call, false)
}

/// `VBS? 'return = <expression>'`.
fn automation_query(scope: &Lecroy, call: &Call) -> Result<Option<Vec<u8>>, Fault> {
    run_vbs(scope, call, true)
}

fn run_vbs(scope: &Lecroy, call: &Call, query: bool) -> Result<Option<Vec<u8>>, Fault> {
    let statement = unquote(one(call.params, "VBS")?).to_string();
    let result = scope.vbs(&statement, query)?;
    let st = scope.lock();
    Ok(result.map(|body| scope.reply(&st, None, call.names, &body)))
}

/// `WF <block>`: uploading a waveform to the scope is not emulated.
fn refuse_waveform_upload(_: &Lecroy, _: &Call) -> Result<Option<Vec<u8>>, Fault> {
    Err(exe_err(
        26,
        "waveform upload to the scope is not implemented",
    ))
}

/// `C<n>:WF? ALL|DESC|DAT1`: the channel's last acquisition as a `#9` block.
fn query_waveform(scope: &Lecroy, call: &Call) -> Result<Option<Vec<u8>>, Fault> {
    let part = match call.params {
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
    scope.settle(Instant::now());
    let st = scope.lock();
    let path = st.path.clone();
    let Some(index) = channel_index(&path) else {
        return Err(exe_err(
            22,
            format!(
                "{path} is not a channel; use C1..C{}",
                scope.model.limits.channels
            ),
        ));
    };
    let (long, short) = call.names;
    let mut out = match st.header {
        HeaderMode::Off => format!("{part},"),
        HeaderMode::Short => format!("{path}:{short} {part},"),
        HeaderMode::Long => format!("{path}:{long} {part},"),
    }
    .into_bytes();
    if part == "ALL" {
        // The whole block, written once into the reply (tens of megabytes).
        st.waveform_into(&mut out, &scope.model, index, WAVEDESC_INSTRUMENT_NAME);
        return Ok(Some(out));
    }
    let full = st.waveform(&scope.model, index, WAVEDESC_INSTRUMENT_NAME);
    let content = &full[11..];
    // DAT1 is the data array alone: past the descriptor and a sequence's TRIGTIME array.
    let trigtime: [u8; 4] = content[48..52].try_into().unwrap_or_default();
    let trigtime = match st.order {
        ByteOrder::LoFirst => u32::from_le_bytes(trigtime),
        ByteOrder::HiFirst => u32::from_be_bytes(trigtime),
    } as usize;
    let payload: &[u8] = if part == "DESC" {
        &content[..WAVEDESC_LEN]
    } else {
        &content[(WAVEDESC_LEN + trigtime).min(content.len())..]
    };
    out.extend_from_slice(format!("#9{:09}", payload.len()).as_bytes());
    out.extend_from_slice(payload);
    Ok(Some(out))
}

#[cfg(test)]
mod tests {
    use super::COMMANDS;

    #[test]
    fn every_command_has_a_form_and_unique_names() {
        for (i, c) in COMMANDS.iter().enumerate() {
            assert!(c.set.is_some() || c.query.is_some(), "{}", c.long);
            for other in &COMMANDS[i + 1..] {
                assert!(
                    c.long != other.long && c.short != other.short,
                    "{} twice",
                    c.long
                );
            }
        }
    }
}
