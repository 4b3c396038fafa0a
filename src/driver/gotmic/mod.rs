//! Gotmic E-band transmitter and receiver modules over serial, through the line protocol the
//! catalog describes (`commands`; the built-in description is the project-defined protocol, not
//! the vendor's, which is not public).
//!
//! The grammar (framing, checksum, request and reply words, number formats) and the register map
//! (addresses, bit positions, writable ranges, the expected module ID) come from the catalog, so
//! a module's real protocol replaces them as data. Safety: enabling needs an
//! [`RfPermit`]; attenuation goes to maximum before the enable; latched faults, interlock, over
//! temperature and LO lock are checked; every write is read back; any failure after the enable
//! switches the module off again before the error is returned.

pub(crate) mod commands;

use self::commands::{Grammar, Reply};
use super::capability::{ReadyToEnable, RfFrontEnd, RfSettings, RfStatus};
use super::error::{session, DriverError};
use super::identity;
use super::io::{session_options, BoxFuture, InstrumentIo};
use super::limits::within;
use super::permit::RfPermit;
use crate::address::Resource;
use crate::catalog::{Checksum, InstrumentModel, Register, RfDirection, RfLimits};
use crate::session::{Crc8, Identity, Session};
use crate::transport::{Journal, SerialSettings};

/// The registers and bits the driver uses, resolved from the catalog once.
#[derive(Debug, Clone)]
struct Map {
    id: Register,
    status: Register,
    control: Register,
    attenuation: Register,
    temperature: Register,
    faults: Register,
    lo_frequency: Option<Register>,
    enable_mask: u16,
}

fn find(model: &InstrumentModel, name: &str) -> Result<Register, DriverError> {
    model
        .registers
        .iter()
        .find(|r| r.name == name)
        .cloned()
        .ok_or_else(|| DriverError::Catalog {
            key: model.instrument.key.clone(),
            reason: format!("the register map has no {name} register"),
        })
}

fn bit(model: &InstrumentModel, register: &Register, field: &str) -> Result<u16, DriverError> {
    register
        .bit(field)
        .filter(|b| *b < 16)
        .map(|b| 1u16 << b)
        .ok_or_else(|| DriverError::Catalog {
            key: model.instrument.key.clone(),
            reason: format!("register {} has no bit field {field}", register.name),
        })
}

impl Map {
    fn resolve(model: &InstrumentModel) -> Result<Map, DriverError> {
        let control = find(model, "CONTROL")?;
        let mut enable_mask =
            bit(model, &control, "MASTER_ENABLE")? | bit(model, &control, "AMP_ENABLE")?;
        // Optional enables (LO multiplier, I/Q (de)modulator) are switched with the rest when the
        // map has them.
        for optional in ["LO_MULTIPLIER_ENABLE", "IQ_ENABLE"] {
            if let Ok(b) = bit(model, &control, optional) {
                enable_mask |= b;
            }
        }
        let status = find(model, "STATUS")?;
        for field in [
            "LO_LOCKED",
            "RF_ENABLED",
            "OVER_TEMPERATURE",
            "INTERLOCK_OPEN",
        ] {
            bit(model, &status, field)?;
        }
        let attenuation = find(model, "GAIN_ATT")?;
        if attenuation.max.is_none() {
            return Err(DriverError::Catalog {
                key: model.instrument.key.clone(),
                reason: "register GAIN_ATT needs a max (the maximum attenuation code)".into(),
            });
        }
        Ok(Map {
            id: find(model, "ID")?,
            status,
            control,
            attenuation,
            temperature: find(model, "TEMP_DC")?,
            faults: find(model, "FAULT_LATCH")?,
            lo_frequency: find(model, "LO_FREQ_MHZ").ok(),
            enable_mask,
        })
    }
}

/// The status bits, CONTROL and the fault latch decoded, with the temperature and attenuation.
fn decode_status(
    map: &Map,
    status: u16,
    control: u16,
    faults: u16,
    temperature_c: f64,
    attenuation_db: f64,
) -> RfStatus {
    let has = |field: &str| {
        map.status
            .bit(field)
            .is_some_and(|b| status & (1 << b) != 0)
    };
    RfStatus {
        powered: has("POWERED"),
        lo_locked: has("LO_LOCKED"),
        rf_enabled: has("RF_ENABLED"),
        over_temperature: has("OVER_TEMPERATURE"),
        interlock_open: has("INTERLOCK_OPEN"),
        faults: map
            .faults
            .fields
            .iter()
            .filter(|f| f.bit < 16 && faults & (1 << f.bit) != 0)
            .map(|f| f.name.clone())
            .collect(),
        control,
        temperature_c,
        attenuation_db,
    }
}

/// How request and reply lines are framed.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Framing {
    /// Bare lines.
    Plain,
    /// `*<hh>` CRC-8 suffix on every request and reply (`CRC ON`), with the catalog's polynomial
    /// and initial value: a corrupted line on the serial link is detected, never acted on.
    Crc8(Crc8),
}

impl Framing {
    /// The framing a module on the wrong CRC mode would answer in: plain lines when the
    /// catalog's are CRC-8 framed, else CRC-8 (the catalog's polynomial, or CRC-8/SMBUS).
    pub(crate) fn other_than_catalog(model: &InstrumentModel) -> Framing {
        match Framing::from_catalog(model) {
            Framing::Crc8(_) => Framing::Plain,
            Framing::Plain => Framing::Crc8(Crc8 {
                poly: model
                    .protocol
                    .as_ref()
                    .map(|p| p.crc_poly)
                    .filter(|&poly| poly != 0)
                    .unwrap_or(0x07),
                init: model.protocol.as_ref().map_or(0x00, |p| p.crc_init),
            }),
        }
    }

    /// CRC-8 when the catalog's `[protocol]` says `checksum = "crc8"`, else plain lines.
    pub fn from_catalog(model: &InstrumentModel) -> Framing {
        match &model.protocol {
            Some(p) if p.checksum == Checksum::Crc8 => Framing::Crc8(Crc8 {
                poly: p.crc_poly,
                init: p.crc_init,
            }),
            _ => Framing::Plain,
        }
    }
}

/// A connected Gotmic module (transmitter or receiver).
pub struct Gotmic {
    io: Box<dyn InstrumentIo>,
    framing: Framing,
    grammar: Grammar,
    model: InstrumentModel,
    limits: RfLimits,
    map: Map,
    identity: Identity,
    name: String,
}

/// Serial settings from the catalog's `[serial]` section.
fn serial_settings(model: &InstrumentModel) -> SerialSettings {
    let mut s = SerialSettings::default();
    if let Some(c) = &model.serial {
        s.baud = c.baud;
        s.data_bits = c.data_bits;
        s.stop_bits = c.stop_bits;
        s.parity = match c.parity {
            crate::catalog::Parity::None => "none",
            crate::catalog::Parity::Even => "even",
            crate::catalog::Parity::Odd => "odd",
        }
        .to_string();
        s.line_terminator = c.line_terminator.clone();
    }
    s
}

impl Gotmic {
    /// Opens the serial resource with the catalog's line settings and timeouts, then connects.
    ///
    /// # Errors
    ///
    /// [`DriverError::Session`] when the serial line cannot be opened, and every error of
    /// [`connect_with`](Gotmic::connect_with).
    pub async fn open(
        resource: Resource,
        model: &InstrumentModel,
        journal: Option<Journal>,
        name: &str,
    ) -> Result<Gotmic, DriverError> {
        Gotmic::open_with(resource, model, journal, name, Framing::from_catalog(model)).await
    }

    /// [`open`](Gotmic::open) with the given framing instead of the catalog's (the bench doctor
    /// tries the other one to tell a line in the wrong CRC mode from a dead one).
    pub(crate) async fn open_with(
        resource: Resource,
        model: &InstrumentModel,
        journal: Option<Journal>,
        name: &str,
        framing: Framing,
    ) -> Result<Gotmic, DriverError> {
        let mut options = session_options(model, "");
        options.link.serial = serial_settings(model);
        // No quiet-line wait before the first request (it cost 50-60 ms per module): the input
        // is flushed at open and before every request, the module answers in order, and the
        // connect's first exchanges find a reply out of step. A reply the previous user of the
        // port left in flight can only be taken for the answer to `CRC ON` (whose answer is not
        // used); the real answer to `CRC ON` is then either flushed before `*IDN?` is sent or
        // read as the identity, which it never is (the connect fails: no CRC, no identity).
        // Once `*IDN?` and the ID register have answered as they must, every reply the module
        // owed anyone before has been sent.
        options.link.serial_on_open = crate::transport::OnOpen::Flush;
        let session = Session::open(resource, options, journal, name)
            .await
            .map_err(session(name))?;
        Gotmic::connect_with(Box::new(session), model, name, framing).await
    }

    /// Identifies the module (`*IDN?` and the ID register) on an open session or a fake, with
    /// plain lines.
    ///
    /// # Errors
    ///
    /// As [`connect_with`](Gotmic::connect_with).
    pub async fn connect(
        io: Box<dyn InstrumentIo>,
        model: &InstrumentModel,
        name: &str,
    ) -> Result<Gotmic, DriverError> {
        Gotmic::connect_with(io, model, name, Framing::Plain).await
    }

    /// Like [`connect`](Gotmic::connect) with the given framing (CRC is switched on first).
    ///
    /// # Errors
    ///
    /// [`DriverError::Catalog`] when the model has no `[rf]` section or its register map does not
    /// resolve; [`DriverError::Session`] when the line fails; [`DriverError::Reply`] or
    /// [`DriverError::LineRefused`] when an answer is unreadable or refused;
    /// [`DriverError::WrongInstrument`] when `*IDN?` or the ID register is not the catalog model.
    pub async fn connect_with(
        io: Box<dyn InstrumentIo>,
        model: &InstrumentModel,
        name: &str,
        framing: Framing,
    ) -> Result<Gotmic, DriverError> {
        let limits = model.rf.clone().ok_or_else(|| DriverError::Catalog {
            key: model.instrument.key.clone(),
            reason: "the model has no [rf] section; it is not an RF front end".into(),
        })?;
        let map = Map::resolve(model)?;
        let mut driver = Gotmic {
            io,
            framing,
            grammar: Grammar::of(model),
            model: model.clone(),
            limits,
            map,
            identity: Identity {
                manufacturer: String::new(),
                model: String::new(),
                serial: String::new(),
                firmware: String::new(),
            },
            name: name.to_string(),
        };
        let checksum_on = match framing {
            Framing::Crc8(_) => driver
                .grammar
                .checksum_on()
                .map(|on| driver.grammar.request(on)),
            Framing::Plain => None,
        };
        if let Some(on) = checksum_on {
            // Sent unframed. Whatever the module answers (OK, or the CRC error of a module
            // already in CRC mode), CRC framing is on afterwards; the framed identity request
            // below proves it.
            let reply = driver.io.query(&on).await.map_err(session(name))?;
            tracing::debug!(instrument = name, "{on} -> {reply}");
        }
        let identify = driver.grammar.identify().to_string();
        let idn_text = driver.line(&identify).await?;
        driver.identity = identity::check(
            model,
            name,
            &driver.io.resource_text(),
            &identify,
            &idn_text,
        )?;
        let id = driver.read(&driver.map.id.clone()).await?;
        if id != driver.map.id.reset {
            return Err(DriverError::WrongInstrument {
                resource: driver.io.resource_text(),
                expected: format!(
                    "{} (ID register 0x{:04X})",
                    driver.model.instrument.model, driver.map.id.reset
                ),
                idn: format!("{} with ID register 0x{id:04X}", driver.identity),
            });
        }
        Ok(driver)
    }

    /// One request line and its reply line, prefixed, framed and checked as configured.
    async fn line(&mut self, request: &str) -> Result<String, DriverError> {
        let request = self.grammar.request(request);
        let (sent, body) = match self.framing {
            Framing::Plain => {
                let reply = self.io.query(&request).await.map_err(session(&self.name))?;
                (request, reply)
            }
            Framing::Crc8(crc) => {
                let sent = crc.frame(&request);
                let reply = self.io.query(&sent).await.map_err(session(&self.name))?;
                let body = crc
                    .unframe(reply.trim())
                    .map(str::to_string)
                    .ok_or_else(|| DriverError::Reply {
                        instrument: self.name.clone(),
                        command: sent.clone(),
                        expected: "a reply ending in a valid *<hh> CRC-8 (check the cable and the line settings)",
                        reply,
                    })?;
                (sent, body)
            }
        };
        match self.grammar.reply(&body) {
            Some(text) => Ok(text.to_string()),
            None => Err(DriverError::Reply {
                instrument: self.name.clone(),
                command: sent,
                expected: "a reply starting with the catalog's protocol.reply_prefix",
                reply: body,
            }),
        }
    }

    pub fn model(&self) -> &InstrumentModel {
        &self.model
    }

    async fn request(&mut self, line: &str) -> Result<Option<u16>, DriverError> {
        let reply = self.line(line).await?;
        match self.grammar.parse_reply(&reply) {
            Some(Reply::Ok(v)) => Ok(v),
            Some(Reply::Err { code, text }) => Err(DriverError::LineRefused {
                instrument: self.name.clone(),
                request: line.to_string(),
                code,
                text,
            }),
            None => Err(DriverError::Reply {
                instrument: self.name.clone(),
                command: line.to_string(),
                expected: "the catalog's reply forms (protocol.reply_ok [value] or \
                           protocol.reply_error <code> <text>)",
                reply: format!("{reply} (expected {})", self.grammar.reply_forms()),
            }),
        }
    }

    async fn read(&mut self, register: &Register) -> Result<u16, DriverError> {
        let line = self.grammar.read(register.address);
        match self.request(&line).await? {
            Some(v) => Ok(v),
            None => Err(DriverError::Reply {
                instrument: self.name.clone(),
                command: line,
                expected: "an acceptance with the register's value",
                reply: "an acceptance without a value".into(),
            }),
        }
    }

    /// Writes a register after checking the catalog's range, then reads it back.
    async fn write_verified(&mut self, register: &Register, value: u16) -> Result<(), DriverError> {
        let (min, max) = (register.min.unwrap_or(0), register.max.unwrap_or(u16::MAX));
        if value < min || value > max {
            return Err(DriverError::OutOfLimits {
                instrument: self.name.clone(),
                field: "register value",
                value: format!("{} = {value}", register.name),
                allowed: format!("{min} ..= {max}"),
            });
        }
        self.request(&self.grammar.write(register.address, value))
            .await?;
        let read = self.read(register).await?;
        if read != value {
            return Err(DriverError::VerifyFailed {
                instrument: self.name.clone(),
                register: register.name.clone(),
                wrote: value,
                read,
            });
        }
        Ok(())
    }

    fn max_attenuation_code(&self) -> u16 {
        self.map.attenuation.max.unwrap_or(0)
    }

    fn attenuation_code(&self, db: f64) -> Result<u16, DriverError> {
        let step = self.limits.attenuation_step_db;
        let max = self.max_attenuation_code();
        let min = self.map.attenuation.min.unwrap_or(0);
        let highest = f64::from(max) * step;
        let lowest = f64::from(min) * step;
        within(&self.name, "attenuation_db", db, lowest, highest, "dB")?;
        Ok(((db / step).round() as u16).clamp(min, max))
    }

    async fn status_impl(&mut self) -> Result<RfStatus, DriverError> {
        let map = self.map.clone();
        let status = self.read(&map.status).await?;
        let control = self.read(&map.control).await?;
        let att = self.read(&map.attenuation).await?;
        let temp = self.read(&map.temperature).await?;
        let faults = self.read(&map.faults).await?;
        let temperature = if map.temperature.signed {
            f64::from(temp as i16)
        } else {
            f64::from(temp)
        } / 10.0;
        Ok(decode_status(
            &map,
            status,
            control,
            faults,
            temperature,
            f64::from(att) * self.limits.attenuation_step_db,
        ))
    }

    fn not_ready(&self, reason: String) -> DriverError {
        DriverError::RfNotReady {
            instrument: self.name.clone(),
            reason,
        }
    }

    async fn enable_impl(&mut self, settings: &RfSettings) -> Result<RfStatus, DriverError> {
        let ready = self.check_impl(settings).await?;
        self.enable_checked_impl(ready).await
    }

    /// Everything checkable before the enable, nothing radiating: the requested attenuation and
    /// LO within the catalog's limits, one look at the module (status, control, attenuation,
    /// temperature, faults), the attenuation at its maximum (read back here, written and
    /// verified only when it is not: the disable leaves it there), the LO register written.
    async fn check_impl(&mut self, settings: &RfSettings) -> Result<ReadyToEnable, DriverError> {
        let code = self.attenuation_code(settings.attenuation_db)?;
        let lo_mhz = match settings.lo_frequency_hz {
            Some(f) => {
                within(
                    &self.name,
                    "lo_frequency_hz",
                    f,
                    self.limits.lo_min_hz,
                    self.limits.lo_max_hz,
                    "Hz",
                )?;
                Some((f / 1e6).round() as u16)
            }
            None => None,
        };
        let map = self.map.clone();
        let before = self.status_impl().await?;
        let max = self.max_attenuation_code();
        let att_code = (before.attenuation_db / self.limits.attenuation_step_db).round();
        if att_code != f64::from(max) {
            self.write_verified(&map.attenuation, max).await?;
        }
        if let (Some(reg), Some(mhz)) = (&map.lo_frequency, lo_mhz) {
            self.write_verified(reg, mhz).await?;
        }
        if !before.faults.is_empty() {
            return Err(self.not_ready(format!(
                "latched faults {:?}: fix their cause, then clear them explicitly (clear_faults) before enabling RF",
                before.faults
            )));
        }
        if before.over_temperature {
            return Err(self.not_ready(format!(
                "over temperature ({} degC, limit {} degC): let the module cool down",
                before.temperature_c, self.limits.over_temperature_c
            )));
        }
        if before.interlock_open && self.limits.enable_requires_interlock_closed {
            return Err(self.not_ready(
                "the interlock is open: close it (waveguide load or antenna connected, door closed) before enabling RF".into(),
            ));
        }
        Ok(ReadyToEnable {
            instrument: self.name.clone(),
            attenuation_code: code,
            before,
        })
    }

    /// Switches on after [`check_impl`](Self::check_impl); any failure switches off again.
    async fn enable_checked_impl(&mut self, ready: ReadyToEnable) -> Result<RfStatus, DriverError> {
        if ready.instrument != self.name {
            return Err(DriverError::Sequence {
                instrument: self.name.clone(),
                what: format!("was given the enable check of `{}`", ready.instrument),
            });
        }
        let result = self.switch_on(ready.attenuation_code, ready.before).await;
        if result.is_err() {
            if let Err(e) = self.disable_impl().await {
                tracing::error!(instrument = %self.name, "switching off after a failed enable failed too: {e}");
            }
        }
        result
    }

    /// Writes the enables, then reads back what RF safety needs: CONTROL (the write took),
    /// STATUS (RF on, LO locked) and the fault latch; then the operating attenuation, verified.
    /// The returned status is that read-back with the verified attenuation (and the temperature
    /// of `before`, read a moment earlier).
    async fn switch_on(&mut self, code: u16, before: RfStatus) -> Result<RfStatus, DriverError> {
        let map = self.map.clone();
        // On (for the live view) from the moment the enable is sent, until a switch-off took.
        crate::driver::rf_state::set(&self.name, true);
        self.request(&self.grammar.write(map.control.address, map.enable_mask))
            .await?;
        let status = self.read(&map.status).await?;
        let control = self.read(&map.control).await?;
        let faults = self.read(&map.faults).await?;
        if control != map.enable_mask {
            return Err(DriverError::VerifyFailed {
                instrument: self.name.clone(),
                register: map.control.name.clone(),
                wrote: map.enable_mask,
                read: control,
            });
        }
        let after = decode_status(
            &map,
            status,
            control,
            faults,
            before.temperature_c,
            before.attenuation_db,
        );
        if self.limits.enable_requires_lo && !after.lo_locked {
            return Err(self.not_ready(format!(
                "the LO is not locked: check the LO input ({} ..= {} Hz, x{} multiplier)",
                self.limits.lo_min_hz, self.limits.lo_max_hz, self.limits.lo_multiplier
            )));
        }
        if !after.rf_enabled {
            return Err(self.not_ready(format!(
                "CONTROL = 0x{:04X} was accepted but STATUS does not report RF enabled",
                map.enable_mask
            )));
        }
        self.write_verified(&map.attenuation, code).await?;
        Ok(RfStatus {
            attenuation_db: f64::from(code) * self.limits.attenuation_step_db,
            ..after
        })
    }

    /// RF off first, then maximum attenuation; both tried, the first error returned.
    async fn disable_impl(&mut self) -> Result<(), DriverError> {
        let map = self.map.clone();
        let mut off = self.write_verified(&map.control, 0).await;
        if let Err(DriverError::Reply { reply, .. }) = &off {
            if self.answers_as_at_power_on(reply) {
                // Power-cycled since its line was switched to CRC-8: the module is at power-on
                // (RF off) and takes plain lines. It is told so in them rather than reported
                // as a safe state that failed.
                tracing::info!(
                    instrument = %self.name,
                    "the module answers in plain lines, as at power-on: RF off in plain lines"
                );
                self.framing = Framing::Plain;
                off = self.write_verified(&map.control, 0).await;
            }
        }
        match &off {
            Err(e) => tracing::error!(instrument = %self.name, "switching RF off failed: {e}"),
            Ok(()) => crate::driver::rf_state::set(&self.name, false),
        }
        let att = self
            .write_verified(&map.attenuation, self.max_attenuation_code())
            .await;
        off.and(att)
    }

    /// After a capture: the module read back as `enabled` left it, or why not (see
    /// [`RfFrontEnd::confirm_enabled`]).
    async fn confirm_enabled_impl(&mut self, enabled: &RfStatus) -> Result<RfStatus, DriverError> {
        let now = match self.status_impl().await {
            Ok(now) => now,
            Err(e) => return Err(self.unreadable_after_capture(e)),
        };
        let step = self.limits.attenuation_step_db;
        let code = |db: f64| (db / step).round() as u16;
        let lost = |found: String, certain: bool| DriverError::StateLost {
            instrument: self.name.clone(),
            found,
            certain,
        };
        if !now.rf_enabled && !now.faults.is_empty() {
            return Err(self.not_ready(format!(
                "RF went off during the capture with latched faults {:?}: fix their cause, then \
                 clear them explicitly (clear_faults) before enabling RF",
                now.faults
            )));
        }
        let power_on = now.control == self.map.control.reset
            && code(now.attenuation_db) == self.map.attenuation.reset;
        if power_on && !now.rf_enabled {
            return Err(lost(
                format!(
                    "the module is back at its power-on state (RF off, CONTROL 0x{:04X}, \
                     attenuation {} dB)",
                    now.control, now.attenuation_db
                ),
                true,
            ));
        }
        if !now.rf_enabled || now.control != enabled.control {
            return Err(lost(
                format!(
                    "RF is {} (CONTROL 0x{:04X}, switched on with 0x{:04X})",
                    if now.rf_enabled { "on" } else { "off" },
                    now.control,
                    enabled.control
                ),
                false,
            ));
        }
        if code(now.attenuation_db) != code(enabled.attenuation_db) {
            return Err(lost(
                format!(
                    "the attenuation is {} dB, set to {} dB",
                    now.attenuation_db, enabled.attenuation_db
                ),
                false,
            ));
        }
        Ok(now)
    }

    /// The read-back after a capture failed: a module that answers in plain lines though it was
    /// switched to CRC framing is back at power-on; one that does not answer (or answers
    /// garbled, or refuses a read it served before) may be.
    fn unreadable_after_capture(&self, e: DriverError) -> DriverError {
        let lost = |found: String, certain: bool| DriverError::StateLost {
            instrument: self.name.clone(),
            found,
            certain,
        };
        match e {
            DriverError::Reply {
                reply, expected, ..
            } if expected.contains("CRC-8") && self.answers_as_at_power_on(&reply) => lost(
                format!(
                    "the module answers without the CRC-8 framing it was switched to, as at \
                     power-on ({:?})",
                    reply.trim()
                ),
                true,
            ),
            DriverError::Session { source, .. } => lost(
                format!("the module did not answer when read back ({source})"),
                false,
            ),
            e @ (DriverError::Reply { .. } | DriverError::LineRefused { .. }) => {
                let text = e.to_string();
                let text = text
                    .strip_prefix(&format!("{}: ", self.name))
                    .unwrap_or(&text)
                    .to_string();
                lost(
                    format!("the module's answer when read back is not as before ({text})"),
                    false,
                )
            }
            e => e,
        }
    }

    /// Whether `reply` (without a valid CRC) is a whole reply in plain lines, as a module whose
    /// CRC framing was switched on answers once it is back at power-on (CRC off).
    fn answers_as_at_power_on(&self, reply: &str) -> bool {
        matches!(self.framing, Framing::Crc8(crc) if crc.unframe(reply.trim()).is_none())
            && self
                .grammar
                .reply(reply.trim())
                .and_then(|body| self.grammar.parse_reply(body))
                .is_some()
    }

    async fn clear_faults_impl(&mut self) -> Result<(), DriverError> {
        let map = self.map.clone();
        let mask = map
            .faults
            .fields
            .iter()
            .filter(|f| f.bit < 16)
            .fold(0u16, |m, f| m | (1 << f.bit));
        self.request(&self.grammar.write(map.faults.address, mask))
            .await?;
        let left = self.read(&map.faults).await?;
        if left != 0 {
            return Err(self.not_ready(format!(
                "faults 0x{left:04X} are still latched after clearing: their cause persists"
            )));
        }
        Ok(())
    }
}

impl RfFrontEnd for Gotmic {
    fn identity(&self) -> &Identity {
        &self.identity
    }

    fn direction(&self) -> RfDirection {
        self.limits.direction
    }

    fn status(&mut self) -> BoxFuture<'_, Result<RfStatus, DriverError>> {
        Box::pin(self.status_impl())
    }

    fn set_attenuation(&mut self, db: f64) -> BoxFuture<'_, Result<f64, DriverError>> {
        Box::pin(async move {
            let code = self.attenuation_code(db)?;
            let reg = self.map.attenuation.clone();
            self.write_verified(&reg, code).await?;
            Ok(f64::from(code) * self.limits.attenuation_step_db)
        })
    }

    fn enable<'a>(
        &'a mut self,
        _permit: &'a RfPermit,
        settings: &'a RfSettings,
    ) -> BoxFuture<'a, Result<RfStatus, DriverError>> {
        Box::pin(self.enable_impl(settings))
    }

    fn check_before_enable<'a>(
        &'a mut self,
        settings: &'a RfSettings,
    ) -> BoxFuture<'a, Result<ReadyToEnable, DriverError>> {
        Box::pin(self.check_impl(settings))
    }

    fn enable_checked<'a>(
        &'a mut self,
        _permit: &'a RfPermit,
        ready: ReadyToEnable,
    ) -> BoxFuture<'a, Result<RfStatus, DriverError>> {
        Box::pin(self.enable_checked_impl(ready))
    }

    fn disable(&mut self) -> BoxFuture<'_, Result<(), DriverError>> {
        Box::pin(self.disable_impl())
    }

    fn confirm_enabled<'a>(
        &'a mut self,
        enabled: &'a RfStatus,
    ) -> BoxFuture<'a, Result<RfStatus, DriverError>> {
        Box::pin(self.confirm_enabled_impl(enabled))
    }

    fn clear_faults(&mut self) -> BoxFuture<'_, Result<(), DriverError>> {
        Box::pin(self.clear_faults_impl())
    }
}
