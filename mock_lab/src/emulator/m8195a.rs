//! Keysight M8195A emulator: the SCPI command tree a driver uses and its common neighbours, the
//! instrument's rules (raster range, granularity and minimum length per divider, amplitude ranges,
//! no output or run without a waveform), real SCPI error codes, and the played waveform for the scene.
//!
//! Parsing: IEEE 488.2 messages are split by `scpi::message` (block-aware),
//! headers matched against the manual-style table in `commands` (see there why not the `scpi` crate).
//! Command errors (`-1xx`) abandon the rest of the program message, as IEEE 488.2 requires; execution
//! errors (`-2xx`) are queued and the following units still run. Several queries in one message are
//! answered in one response, separated by `;`.

mod commands;
mod handlers;
mod inner;
mod state;

use std::sync::Mutex;

pub use state::{AwgState, Channel, ChannelPlayback, Memory, Playback, Segment};

use self::commands::Entry;
use self::handlers::Call;
use self::inner::Inner;
use super::received_log::ReceivedLog;
use super::scpi::error_queue::{ErrorQueue, ScpiError};
use super::scpi::header::{Header, PathContext, Pattern};
use super::scpi::message::{parse_unit, split_units, Param, Unit};
use super::scpi::numeric;
use crate::catalog::{self, AwgModel, CatalogError};
use crate::server::Handler;

/// Entries kept in the received-message log.
const LOG_CAPACITY: usize = 1000;
/// Entries kept in the SCPI error queue.
const ERROR_QUEUE_CAPACITY: usize = 30;

/// IEEE 488.2 standard event status register bits.
mod esr {
    pub(super) const OPC: u8 = 0x01;
    pub(super) const QUERY_ERROR: u8 = 0x04;
    pub(super) const DEVICE_ERROR: u8 = 0x08;
    pub(super) const EXECUTION_ERROR: u8 = 0x10;
    pub(super) const COMMAND_ERROR: u8 = 0x20;
}

/// The emulated M8195A.
pub struct M8195a {
    model: AwgModel,
    tree: Vec<(Pattern, &'static Entry)>,
    inner: Mutex<Inner>,
    log: ReceivedLog,
}

impl M8195a {
    /// Makes `*OPT?` answer `options` (a unit with other options than the catalog lists, for
    /// `doctor --verify-catalog`'s tests); `None`: the catalog's again.
    pub(crate) fn set_options(&self, options: Option<Vec<String>>) {
        self.lock().options = options;
    }

    /// Makes `:FREQ:RAST? MAX` answer `max` (a unit with another limit than the catalog's, for
    /// `doctor --verify-catalog`'s tests); `None`: the catalog's again.
    pub(crate) fn set_raster_max(&self, max: Option<f64>) {
        self.lock().raster_max = max;
    }

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
                options: None,
                raster_max: None,
                playback: None,
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
        let mut inner = self.lock();
        if let Some(playback) = &inner.playback {
            return playback.clone();
        }
        let playback = inner.state.playback(&self.model);
        inner.playback = Some(playback.clone());
        playback
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
        inner.playback = None;
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
            for (pattern, entry) in &self.tree {
                let Some(suffixes) = pattern.matches(&nodes) else {
                    continue;
                };
                path.matched(&nodes);
                let Some(form) = entry.form(header.query) else {
                    let form = if header.query { "query" } else { "command" };
                    return Err(ScpiError::new(
                        -113,
                        format!("{} has no {form} form", unit.header),
                    ));
                };
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
                let call = Call {
                    model: &self.model,
                    channel,
                    header: &unit.header,
                    params: &unit.params,
                };
                return form.run(inner, &call);
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
            "*OPT?" => no_params(Some(
                inner
                    .options
                    .as_ref()
                    .unwrap_or(&self.model.limits.options)
                    .join(","),
            )),
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

fn one_text<'a>(params: &'a [Param], header: &str) -> Result<&'a str, ScpiError> {
    match params {
        [p] => handlers::text(p),
        [] => Err(ScpiError::new(-109, format!("{header} needs a parameter"))),
        _ => Err(ScpiError::new(
            -108,
            format!("{header} takes one parameter"),
        )),
    }
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
