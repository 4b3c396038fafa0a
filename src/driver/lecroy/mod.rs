//! Teledyne LeCroy (MAUI / X-Stream) driver, over VICP or VXI-11 with the same commands.
//!
//! I on C1, Q on C2, the AWG's marker on the external trigger input; a fixed sample rate set with
//! automation (`VBS`) commands; the record long enough for one repetition plus the longest echo;
//! single-shot arm, wait and `*OPC?`, then `INR?` tells whether a trigger came. Waveforms are
//! read with `C<n>:WF? ALL` in 16-bit words and decoded by [`wavedesc`]. The scope has no SCPI
//! error queue: its command and execution error registers (`CMR?`, `EXR?`) are read after each
//! configuration batch instead.

pub mod commands;
/// The LeCroy waveform format lives in [`crate::trc`] (a pure codec shared with file readers).
pub use crate::trc as wavedesc;

use bytes::Bytes;

use self::wavedesc::Trace;
use super::capability::{Digitizer, DigitizerApplied, DigitizerSettings, IqCapture};
use super::common::{self, close, session, within};
use super::error::DriverError;
use super::io::{open_session, BoxFuture, InstrumentIo};
use crate::address::Resource;
use crate::catalog::{DigitizerLimits, InstrumentModel};
use crate::session::reply::{parse_f64, parse_i64};
use crate::session::{DeviceError, Identity, SessionError};
use crate::transport::{Journal, LinkError};

/// Channel that carries I.
pub const I_CHANNEL: u8 = 1;
/// Channel that carries Q.
pub const Q_CHANNEL: u8 = 2;
/// INR bit 0: a new acquisition completed.
const INR_NEW_ACQUISITION: i64 = 1;
/// Relative tolerance on the read-back sample rate.
const RATE_TOLERANCE: f64 = 1e-6;
/// Slack on the WAIT timeout before the reply itself is considered late, seconds.
const WAIT_SLACK_S: f64 = 5.0;

/// A connected LeCroy scope.
pub struct Lecroy {
    io: Box<dyn InstrumentIo>,
    model: InstrumentModel,
    limits: DigitizerLimits,
    identity: Identity,
    name: String,
    vbs_prefix: Option<String>,
}

/// The names the scope's menu gives the two remote protocols.
fn protocol_names(protocol: &str) -> (&'static str, &'static str) {
    if protocol == "vicp" {
        ("TCPIP (VICP)", "LXI (VXI-11)")
    } else {
        ("LXI (VXI-11)", "TCPIP (VICP)")
    }
}

/// Link failures at connection time that mean "nobody answers this protocol here".
fn no_answer(e: &SessionError) -> bool {
    matches!(
        e.link_error(),
        Some(
            LinkError::Timeout { .. }
                | LinkError::Closed { .. }
                | LinkError::Connect { .. }
                | LinkError::Refused { .. }
        )
    )
}

fn remote_interface(resource: String, protocol: &str, source: SessionError) -> DriverError {
    let (this, other) = protocol_names(protocol);
    DriverError::RemoteInterface {
        resource,
        protocol: this,
        other,
        source: Box::new(source),
    }
}

impl Lecroy {
    /// Opens the resource (VICP or VXI-11), identifies the scope and returns the driver. When the
    /// scope does not answer on this protocol the error says to check its remote setting.
    pub async fn open(
        resource: Resource,
        model: &InstrumentModel,
        journal: Option<Journal>,
        name: &str,
    ) -> Result<Lecroy, DriverError> {
        let text = resource.to_string();
        let protocol = resource.protocol();
        let session = open_session(resource, &model.timeouts, "CMR?", journal, name)
            .await
            .map_err(|e| {
                if no_answer(&e) {
                    remote_interface(text.clone(), protocol, e)
                } else {
                    session(name)(e)
                }
            })?;
        Lecroy::connect(Box::new(session), model, name).await
    }

    /// Identifies the scope on an open session (or a scripted fake).
    pub async fn connect(
        mut io: Box<dyn InstrumentIo>,
        model: &InstrumentModel,
        name: &str,
    ) -> Result<Lecroy, DriverError> {
        let limits = model
            .digitizer
            .clone()
            .ok_or_else(|| DriverError::Catalog {
                key: model.instrument.key.clone(),
                reason: "the model has no [digitizer] section; it is not a scope".into(),
            })?;
        // Response headers are on after power-up (`*IDN LECROY,...`); switch them off first.
        let identified = match io.write(commands::HEADERS_OFF).await {
            Ok(()) => common::identify(io.as_mut(), model, name).await,
            Err(e) => Err(session(name)(e)),
        };
        let identity = match identified {
            Err(DriverError::Session { source, .. }) if no_answer(&source) => {
                return Err(remote_interface(io.resource_text(), io.protocol(), *source))
            }
            other => other?,
        };
        Ok(Lecroy {
            io,
            vbs_prefix: model.quirks.vbs_reply_prefix.clone(),
            model: model.clone(),
            limits,
            identity,
            name: name.to_string(),
        })
    }

    pub fn model(&self) -> &InstrumentModel {
        &self.model
    }

    async fn send(&mut self, command: &str) -> Result<(), DriverError> {
        self.io.write(command).await.map_err(session(&self.name))
    }

    async fn ask(&mut self, query: &str) -> Result<String, DriverError> {
        self.io.query(query).await.map_err(session(&self.name))
    }

    fn reply_error(&self, command: &str, expected: &'static str, reply: &str) -> DriverError {
        DriverError::Reply {
            instrument: self.name.clone(),
            command: command.to_string(),
            expected,
            reply: reply.to_string(),
        }
    }

    /// An integer reply, with or without a response header (`INR 8193` or `8193`).
    async fn ask_int(&mut self, query: &str) -> Result<i64, DriverError> {
        let text = self.ask(query).await?;
        text.split_whitespace()
            .last()
            .and_then(parse_i64)
            .ok_or_else(|| self.reply_error(query, "an integer", &text))
    }

    /// A `VBS?` number, with the `VBS ` header stripped when present.
    async fn ask_vbs_number(&mut self, query: &str) -> Result<f64, DriverError> {
        let text = self.ask(query).await?;
        let mut body = text.trim();
        if let Some(prefix) = &self.vbs_prefix {
            body = body.strip_prefix(prefix.as_str()).unwrap_or(body);
        }
        parse_f64(body.trim()).ok_or_else(|| self.reply_error(query, "a number", &text))
    }

    /// Reads (and thereby clears) the command and execution error registers.
    async fn check(&mut self, batch: &str) -> Result<(), DriverError> {
        let mut errors = Vec::new();
        let cmr = self.ask_int(commands::COMMAND_ERRORS).await?;
        if cmr != 0 {
            errors.push(DeviceError {
                code: cmr as i32,
                message: commands::command_error_text(cmr).to_string(),
            });
        }
        let exr = self.ask_int(commands::EXECUTION_ERRORS).await?;
        if exr != 0 {
            errors.push(DeviceError {
                code: exr as i32,
                message: commands::execution_error_text(exr).to_string(),
            });
        }
        if errors.is_empty() {
            Ok(())
        } else {
            Err(DriverError::Refused {
                instrument: self.name.clone(),
                batch: batch.to_string(),
                errors,
            })
        }
    }

    fn validate(&self, s: &DigitizerSettings) -> Result<(), DriverError> {
        let l = &self.limits;
        let n = &self.name;
        if !l
            .sample_rates
            .iter()
            .any(|r| close(*r, s.sample_rate_hz, RATE_TOLERANCE))
        {
            return Err(DriverError::OutOfLimits {
                instrument: n.clone(),
                field: "sample_rate_hz",
                value: format!("{} Sa/s", s.sample_rate_hz),
                allowed: format!("one of {:?} Sa/s", l.sample_rates),
            });
        }
        within(
            n,
            "repetition_s",
            s.repetition_s,
            f64::MIN_POSITIVE,
            f64::MAX,
            "s",
        )?;
        within(n, "longest_echo_s", s.longest_echo_s, 0.0, f64::MAX, "s")?;
        within(n, "pre_trigger_s", s.pre_trigger_s, 0.0, f64::MAX, "s")?;
        let points = (s.record_s() * s.sample_rate_hz).ceil();
        if points > l.max_points_per_channel as f64 {
            return Err(DriverError::OutOfLimits {
                instrument: n.clone(),
                field: "repetition_s + longest_echo_s + pre_trigger_s",
                value: format!("{} s = {points} points", s.record_s()),
                allowed: format!(
                    "at most {} points per channel ({} s at {} Sa/s)",
                    l.max_points_per_channel,
                    l.max_points_per_channel as f64 / s.sample_rate_hz,
                    s.sample_rate_hz
                ),
            });
        }
        for (field, v) in [
            ("i_volts_per_div", s.i_volts_per_div),
            ("q_volts_per_div", s.q_volts_per_div),
        ] {
            within(
                n,
                field,
                v,
                l.volts_per_div_min,
                l.volts_per_div_max,
                "V/div",
            )?;
        }
        for (field, v) in [("i_offset_v", s.i_offset_v), ("q_offset_v", s.q_offset_v)] {
            within(n, field, v, l.offset_v_min, l.offset_v_max, "V")?;
        }
        within(
            n,
            "trigger_level_v",
            s.trigger_level_v,
            l.ext_trigger_level_v_min,
            l.ext_trigger_level_v_max,
            "V",
        )?;
        if !l.trigger_sources.iter().any(|t| t == commands::EXTERNAL) {
            return Err(DriverError::Catalog {
                key: self.model.instrument.key.clone(),
                reason: "trigger_sources lacks EX (the external input the marker drives)".into(),
            });
        }
        if l.channels < Q_CHANNEL {
            return Err(DriverError::Catalog {
                key: self.model.instrument.key.clone(),
                reason: "the driver needs two channels (I on C1, Q on C2)".into(),
            });
        }
        Ok(())
    }

    async fn configure_impl(
        &mut self,
        s: &DigitizerSettings,
    ) -> Result<DigitizerApplied, DriverError> {
        self.validate(s)?;
        let divisions = f64::from(self.limits.horizontal_divisions);
        // Clear stale error bits so they are not blamed on this configuration.
        let _ = self.ask_int(commands::COMMAND_ERRORS).await?;
        let _ = self.ask_int(commands::EXECUTION_ERRORS).await?;
        for command in [
            commands::HEADERS_OFF,
            commands::WORD_FORMAT,
            commands::LSB_FIRST,
            commands::WHOLE_RECORD,
        ] {
            self.send(command).await?;
        }
        self.check("the transfer format").await?;
        for (ch, vdiv, offset) in [
            (I_CHANNEL, s.i_volts_per_div, s.i_offset_v),
            (Q_CHANNEL, s.q_volts_per_div, s.q_offset_v),
        ] {
            self.send(&commands::trace_on(ch)).await?;
            self.send(&commands::volts_per_div(ch, vdiv)).await?;
            self.send(&commands::offset(ch, offset)).await?;
        }
        if s.external_reference {
            self.send(commands::EXTERNAL_REFERENCE).await?;
        }
        self.check("the channel settings").await?;
        self.send(commands::FIXED_RATE).await?;
        self.send(&commands::sample_rate(s.sample_rate_hz)).await?;
        self.send(&commands::hor_scale(s.record_s() / divisions))
            .await?;
        self.check("the sample rate and record length").await?;
        let rate = self.ask_vbs_number(commands::SAMPLING_RATE_QUERY).await?;
        if !close(rate, s.sample_rate_hz, RATE_TOLERANCE) {
            return Err(DriverError::NotApplied {
                instrument: self.name.clone(),
                setting: "sample rate (Sa/s)",
                wanted: s.sample_rate_hz.to_string(),
                applied: rate.to_string(),
            });
        }
        let hor_scale = self.ask_vbs_number(commands::HOR_SCALE_QUERY).await?;
        let record_s = hor_scale * divisions;
        if record_s < s.record_s() * (1.0 - 1e-9) {
            return Err(DriverError::NotApplied {
                instrument: self.name.clone(),
                setting: "record length (s)",
                wanted: s.record_s().to_string(),
                applied: record_s.to_string(),
            });
        }
        // The record starts pre_trigger_s before the trigger: the scope puts the trigger at the
        // grid's centre for a delay of 0, so move it by half the record.
        let trigger_delay_s = s.pre_trigger_s - divisions / 2.0 * hor_scale;
        self.send(&commands::edge_trigger(commands::EXTERNAL))
            .await?;
        self.send(&commands::trigger_level(
            commands::EXTERNAL,
            s.trigger_level_v,
        ))
        .await?;
        self.send(&commands::trigger_slope(
            commands::EXTERNAL,
            s.trigger_slope,
        ))
        .await?;
        self.send(&commands::trigger_delay(trigger_delay_s)).await?;
        self.check("the trigger settings").await?;
        Ok(DigitizerApplied {
            sample_rate_hz: rate,
            hor_scale_s: hor_scale,
            record_s,
            points: (record_s * rate).round() as u64,
            trigger_delay_s,
            trigger_source: commands::EXTERNAL.to_string(),
            trigger_level_v: s.trigger_level_v,
        })
    }

    async fn acquire_impl(&mut self, wait_s: f64) -> Result<(), DriverError> {
        within(&self.name, "wait_s", wait_s, 0.0, 1.0e5, "s")?;
        // Reading INR clears it, so bit 0 afterwards means this acquisition.
        self.ask_int(commands::STATUS).await?;
        let query = commands::single_shot(wait_s);
        let allowed = std::time::Duration::from_secs_f64(wait_s + WAIT_SLACK_S)
            + std::time::Duration::from_millis(self.model.timeouts.read_ms);
        let opc = self
            .io
            .query_with_timeout(&query, allowed)
            .await
            .map_err(session(&self.name))?;
        if parse_i64(opc.split_whitespace().last().unwrap_or("")) != Some(1) {
            return Err(self.reply_error(&query, "1", &opc));
        }
        let inr = self.ask_int(commands::STATUS).await?;
        if inr & INR_NEW_ACQUISITION == 0 {
            // Disarm so a late edge does not complete an acquisition nobody reads.
            self.send(commands::STOP).await?;
            return Err(DriverError::NoTrigger {
                instrument: self.name.clone(),
                source_name: commands::EXTERNAL.to_string(),
                waited_s: wait_s,
            });
        }
        Ok(())
    }

    async fn fetch_impl(&mut self, channel: u8) -> Result<Trace, DriverError> {
        if channel == 0 || channel > self.limits.channels {
            return Err(DriverError::BadSettings {
                instrument: self.name.clone(),
                field: "channel",
                reason: format!(
                    "C{channel} does not exist; allowed C1..=C{}",
                    self.limits.channels
                ),
            });
        }
        let query = commands::waveform(channel);
        let block = self
            .io
            .query_block(&query)
            .await
            .map_err(session(&self.name))?;
        let payload: Bytes = block.into_payload();
        Trace::decode(channel, payload).map_err(|source| DriverError::Waveform {
            instrument: self.name.clone(),
            channel,
            source,
        })
    }
}

impl Digitizer for Lecroy {
    fn identity(&self) -> &Identity {
        &self.identity
    }

    fn configure<'a>(
        &'a mut self,
        settings: &'a DigitizerSettings,
    ) -> BoxFuture<'a, Result<DigitizerApplied, DriverError>> {
        Box::pin(self.configure_impl(settings))
    }

    fn acquire(&mut self, wait_s: f64) -> BoxFuture<'_, Result<(), DriverError>> {
        Box::pin(self.acquire_impl(wait_s))
    }

    fn fetch(&mut self, channel: u8) -> BoxFuture<'_, Result<Trace, DriverError>> {
        Box::pin(self.fetch_impl(channel))
    }

    fn capture_iq(&mut self, wait_s: f64) -> BoxFuture<'_, Result<IqCapture, DriverError>> {
        Box::pin(async move {
            self.acquire_impl(wait_s).await?;
            let i = self.fetch_impl(I_CHANNEL).await?;
            let q = self.fetch_impl(Q_CHANNEL).await?;
            Ok(IqCapture { i, q })
        })
    }

    fn stop(&mut self) -> BoxFuture<'_, Result<(), DriverError>> {
        Box::pin(async move { self.send(commands::STOP).await })
    }
}
