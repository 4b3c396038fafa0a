//! Teledyne LeCroy LabMaster driver: I on C1, Q on C2, the AWG marker on the external trigger input,
//! a fixed 80 GSa/s, a record long enough for one repetition plus the longest echo, single-shot
//! arm / wait / `*OPC?`, `WF? ALL` in 16-bit words decoded to volts and a time axis that includes
//! HORIZ_OFFSET, and the raw block kept for `.trc` files. Works over VICP and VXI-11 alike (the
//! session hides the transport). The legacy command set has no `SYST:ERR?`: errors are read from
//! `CMR?` (command errors) and `EXR?` (execution errors) after each batch.

pub mod commands;
pub mod wavedesc;

use std::time::Duration;

use crate::address::Resource;
use crate::catalog::{DigitizerLimits, InstrumentModel};
use crate::session::{Identity, Session, SessionError, SessionOptions};

use super::{identity_matches, Digitizer, DigitizerApplied, DigitizerSetup, DriverError};
pub use wavedesc::{Trace, WaveDesc, WaveformError};

const NAME: &str = "LeCroy";
/// Channels carrying I and Q.
pub const I_CHANNEL: u8 = 1;
pub const Q_CHANNEL: u8 = 2;

/// A connected LeCroy scope.
pub struct Lecroy {
    session: Session,
    limits: DigitizerLimits,
    identity: Identity,
}

fn limit(parameter: &'static str, value: impl ToString, allowed: impl Into<String>) -> DriverError {
    DriverError::Limit {
        instrument: NAME,
        parameter,
        value: value.to_string(),
        allowed: allowed.into(),
    }
}

/// Explains a scope that does not answer: over VICP or VXI-11 the usual cause is the remote
/// interface set to the other protocol (the scope then has no server for this one).
fn remote_interface_hint(resource: &Resource, err: SessionError) -> DriverError {
    let explain = matches!(
        err.link_error(),
        Some(
            crate::transport::LinkError::Connect { .. }
                | crate::transport::LinkError::Timeout { .. }
                | crate::transport::LinkError::Closed { .. }
        )
    );
    if !explain {
        return DriverError::Session(err);
    }
    let (this, other) = match resource {
        Resource::Vicp { .. } => ("TCPIP (VICP)", "LXI (VXI-11)"),
        Resource::Vxi11 { .. } => ("LXI (VXI-11)", "TCPIP (VICP)"),
        _ => ("this protocol", "another protocol"),
    };
    DriverError::RemoteInterface {
        instrument: NAME,
        resource: resource.to_string(),
        detail: format!(
            "the scope did not answer over {this}; its remote interface is probably set to {other}: \
             set Utilities > Utilities Setup > Remote to {this}, or use a {other} resource ({err})"
        ),
    }
}

impl Lecroy {
    /// Opens the resource and checks `*IDN?` against the catalog entry. A scope that refuses or
    /// never answers is reported with the remote-interface setting to check.
    pub async fn open(
        resource: Resource,
        options: SessionOptions,
        model: &InstrumentModel,
    ) -> Result<Self, DriverError> {
        let session = Session::open(resource.clone(), options, None, "scope")
            .await
            .map_err(|e| remote_interface_hint(&resource, e))?;
        Self::connect(session, model).await
    }

    /// Checks `*IDN?` on an open session and returns the driver.
    pub async fn connect(
        mut session: Session,
        model: &InstrumentModel,
    ) -> Result<Self, DriverError> {
        let limits = model
            .digitizer
            .clone()
            .ok_or_else(|| DriverError::Catalog {
                instrument: NAME,
                key: model.instrument.key.clone(),
                what: "[digitizer] section",
            })?;
        let resource = session.resource().clone();
        // Headers off first, so every reply is a bare value.
        session
            .write(commands::TRANSFER_SETUP[0])
            .await
            .map_err(|e| remote_interface_hint(&resource, e))?;
        let identity = session
            .idn()
            .await
            .map_err(|e| remote_interface_hint(&resource, e))?;
        if !identity_matches(model, &identity) {
            return Err(DriverError::WrongInstrument {
                instrument: NAME,
                expected: format!(
                    "{} {}",
                    model.instrument.manufacturer, model.instrument.model
                ),
                idn: identity.to_string(),
            });
        }
        Ok(Lecroy {
            session,
            limits,
            identity,
        })
    }

    pub fn identity(&self) -> &Identity {
        &self.identity
    }

    pub fn session(&mut self) -> &mut Session {
        &mut self.session
    }

    /// Seconds per division that hold `record_seconds` on the grid, rounded up to whole samples.
    pub fn hor_scale(&self, rate: f64, record_seconds: f64) -> f64 {
        let divisions = f64::from(self.limits.horizontal_divisions);
        let points = (record_seconds * rate).ceil();
        points / rate / divisions
    }

    fn check_setup(&self, setup: &DigitizerSetup) -> Result<(), DriverError> {
        let l = &self.limits;
        if !l
            .sample_rates
            .iter()
            .any(|r| (r - setup.sample_rate).abs() <= r * 1e-12)
        {
            let allowed: Vec<String> = l.sample_rates.iter().map(|r| format!("{r:e}")).collect();
            return Err(limit(
                "sample_rate",
                setup.sample_rate,
                format!("one of {} Sa/s", allowed.join(", ")),
            ));
        }
        let points = (setup.record_seconds * setup.sample_rate).ceil();
        if !(points >= 1.0 && points <= l.max_points_per_channel as f64) {
            return Err(limit(
                "record_seconds",
                setup.record_seconds,
                format!(
                    "a record of 1..={} points ({:e} s at {:e} Sa/s)",
                    l.max_points_per_channel,
                    l.max_points_per_channel as f64 / setup.sample_rate,
                    setup.sample_rate
                ),
            ));
        }
        if !(setup.trigger_level_v >= l.ext_trigger_level_v_min
            && setup.trigger_level_v <= l.ext_trigger_level_v_max)
        {
            return Err(limit(
                "trigger_level_v",
                setup.trigger_level_v,
                format!(
                    "{} ..= {} V on EX",
                    l.ext_trigger_level_v_min, l.ext_trigger_level_v_max
                ),
            ));
        }
        if !(setup.volts_per_div >= l.volts_per_div_min
            && setup.volts_per_div <= l.volts_per_div_max)
        {
            return Err(limit(
                "volts_per_div",
                setup.volts_per_div,
                format!("{} ..= {} V/div", l.volts_per_div_min, l.volts_per_div_max),
            ));
        }
        Ok(())
    }

    /// Reads CMR? and EXR? (both clear on read) and fails if either holds an error.
    async fn check_errors(&mut self, after: &str) -> Result<(), DriverError> {
        for query in [
            commands::COMMAND_ERROR_QUERY,
            commands::EXECUTION_ERROR_QUERY,
        ] {
            let code = self.session.query_i64(query).await?;
            if code != 0 {
                return Err(DriverError::Refused {
                    instrument: NAME,
                    request: after.to_string(),
                    code: u8::try_from(code).unwrap_or(u8::MAX),
                    text: format!("{} ({query})", commands::error_text(code)),
                });
            }
        }
        Ok(())
    }

    async fn send_all(&mut self, batch: &[String], what: &str) -> Result<(), DriverError> {
        for command in batch {
            self.session.write(command).await?;
        }
        self.check_errors(what).await
    }
}

impl Digitizer for Lecroy {
    async fn configure(&mut self, setup: &DigitizerSetup) -> Result<DigitizerApplied, DriverError> {
        self.check_setup(setup)?;
        let scale = self.hor_scale(setup.sample_rate, setup.record_seconds);
        let half_grid = f64::from(self.limits.horizontal_divisions) / 2.0 * scale;
        let mut batch: Vec<String> = commands::TRANSFER_SETUP
            .iter()
            .map(|c| c.to_string())
            .collect();
        batch.extend([
            commands::FIXED_SAMPLE_RATE.to_string(),
            commands::sample_rate(setup.sample_rate),
            commands::hor_scale(scale),
            // The grid starts at the trigger: HORIZ_OFFSET = 0 up to the scope's rounding.
            commands::trigger_delay(-half_grid),
            commands::trace_on(I_CHANNEL),
            commands::trace_on(Q_CHANNEL),
            commands::volts_per_div(I_CHANNEL, setup.volts_per_div),
            commands::volts_per_div(Q_CHANNEL, setup.volts_per_div),
            commands::EDGE_ON_EXT.to_string(),
            commands::ext_level(setup.trigger_level_v),
            commands::SLOPE_POSITIVE.to_string(),
        ]);
        self.send_all(&batch, "configure").await?;
        let applied = self.applied().await?;
        if (applied.sample_rate - setup.sample_rate).abs() > setup.sample_rate * 1e-9 {
            return Err(DriverError::Readback {
                instrument: NAME,
                what: "SamplingRate".into(),
                expected: format!("{:e}", setup.sample_rate),
                got: format!("{:e}", applied.sample_rate),
            });
        }
        Ok(applied)
    }

    async fn acquire(&mut self, timeout: Duration) -> Result<(), DriverError> {
        let seconds = timeout.as_secs_f64();
        let saved = self.session.link_options_mut().timeouts.read;
        self.session.link_options_mut().timeouts.read = saved + timeout;
        let result = self.session.query(&commands::single_shot(seconds)).await;
        self.session.link_options_mut().timeouts.read = saved;
        let reply = result?;
        if reply.trim() != "1" {
            return Err(DriverError::BadReply {
                instrument: NAME,
                request: commands::single_shot(seconds),
                expected: "1",
                reply,
            });
        }
        let inr = self.session.query_i64(commands::INR_QUERY).await?;
        if inr & 1 == 0 {
            return Err(DriverError::NoTrigger {
                instrument: NAME,
                waited: timeout,
            });
        }
        Ok(())
    }

    async fn read(&mut self, channel: u8) -> Result<Trace, DriverError> {
        if channel == 0 || channel > self.limits.channels {
            return Err(limit(
                "channel",
                channel,
                format!("1..={}", self.limits.channels),
            ));
        }
        let query = commands::waveform_query(channel);
        let block = self.session.query_block(&query).await?;
        wavedesc::decode(block.payload()).map_err(|e| DriverError::BadReply {
            instrument: NAME,
            request: query,
            expected: "a LECROY_2_3 waveform block",
            reply: e.0,
        })
    }

    async fn applied(&mut self) -> Result<DigitizerApplied, DriverError> {
        let sample_rate = self
            .session
            .query_f64(commands::SAMPLING_RATE_QUERY)
            .await?;
        let points = self.session.query_i64(commands::NUM_POINTS_QUERY).await?;
        Ok(DigitizerApplied {
            sample_rate,
            points: u64::try_from(points).unwrap_or(0),
        })
    }
}
