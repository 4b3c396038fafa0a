//! Gotmic E-band Tx/Rx emulators behind the line protocol their catalog file describes: by default
//! the PROJECT-DEFINED protocol of instruments.md section 5 (the vendor's protocol is not public;
//! this is not it); any other description (`[protocol]`: checksum, prefixes, request and reply
//! words, number formats) is served the same way, so a lab's own description is tested here.
//!
//! One ASCII request per line, one reply line per request; in the built-in spelling:
//!
//! | request | reply |
//! |---|---|
//! | `*IDN?` | `MOCK_LAB,GOTMIC-EBAND-TX-EMU,<serial>,<fw>` |
//! | `R <reg hex>` | `OK <value hex4>` |
//! | `W <reg hex> <value hex>` | `OK` |
//! | `CRC ON` / `CRC OFF` | `OK` |
//! | anything wrong | `ERR <code> <text>[: <detail>]` |
//!
//! With `CRC ON`, every request must end in `*<hh>` (CRC-8 of the text before `*`, polynomial and
//! initial value from the catalog) and every reply carries one. The reply to a `CRC` request is framed
//! in the mode that was in effect when the request arrived.
//!
//! The register map (addresses, access, ranges, bit fields, error codes) comes from the catalog; the
//! emulator addresses registers by name. Safety behaviour: RF is off at power-on; enabling RF is
//! refused while the interlock is open (Tx), the LO is absent, the module is over temperature or a
//! fault is latched; an interlock opening, an LO loss or over-temperature while enabled switches RF
//! off and latches the fault (FAULT_LATCH, write 1 to clear).

use std::sync::{Mutex, MutexGuard};

use super::received_log::ReceivedLog;
use crate::catalog::{self, Access, CatalogError, Checksum, Register, RfModel};
use crate::server::Handler;

const LOG_CAPACITY: usize = 1000;

/// Live conditions around the module and its writable registers.
#[derive(Debug, Clone, PartialEq)]
struct ModuleState {
    /// Values of writable registers by address.
    values: Vec<(u8, u16)>,
    interlock_open: bool,
    lo_present: bool,
    temperature_dc: i16,
    crc: bool,
    /// The CRC mode fixed by the module's own configuration (`None`: `CRC ON|OFF` switch it).
    crc_fixed: Option<bool>,
}

/// What the module does now, for the scene physics and tests.
#[derive(Debug, Clone, PartialEq)]
pub struct FrontEndState {
    /// Master and amplifier enabled: the module radiates (Tx) or amplifies (Rx).
    pub rf_enabled: bool,
    pub lo_multiplier_enabled: bool,
    pub iq_enabled: bool,
    pub attenuation_db: f64,
    pub lo_present: bool,
    pub interlock_open: bool,
    pub temperature_c: f64,
    pub status: u16,
    pub control: u16,
    pub fault_latch: u16,
}

/// An emulated Gotmic module (Tx or Rx, per its catalog file).
pub struct Gotmic {
    model: RfModel,
    inner: Mutex<ModuleState>,
    log: ReceivedLog,
}

/// A protocol error: catalog error name and detail.
struct Refusal {
    name: &'static str,
    detail: String,
}

fn refuse(name: &'static str, detail: impl Into<String>) -> Refusal {
    Refusal {
        name,
        detail: detail.into(),
    }
}

/// CRC-8, MSB first, no reflection, no final XOR (CRC-8/SMBUS with poly 0x07 and init 0x00).
pub fn crc8(data: &[u8], poly: u8, init: u8) -> u8 {
    let mut crc = init;
    for byte in data {
        crc ^= byte;
        for _ in 0..8 {
            crc = if crc & 0x80 != 0 {
                (crc << 1) ^ poly
            } else {
                crc << 1
            };
        }
    }
    crc
}

impl Gotmic {
    /// A module with `model`'s register map and behaviour, in its power-on state: LO present,
    /// interlock closed, ambient temperature, RF off. Refuses a model that lacks a register, bit
    /// field or error name the emulator needs.
    pub fn new(model: RfModel) -> Result<Gotmic, CatalogError> {
        catalog::check_rf(&model)?;
        let values = model
            .registers
            .iter()
            .filter(|r| r.access != Access::Ro)
            .map(|r| (r.address, r.reset))
            .collect();
        let temperature_dc = (model.limits.ambient_temperature_c * 10.0).round() as i16;
        let crc = always_crc(&model);
        Ok(Gotmic {
            inner: Mutex::new(ModuleState {
                values,
                interlock_open: false,
                lo_present: true,
                temperature_dc,
                crc,
                crc_fixed: None,
            }),
            log: ReceivedLog::new("gotmic", LOG_CAPACITY),
            model,
        })
    }

    /// The built-in transmitter model.
    pub fn tx_embedded() -> Result<Gotmic, CatalogError> {
        Gotmic::new(catalog::gotmic_tx()?)
    }

    /// The built-in receiver model.
    pub fn rx_embedded() -> Result<Gotmic, CatalogError> {
        Gotmic::new(catalog::gotmic_rx()?)
    }

    pub fn model(&self) -> &RfModel {
        &self.model
    }

    pub fn log(&self) -> &ReceivedLog {
        &self.log
    }

    fn lock(&self) -> MutexGuard<'_, ModuleState> {
        self.inner.lock().unwrap_or_else(|e| e.into_inner())
    }

    fn reg(&self, name: &str) -> &Register {
        // The catalog reader guarantees the required registers and fields exist.
        self.model
            .register(name)
            .unwrap_or_else(|| unreachable!("Gotmic::new checked register {name}"))
    }

    fn mask(&self, register: &str, field: &str) -> u16 {
        self.reg(register).mask(field).unwrap_or(0)
    }

    fn value(&self, st: &ModuleState, name: &str) -> u16 {
        let address = self.reg(name).address;
        st.values
            .iter()
            .find(|(a, _)| *a == address)
            .map(|(_, v)| *v)
            .unwrap_or(0)
    }

    fn set_value(&self, st: &mut ModuleState, name: &str, value: u16) {
        let address = self.reg(name).address;
        if let Some(slot) = st.values.iter_mut().find(|(a, _)| *a == address) {
            slot.1 = value;
        }
    }

    fn rf_bits(&self) -> u16 {
        self.mask("CONTROL", "MASTER_ENABLE") | self.mask("CONTROL", "AMP_ENABLE")
    }

    fn over_temperature(&self, st: &ModuleState) -> bool {
        f64::from(st.temperature_dc) / 10.0 > self.model.limits.over_temperature_c
    }

    fn status(&self, st: &ModuleState) -> u16 {
        let control = self.value(st, "CONTROL");
        let rf = self.rf_bits();
        let mut status = self.mask("STATUS", "POWERED");
        if st.lo_present {
            status |= self.mask("STATUS", "LO_LOCKED");
        }
        if rf != 0 && control & rf == rf {
            status |= self.mask("STATUS", "RF_ENABLED");
        }
        if self.over_temperature(st) {
            status |= self.mask("STATUS", "OVER_TEMPERATURE");
        }
        if st.interlock_open {
            status |= self.mask("STATUS", "INTERLOCK_OPEN");
        }
        status
    }

    /// Switches RF off and latches `fault` if any RF bit is on.
    fn trip(&self, st: &mut ModuleState, fault: &str) {
        let control = self.value(st, "CONTROL");
        if control & self.rf_bits() != 0 {
            self.set_value(st, "CONTROL", control & !self.rf_bits());
            let latch = self.value(st, "FAULT_LATCH") | self.mask("FAULT_LATCH", fault);
            self.set_value(st, "FAULT_LATCH", latch);
            tracing::warn!(instrument = "gotmic", fault, "RF switched off by a fault");
        }
    }

    /// Opens or closes the safety interlock (bench wiring, tests).
    pub fn set_interlock_open(&self, open: bool) {
        let mut st = self.lock();
        st.interlock_open = open;
        if open && self.model.limits.enable_requires_interlock_closed {
            self.trip(&mut st, "INTERLOCK_OPENED");
        }
    }

    /// Connects or removes the LO input.
    pub fn set_lo_present(&self, present: bool) {
        let mut st = self.lock();
        st.lo_present = present;
        if !present && self.model.limits.enable_requires_lo {
            self.trip(&mut st, "LO_LOST");
        }
    }

    /// Sets the module temperature (above the catalog limit RF trips off).
    pub fn set_temperature_c(&self, celsius: f64) {
        let mut st = self.lock();
        st.temperature_dc = (celsius * 10.0).round().clamp(-32768.0, 32767.0) as i16;
        if self.over_temperature(&st) {
            self.trip(&mut st, "OVER_TEMPERATURE");
        }
    }

    /// Fixes the line's CRC mode as a module configured for one mode only does (`Some(false)`:
    /// plain lines only, `Some(true)`: CRC-framed lines only); `CRC ON|OFF` is then refused.
    /// `None` (power-on) lets `CRC ON|OFF` switch it. A fault for tests of the bench doctor: a
    /// line whose CRC mode is not the one the catalog expects.
    pub fn set_crc_fixed(&self, fixed: Option<bool>) {
        let mut st = self.lock();
        st.crc_fixed = fixed;
        if let Some(mode) = fixed {
            st.crc = mode;
        }
    }

    /// Power off and on again: every writable register back at its reset value (RF off), the
    /// line's CRC mode as at power-on (or as the module's configuration fixes it). The module's
    /// surroundings (interlock, LO, temperature) are not the module's to forget.
    pub fn power_cycle(&self) {
        let mut st = self.lock();
        for (address, value) in st.values.iter_mut() {
            if let Some(r) = self.model.registers.iter().find(|r| r.address == *address) {
                *value = r.reset;
            }
        }
        st.crc = st.crc_fixed.unwrap_or(always_crc(&self.model));
    }

    /// What the module does now.
    pub fn front_end(&self) -> FrontEndState {
        let st = self.lock();
        let control = self.value(&st, "CONTROL");
        let status = self.status(&st);
        FrontEndState {
            rf_enabled: status & self.mask("STATUS", "RF_ENABLED") != 0,
            lo_multiplier_enabled: control & self.mask("CONTROL", "LO_MULTIPLIER_ENABLE") != 0,
            iq_enabled: control & self.mask("CONTROL", "IQ_ENABLE") != 0,
            attenuation_db: f64::from(self.value(&st, "GAIN_ATT"))
                * self.model.limits.attenuation_step_db,
            lo_present: st.lo_present,
            interlock_open: st.interlock_open,
            temperature_c: f64::from(st.temperature_dc) / 10.0,
            status,
            control,
            fault_latch: self.value(&st, "FAULT_LATCH"),
        }
    }

    /// Handles one request line and returns the reply line (without terminator).
    pub fn line(&self, line: &str) -> String {
        self.log.record(line.as_bytes());
        let mut st = self.lock();
        let crc_mode = st.crc;
        let request = line.trim_end_matches(['\r', '\n']).trim();
        let prefix = self.model.protocol.request_prefix.as_str();
        let outcome = self
            .check_crc(request, crc_mode)
            .and_then(|framed| {
                framed
                    .strip_prefix(prefix)
                    .ok_or_else(|| refuse("syntax", format!("requests start with {prefix:?}")))
            })
            .and_then(|body| self.handle(&mut st, body.trim()));
        let reply = match outcome {
            Ok(reply) => reply,
            Err(refusal) => {
                let error = self.model.error(refusal.name);
                let (code, text) = error
                    .map(|e| (e.code, e.text.as_str()))
                    .unwrap_or((1, "error"));
                let err = &self.model.protocol.reply_error;
                if refusal.detail.is_empty() {
                    format!("{err} {code} {text}")
                } else {
                    format!("{err} {code} {text}: {}", refusal.detail)
                }
            }
        };
        let reply = format!("{}{reply}", self.model.protocol.reply_prefix);
        if crc_mode {
            let p = &self.model.protocol;
            format!(
                "{reply}*{:02X}",
                crc8(reply.as_bytes(), p.crc_poly, p.crc_init)
            )
        } else {
            reply
        }
    }

    fn check_crc<'a>(&self, request: &'a str, crc_mode: bool) -> Result<&'a str, Refusal> {
        if !crc_mode {
            return Ok(request);
        }
        let Some((body, sum)) = request.rsplit_once('*').filter(|(b, _)| !b.is_empty()) else {
            return Err(refuse("crc", "CRC is ON: end the request with *<hh>"));
        };
        let p = &self.model.protocol;
        let expected = crc8(body.as_bytes(), p.crc_poly, p.crc_init);
        match u8::from_str_radix(sum, 16) {
            Ok(got) if got == expected && sum.len() == 2 => Ok(body),
            _ => Err(refuse(
                "crc",
                format!("expected *{expected:02X} for {body:?}, got *{sum}"),
            )),
        }
    }

    fn handle(&self, st: &mut ModuleState, body: &str) -> Result<String, Refusal> {
        let p = &self.model.protocol;
        let ok = p.reply_ok.as_str();
        let switchable = p.checksum == Checksum::Crc8;
        let same = |word: &str| !word.is_empty() && body.eq_ignore_ascii_case(word.trim());
        if body.is_empty() {
            return Err(refuse("syntax", "empty request"));
        }
        if same(&p.identify) {
            return Ok(self.model.identity.idn());
        }
        if switchable && (same(&p.checksum_on) || same(&p.checksum_off)) {
            if let Some(fixed) = st.crc_fixed {
                let now = if fixed { "ON" } else { "OFF" };
                return Err(refuse(
                    "syntax",
                    format!("CRC is fixed {now} by the module's configuration"),
                ));
            }
            st.crc = same(&p.checksum_on);
            return Ok(ok.into());
        }
        if let Some([Some(reg), _]) = match_template(&p.read, body) {
            let register = self.register_at(reg)?;
            return Ok(format!(
                "{ok} {}",
                p.value_format.write(self.read(st, register))
            ));
        }
        if let Some([Some(reg), Some(value)]) = match_template(&p.write, body) {
            let register = self.register_at(reg)?;
            let value = p.value_format.read(value).ok_or_else(|| {
                refuse(
                    "syntax",
                    format!("{value:?} is not a value in {:?}", p.value_format),
                )
            })?;
            self.write(st, register, value)?;
            return Ok(ok.into());
        }
        let mut forms = vec![p.identify.clone(), p.read.clone(), p.write.clone()];
        if switchable && !p.checksum_on.is_empty() {
            forms.push(format!("{} | {}", p.checksum_on, p.checksum_off));
        }
        Err(refuse(
            "syntax",
            format!("expected one of: {}", forms.join(", ")),
        ))
    }

    fn register_at(&self, text: &str) -> Result<&Register, Refusal> {
        let format = self.model.protocol.address_format;
        let address = format.read(text).ok_or_else(|| {
            refuse(
                "syntax",
                format!("{text:?} is not a register address in {format:?}"),
            )
        })?;
        self.model
            .registers
            .iter()
            .find(|r| u16::from(r.address) == address)
            .ok_or_else(|| refuse("unknown_register", format!("no register 0x{address:02X}")))
    }

    fn read(&self, st: &ModuleState, register: &Register) -> u16 {
        match register.name.as_str() {
            "STATUS" => self.status(st),
            "TEMP_DC" => st.temperature_dc as u16,
            _ if register.access == Access::Ro => register.reset,
            name => self.value(st, name),
        }
    }

    fn write(&self, st: &mut ModuleState, register: &Register, value: u16) -> Result<(), Refusal> {
        if register.access == Access::Ro {
            return Err(refuse(
                "read_only",
                format!("{} is read-only", register.name),
            ));
        }
        let (min, max) = (register.min.unwrap_or(0), register.max.unwrap_or(u16::MAX));
        if value < min || value > max {
            return Err(refuse(
                "out_of_range",
                format!(
                    "{} takes 0x{min:X}..=0x{max:X}, got 0x{value:X}",
                    register.name
                ),
            ));
        }
        if register.access == Access::Rw1c {
            let current = self.value(st, &register.name);
            self.set_value(st, &register.name, current & !value);
            return Ok(());
        }
        if register.name == "CONTROL" {
            let current = self.value(st, "CONTROL");
            let turning_on = value & self.rf_bits() & !current;
            if turning_on != 0 {
                self.may_enable(st)?;
            }
        }
        self.set_value(st, &register.name, value);
        Ok(())
    }

    fn may_enable(&self, st: &ModuleState) -> Result<(), Refusal> {
        let limits = &self.model.limits;
        if limits.enable_requires_interlock_closed && st.interlock_open {
            return Err(refuse("not_allowed", "interlock open"));
        }
        if limits.enable_requires_lo && !st.lo_present {
            return Err(refuse("not_allowed", "LO not present"));
        }
        if self.over_temperature(st) {
            return Err(refuse("not_allowed", "over temperature"));
        }
        let latch = self.value(st, "FAULT_LATCH");
        if latch != 0 {
            let p = &self.model.protocol;
            let address = p
                .address_format
                .write(u16::from(self.reg("FAULT_LATCH").address));
            let clear = p
                .write
                .replace("{address}", &address)
                .replace("{value}", &p.value_format.write(latch));
            return Err(refuse(
                "not_allowed",
                format!("fault latched (0x{latch:04X}); clear it with {clear}"),
            ));
        }
        Ok(())
    }
}

/// Whether the model's lines always carry the checksum (`crc8` without a request to switch it on).
fn always_crc(model: &RfModel) -> bool {
    model.protocol.checksum == Checksum::Crc8 && model.protocol.checksum_on.trim().is_empty()
}

/// Matches `line` against a request template (`R {address}`, `SET {address}={value}`): the
/// literal text case-insensitively, each placeholder one non-empty word without blanks. Returns
/// `[address, value]` as found.
fn match_template<'a>(template: &str, line: &'a str) -> Option<[Option<&'a str>; 2]> {
    let mut found = [None, None];
    let mut rest = line;
    let mut tpl = template;
    while !tpl.is_empty() {
        let next = ["{address}", "{value}"]
            .iter()
            .enumerate()
            .filter_map(|(k, p)| tpl.find(p).map(|at| (at, k, p.len())))
            .min();
        let Some((at, slot, len)) = next else {
            // Only literal text is left: the line must end with it.
            return rest.eq_ignore_ascii_case(tpl).then_some(found);
        };
        let literal = &tpl[..at];
        if !rest
            .get(..literal.len())
            .is_some_and(|head| head.eq_ignore_ascii_case(literal))
        {
            return None;
        }
        rest = &rest[literal.len()..];
        tpl = &tpl[at + len..];
        // The placeholder runs to the next literal text (or the end).
        let stop = ["{address}", "{value}"]
            .iter()
            .filter_map(|p| tpl.find(p))
            .min()
            .unwrap_or(tpl.len());
        let next_literal = &tpl[..stop];
        let end = if next_literal.is_empty() {
            rest.len()
        } else {
            rest.to_ascii_uppercase()
                .find(&next_literal.to_ascii_uppercase())?
        };
        let word = &rest[..end];
        if word.is_empty() || word.contains(char::is_whitespace) {
            return None;
        }
        found[slot] = Some(word);
        rest = &rest[end..];
    }
    rest.is_empty().then_some(found)
}

impl Handler for Gotmic {
    /// Each line of the message is one request; one reply message per request.
    fn message(&self, data: &[u8]) -> Vec<Vec<u8>> {
        let text = String::from_utf8_lossy(data);
        let lines: Vec<&str> = text
            .split('\n')
            .map(|l| l.trim_end_matches('\r'))
            .filter(|l| !l.trim().is_empty())
            .collect();
        if lines.is_empty() {
            return vec![self.line("").into_bytes()];
        }
        lines
            .into_iter()
            .map(|l| self.line(l).into_bytes())
            .collect()
    }

    fn line_terminator(&self) -> Option<&[u8]> {
        Some(self.model.line_terminator.as_bytes())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn crc8_smbus_check_value() {
        // The standard check value of CRC-8/SMBUS over "123456789".
        assert_eq!(crc8(b"123456789", 0x07, 0x00), 0xF4);
    }

    #[test]
    fn number_parsing() {
        use crate::catalog::NumberFormat;
        assert_eq!(NumberFormat::Hex4.read("0x3F"), Some(0x3F));
        assert_eq!(NumberFormat::Hex4.read("003f"), Some(0x3F));
        assert_eq!(NumberFormat::Hex2.read("123"), None);
        assert_eq!(NumberFormat::Hex2.read("g"), None);
        assert_eq!(NumberFormat::Dec.read("63"), Some(63));
        assert_eq!(NumberFormat::Dec.read("3F"), None);
    }

    #[test]
    fn request_templates() {
        assert_eq!(
            match_template("R {address}", "r 03"),
            Some([Some("03"), None])
        );
        assert_eq!(
            match_template("W {address} {value}", "W 02 000F"),
            Some([Some("02"), Some("000F")])
        );
        assert_eq!(
            match_template("SET {address}={value}", "set 18=63"),
            Some([Some("18"), Some("63")])
        );
        assert_eq!(match_template("R {address}", "R 03 04"), None);
        assert_eq!(match_template("R {address}", "W 03"), None);
        assert_eq!(
            match_template("GET {address}?", "GET 7?"),
            Some([Some("7"), None])
        );
        assert_eq!(match_template("GET {address}?", "GET 7"), None);
    }
}
