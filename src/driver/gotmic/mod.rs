//! Gotmic E-band Tx/Rx driver over the PROJECT-DEFINED line protocol of instruments.md section 5
//! (the vendor's protocol is not public). Registers are addressed by name through the catalog's
//! register map, so a real map can replace the project one as data.
//!
//! Safety: enabling RF needs an explicit [`RfPermit`]; the attenuation goes to its maximum before the
//! enable bits are written; every write is read back; STATUS is checked after enabling (RF on, LO
//! locked). [`RfFrontEnd::disable`] is what the safe-state sequence calls on every exit path; a
//! driver dropped while RF may be on logs an error (it cannot talk to the module from `drop`).

pub mod commands;

use crate::catalog::{InstrumentModel, Register, RegisterAccess, RfLimits};
use crate::session::{Identity, Session};

use super::{identity_matches, DriverError, RfFrontEnd, RfPermit, RfStatus};

const NAME: &str = "Gotmic";

/// A connected Gotmic module.
pub struct Gotmic {
    session: Session,
    registers: Vec<Register>,
    limits: RfLimits,
    identity: Identity,
    /// RF may be on (set before enabling, cleared after a verified disable).
    rf_may_be_on: bool,
}

fn limit(parameter: &'static str, value: impl ToString, allowed: impl Into<String>) -> DriverError {
    DriverError::Limit {
        instrument: NAME,
        parameter,
        value: value.to_string(),
        allowed: allowed.into(),
    }
}

impl Gotmic {
    /// Checks `*IDN?` and the ID register against the catalog entry.
    pub async fn connect(session: Session, model: &InstrumentModel) -> Result<Self, DriverError> {
        let limits = model.rf.clone().ok_or_else(|| DriverError::Catalog {
            instrument: NAME,
            key: model.instrument.key.clone(),
            what: "[rf] section",
        })?;
        let mut driver = Gotmic {
            session,
            registers: model.registers.clone(),
            limits,
            identity: Identity {
                manufacturer: String::new(),
                model: String::new(),
                serial: String::new(),
                firmware: String::new(),
            },
            rf_may_be_on: false,
        };
        let idn = driver.request(commands::IDN).await?;
        let identity =
            crate::session::reply::parse_idn(&idn).ok_or_else(|| DriverError::BadReply {
                instrument: NAME,
                request: commands::IDN.into(),
                expected: "manufacturer,model,serial,firmware",
                reply: idn.clone(),
            })?;
        if !identity_matches(model, &identity) {
            return Err(DriverError::WrongInstrument {
                instrument: NAME,
                expected: model.instrument.model.clone(),
                idn,
            });
        }
        driver.identity = identity;
        let expected_id = driver.register("ID")?.reset;
        let id = driver.read("ID").await?;
        if id != expected_id {
            return Err(DriverError::Readback {
                instrument: NAME,
                what: "ID register".into(),
                expected: format!("0x{expected_id:04X}"),
                got: format!("0x{id:04X}"),
            });
        }
        // The module's state is unknown at connect: assume RF may be on until a read says otherwise.
        let status = driver.status().await?;
        driver.rf_may_be_on = status.rf_enabled;
        Ok(driver)
    }

    pub fn identity(&self) -> &Identity {
        &self.identity
    }

    fn register(&self, name: &str) -> Result<&Register, DriverError> {
        self.registers
            .iter()
            .find(|r| r.name == name)
            .ok_or_else(|| DriverError::Catalog {
                instrument: NAME,
                key: name.to_string(),
                what: "register of that name",
            })
    }

    fn mask(&self, register: &str, field: &str) -> Result<u16, DriverError> {
        self.register(register)?
            .bit(field)
            .and_then(|b| 1u16.checked_shl(u32::from(b)))
            .ok_or_else(|| DriverError::Catalog {
                instrument: NAME,
                key: format!("{register}.{field}"),
                what: "bit field of that name",
            })
    }

    /// Sends one request line and returns the `OK...` reply; `ERR` replies become [`DriverError::Refused`].
    async fn request(&mut self, line: &str) -> Result<String, DriverError> {
        let reply = self.session.query(line).await?;
        if let Some((code, text)) = commands::parse_error(&reply) {
            return Err(DriverError::Refused {
                instrument: NAME,
                request: line.to_string(),
                code,
                text,
            });
        }
        Ok(reply)
    }

    /// Reads a register by name.
    pub async fn read(&mut self, name: &str) -> Result<u16, DriverError> {
        let request = commands::read(self.register(name)?.address);
        let reply = self.request(&request).await?;
        match commands::parse_value(&reply) {
            Some(value) => Ok(value),
            None => Err(DriverError::BadReply {
                instrument: NAME,
                request,
                expected: "OK <4 hex digits>",
                reply,
            }),
        }
    }

    /// Writes a register by name (range-checked against the catalog) and reads it back.
    pub async fn write(&mut self, name: &str, value: u16) -> Result<(), DriverError> {
        let register = self.register(name)?.clone();
        if register.access == RegisterAccess::Ro {
            return Err(limit(
                "register",
                name,
                "a writable register (this one is read-only)",
            ));
        }
        let (min, max) = (register.min.unwrap_or(0), register.max.unwrap_or(u16::MAX));
        if value < min || value > max {
            return Err(DriverError::Limit {
                instrument: NAME,
                parameter: "register value",
                value: format!("{name} = 0x{value:X}"),
                allowed: format!("0x{min:X}..=0x{max:X}"),
            });
        }
        let request = commands::write(register.address, value);
        let reply = self.request(&request).await?;
        if reply.trim() != "OK" {
            return Err(DriverError::BadReply {
                instrument: NAME,
                request,
                expected: "OK",
                reply,
            });
        }
        if register.access == RegisterAccess::Rw {
            let back = self.read(name).await?;
            if back != value {
                return Err(DriverError::Readback {
                    instrument: NAME,
                    what: name.to_string(),
                    expected: format!("0x{value:04X}"),
                    got: format!("0x{back:04X}"),
                });
            }
        }
        Ok(())
    }

    fn attenuation_code(&self, db: f64) -> Result<u16, DriverError> {
        let register = self.register("GAIN_ATT")?;
        let (min, max) = (register.min.unwrap_or(0), register.max.unwrap_or(0));
        let step = self.limits.attenuation_step_db;
        let code = (db / step).round();
        if !(db.is_finite() && code >= f64::from(min) && code <= f64::from(max)) {
            return Err(limit(
                "attenuation_db",
                db,
                format!(
                    "{} ..= {} dB in {step} dB steps",
                    f64::from(min) * step,
                    f64::from(max) * step
                ),
            ));
        }
        Ok(code as u16)
    }

    fn max_attenuation(&self) -> Result<u16, DriverError> {
        Ok(self.register("GAIN_ATT")?.max.unwrap_or(0))
    }
}

impl RfFrontEnd for Gotmic {
    async fn status(&mut self) -> Result<RfStatus, DriverError> {
        let status = self.read("STATUS").await?;
        let temperature = self.read("TEMP_DC").await? as i16;
        let attenuation = self.read("GAIN_ATT").await?;
        let fault_latch = self.read("FAULT_LATCH").await?;
        let bit = |field: &str| -> Result<bool, DriverError> {
            Ok(status & self.mask("STATUS", field)? != 0)
        };
        Ok(RfStatus {
            lo_locked: bit("LO_LOCKED")?,
            rf_enabled: bit("RF_ENABLED")?,
            over_temperature: bit("OVER_TEMPERATURE")?,
            interlock_open: bit("INTERLOCK_OPEN")?,
            temperature_c: f64::from(temperature) / 10.0,
            attenuation_db: f64::from(attenuation) * self.limits.attenuation_step_db,
            fault_latch,
        })
    }

    async fn set_attenuation_db(&mut self, db: f64) -> Result<f64, DriverError> {
        let code = self.attenuation_code(db)?;
        self.write("GAIN_ATT", code).await?;
        Ok(f64::from(code) * self.limits.attenuation_step_db)
    }

    async fn enable(
        &mut self,
        _permit: &RfPermit,
        attenuation_db: f64,
    ) -> Result<RfStatus, DriverError> {
        let code = self.attenuation_code(attenuation_db)?;
        let enable_bits = self.mask("CONTROL", "MASTER_ENABLE")?
            | self.mask("CONTROL", "AMP_ENABLE")?
            | self.mask("CONTROL", "LO_MULTIPLIER_ENABLE").unwrap_or(0)
            | self.mask("CONTROL", "IQ_ENABLE").unwrap_or(0);
        let max = self.max_attenuation()?;
        self.write("GAIN_ATT", max).await?;
        self.rf_may_be_on = true;
        if let Err(e) = self.write("CONTROL", enable_bits).await {
            // A refused enable leaves RF off; make sure of it.
            self.rf_may_be_on = self.disable().await.is_err();
            return Err(e);
        }
        let status = self.status().await?;
        if !(status.rf_enabled && status.lo_locked) {
            let detail = format!(
                "RF enabled {}, LO locked {}, interlock open {}, faults 0x{:04X}",
                status.rf_enabled, status.lo_locked, status.interlock_open, status.fault_latch
            );
            self.disable().await?;
            return Err(DriverError::Readback {
                instrument: NAME,
                what: "STATUS after enabling".into(),
                expected: "RF enabled and LO locked".into(),
                got: detail,
            });
        }
        self.write("GAIN_ATT", code).await?;
        self.status().await
    }

    async fn disable(&mut self) -> Result<(), DriverError> {
        self.write("CONTROL", 0).await?;
        let status = self.read("STATUS").await?;
        if status & self.mask("STATUS", "RF_ENABLED")? != 0 {
            return Err(DriverError::Readback {
                instrument: NAME,
                what: "STATUS after disabling".into(),
                expected: "RF off".into(),
                got: format!("0x{status:04X}"),
            });
        }
        self.rf_may_be_on = false;
        Ok(())
    }

    async fn clear_faults(&mut self) -> Result<u16, DriverError> {
        let latched = self.read("FAULT_LATCH").await?;
        if latched != 0 {
            self.write("FAULT_LATCH", latched).await?;
        }
        Ok(latched)
    }
}

impl Drop for Gotmic {
    fn drop(&mut self) {
        if self.rf_may_be_on {
            tracing::error!(
                "Gotmic module {} dropped while RF may be on: the safe-state sequence must call disable()",
                self.identity
            );
        }
    }
}
