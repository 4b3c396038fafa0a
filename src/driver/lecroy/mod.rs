//! Teledyne LeCroy (MAUI / X-Stream) driver, over VICP or VXI-11 with the same commands.
//!
//! I on C1, Q on C2, the AWG's marker on the external trigger input; a fixed sample rate set with
//! automation (`VBS`) commands; the record long enough for one repetition plus the longest echo;
//! single-shot arm, wait and `*OPC?`, then `INR?` tells whether a trigger came. With more than
//! one segment the scope runs in sequence mode: one acquisition records one segment per trigger
//! and `WF? ALL` returns them all, with their trigger times in the TRIGTIME array. Waveforms are
//! read with `C<n>:WF? ALL` in 16-bit words, decoded by [`wavedesc`] and handed up as
//! vendor-neutral [`ChannelTrace`]s (the `.trc` bytes kept beside). The scope has no SCPI
//! error queue: its command and execution error registers (`CMR?`, `EXR?`) are read after each
//! configuration batch instead.

pub(crate) mod commands;
mod vendor;

/// The LeCroy waveform format lives in [`crate::trc`] (a pure codec shared with file readers).
pub use crate::trc as wavedesc;
pub use commands::{
    offset, sample_rate, segments, volts_per_div, waveform, COMMAND_ERRORS, SEGMENTS_QUERY, STATUS,
    STOP,
};

use std::time::Duration;

use bytes::Bytes;

use self::wavedesc::Trace;
use super::capability::{DigitizerApplied, DigitizerSettings};
use super::error::{session, DriverError};
use super::io::{open_session, BoxFuture, InstrumentIo};
use super::scope_core::{ScopeCore, ScopeFamily, I_CHANNEL, Q_CHANNEL};
use super::scpi::Scpi;
use super::trace::{ChannelTrace, NativeFile, SegmentTiming};
use crate::address::Resource;
use crate::catalog::InstrumentModel;
use crate::session::{parse_f64, register_error_text, DeviceError, SessionError};
use crate::transport::Journal;

pub(crate) use self::vendor::check_vendor;

/// INR bit 0: a new acquisition completed.
const INR_NEW_ACQUISITION: i64 = 1;
/// Slack on the WAIT timeout before the reply itself is considered late, seconds.
const WAIT_SLACK_S: f64 = 5.0;

/// A connected LeCroy scope: the shared scope core and the catalog's `VBS` reply quirk.
pub struct Lecroy {
    core: ScopeCore,
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
    ///
    /// # Errors
    ///
    /// [`DriverError::RemoteInterface`] when the scope does not answer on this protocol,
    /// [`DriverError::Session`] when the link fails otherwise, and every error of
    /// [`connect`](Lecroy::connect).
    pub async fn open(
        resource: Resource,
        model: &InstrumentModel,
        journal: Option<Journal>,
        name: &str,
    ) -> Result<Lecroy, DriverError> {
        let text = resource.to_string();
        let protocol = resource.protocol();
        let session = open_session(resource, model, commands::COMMAND_ERRORS, journal, name)
            .await
            .map_err(|e| {
                if e.is_no_answer() {
                    remote_interface(text.clone(), protocol, e)
                } else {
                    session(name)(e)
                }
            })?;
        Lecroy::connect(Box::new(session), model, name).await
    }

    /// Identifies the scope on an open session (or a scripted fake).
    ///
    /// # Errors
    ///
    /// [`DriverError::Catalog`] when the model has no `[digitizer]` section or its `[vendor]` table
    /// does not check;
    /// [`DriverError::RemoteInterface`] when the scope does not answer; [`DriverError::Session`] when
    /// the link fails otherwise; [`DriverError::Reply`] or [`DriverError::WrongInstrument`] when
    /// `*IDN?` is unreadable or not the catalog model.
    pub async fn connect(
        io: Box<dyn InstrumentIo>,
        model: &InstrumentModel,
        name: &str,
    ) -> Result<Lecroy, DriverError> {
        check_vendor(model)?;
        let limits = ScopeCore::limits_of(model)?;
        let mut scpi = Scpi::new(io, name);
        // Response headers are on after power-up (`*IDN LECROY,...`); switch them off first.
        let identified = match scpi.send(commands::HEADERS_OFF).await {
            Ok(()) => scpi.identify(model).await,
            Err(e) => Err(e),
        };
        let identity = match identified {
            Err(DriverError::Session { source, .. }) if source.is_no_answer() => {
                return Err(remote_interface(
                    scpi.resource_text(),
                    scpi.protocol(),
                    *source,
                ))
            }
            other => other?,
        };
        Ok(Lecroy {
            vbs_prefix: model.quirks.vbs_reply_prefix.clone(),
            core: ScopeCore::new(scpi, model, limits, identity),
        })
    }

    pub fn model(&self) -> &InstrumentModel {
        &self.core.model
    }

    /// The timebase's reference as the scope reports it (`RCLK?`: `INTERNAL` or `EXTERNAL`).
    async fn reference_clock_impl(&mut self) -> Result<String, DriverError> {
        let text = self.core.scpi.ask(commands::REFERENCE_QUERY).await?;
        Ok(text.trim().trim_start_matches("RCLK").trim().to_string())
    }

    /// A `VBS?` number, with the catalog's `VBS ` reply prefix stripped when present.
    async fn ask_vbs_number(&mut self, query: &str) -> Result<f64, DriverError> {
        let text = self.core.scpi.ask(query).await?;
        let mut body = text.trim();
        if let Some(prefix) = &self.vbs_prefix {
            body = body.strip_prefix(prefix.as_str()).unwrap_or(body);
        }
        parse_f64(body.trim()).ok_or_else(|| self.core.scpi.reply_error(query, "a number", &text))
    }

    /// Reads one error register (which clears it): its entry, if it holds an error.
    async fn register_error(&mut self, register: &str) -> Result<Option<DeviceError>, DriverError> {
        let code = self.core.scpi.ask_i64(register).await?;
        let code = i32::try_from(code).map_err(|_| {
            self.core
                .scpi
                .reply_error(register, "an error code", &code.to_string())
        })?;
        Ok((code != 0).then(|| DeviceError {
            code,
            message: register_error_text(register, code).to_string(),
        }))
    }

    /// Reads (and thereby clears) the command and execution error registers.
    async fn check(&mut self, batch: &str) -> Result<(), DriverError> {
        let mut errors = Vec::new();
        for register in [commands::COMMAND_ERRORS, commands::EXECUTION_ERRORS] {
            errors.extend(self.register_error(register).await?);
        }
        self.core.scpi.refused_if_any(batch, errors)
    }

    async fn configure_impl(
        &mut self,
        s: &DigitizerSettings,
    ) -> Result<DigitizerApplied, DriverError> {
        let divisions = f64::from(self.core.limits.horizontal_divisions);
        // Clear stale error bits so they are not blamed on this configuration.
        for register in [commands::COMMAND_ERRORS, commands::EXECUTION_ERRORS] {
            if let Some(stale) = self.register_error(register).await? {
                tracing::warn!(instrument = %self.core.scpi.name(), "error register entry from before this configuration: {stale}");
            }
        }
        for command in [
            commands::HEADERS_OFF,
            commands::WORD_FORMAT,
            commands::LSB_FIRST,
            commands::WHOLE_RECORD,
        ] {
            self.core.scpi.send(command).await?;
        }
        self.check("the transfer format").await?;
        for (ch, vdiv, offset) in [
            (I_CHANNEL, s.i_volts_per_div, s.i_offset_v),
            (Q_CHANNEL, s.q_volts_per_div, s.q_offset_v),
        ] {
            self.core.scpi.send(&commands::trace_on(ch)).await?;
            self.core
                .scpi
                .send(&commands::volts_per_div(ch, vdiv))
                .await?;
            self.core.scpi.send(&commands::offset(ch, offset)).await?;
        }
        if s.external_reference {
            self.core.scpi.send(commands::EXTERNAL_REFERENCE).await?;
        }
        self.check("the channel settings").await?;
        // Always set the sample mode: a scope left in sequence mode would otherwise record
        // several triggers where one is expected.
        if s.segments > 1 {
            self.core.scpi.send(commands::SEQUENCE).await?;
            self.core.scpi.send(&commands::segments(s.segments)).await?;
        } else {
            self.core.scpi.send(commands::REAL_TIME).await?;
        }
        self.check("the sample mode").await?;
        if s.segments > 1 {
            let applied = self.ask_vbs_number(commands::SEGMENTS_QUERY).await?;
            self.core.check_segments(s.segments, applied)?;
        }
        self.core.scpi.send(commands::FIXED_RATE).await?;
        self.core
            .scpi
            .send(&commands::sample_rate(s.sample_rate_hz))
            .await?;
        self.core
            .scpi
            .send(&commands::hor_scale(s.record_s() / divisions))
            .await?;
        self.check("the sample rate and record length").await?;
        let rate = self.ask_vbs_number(commands::SAMPLING_RATE_QUERY).await?;
        self.core.check_rate(s.sample_rate_hz, rate)?;
        let hor_scale = self.ask_vbs_number(commands::HOR_SCALE_QUERY).await?;
        let record_s = hor_scale * divisions;
        if record_s < s.record_s() * (1.0 - 1e-9) {
            return Err(self
                .core
                .not_applied("record length (s)", s.record_s(), record_s));
        }
        // The record starts pre_trigger_s before the trigger: the scope puts the trigger at the
        // grid's centre for a delay of 0, so move it by half the record.
        let trigger_delay_s = s.pre_trigger_s - divisions / 2.0 * hor_scale;
        self.core
            .scpi
            .send(&commands::edge_trigger(commands::EXTERNAL))
            .await?;
        self.core
            .scpi
            .send(&commands::trigger_level(
                commands::EXTERNAL,
                s.trigger_level_v,
            ))
            .await?;
        self.core
            .scpi
            .send(&commands::trigger_slope(
                commands::EXTERNAL,
                s.trigger_slope,
            ))
            .await?;
        self.core
            .scpi
            .send(&commands::trigger_delay(trigger_delay_s))
            .await?;
        self.check("the trigger settings").await?;
        Ok(DigitizerApplied {
            sample_rate_hz: rate,
            hor_scale_s: hor_scale,
            record_s,
            points: (record_s * rate).round() as u64,
            trigger_delay_s,
            trigger_source: commands::EXTERNAL.to_string(),
            trigger_level_v: s.trigger_level_v,
            segments: s.segments,
        })
    }

    async fn acquire_impl(&mut self, wait_s: f64) -> Result<(), DriverError> {
        // Reading INR clears it, so bit 0 afterwards means this acquisition.
        self.core.scpi.ask_i64(commands::STATUS).await?;
        let query = commands::single_shot(wait_s);
        let allowed = Duration::from_secs_f64(wait_s + WAIT_SLACK_S)
            + Duration::from_millis(self.core.model.timeouts.read_ms);
        self.core.scpi.complete_within(&query, allowed).await?;
        let inr = self.core.scpi.ask_i64(commands::STATUS).await?;
        if inr & INR_NEW_ACQUISITION == 0 {
            // Disarm so a late edge does not complete an acquisition nobody reads.
            self.core.scpi.send(commands::STOP).await?;
            return Err(DriverError::NoTrigger {
                instrument: self.core.scpi.name().to_string(),
                source_name: commands::EXTERNAL.to_string(),
                waited_s: wait_s,
                safe_state: None,
            });
        }
        Ok(())
    }

    async fn fetch_impl(&mut self, channel: u8) -> Result<ChannelTrace, DriverError> {
        let query = commands::waveform(channel);
        let block = self.core.scpi.query_block(&query).await?;
        let payload: Bytes = block.into_payload();
        let trace = Trace::decode(channel, payload).map_err(|source| DriverError::Waveform {
            instrument: self.core.scpi.name().to_string(),
            channel,
            source,
        })?;
        Ok(neutral(trace))
    }
}

/// A decoded WAVEDESC block in vendor-neutral terms; the `.trc` file bytes are kept beside.
fn neutral(trace: Trace) -> ChannelTrace {
    let segments = trace
        .segments()
        .map(|s| SegmentTiming {
            trigger_time_s: s.trigger_time_s,
            first_sample_s: s.trigger_offset_s,
        })
        .collect();
    // A `.trc` file is the block with its `#9` length header.
    let native = NativeFile {
        extension: "trc",
        header: format!("#9{:09}", trace.block().len()).into_bytes(),
        body: trace.block().clone(),
    };
    ChannelTrace {
        channel: trace.channel,
        volts_per_code: f64::from(trace.desc.vertical_gain),
        offset_v: f64::from(trace.desc.vertical_offset),
        sample_interval_s: trace.sample_interval_s(),
        segments,
        native: Some(native),
        codes: trace.codes,
    }
}

/// The LeCroy's own commands around the shared scope core.
impl ScopeFamily for Lecroy {
    const CHANNEL: &'static str = "C";
    const STOP: &'static str = commands::STOP;

    fn core(&self) -> &ScopeCore {
        &self.core
    }

    fn core_mut(&mut self) -> &mut ScopeCore {
        &mut self.core
    }

    fn trigger_source(&self) -> &str {
        commands::EXTERNAL
    }

    fn send_settings<'a>(
        &'a mut self,
        settings: &'a DigitizerSettings,
        _points: u64,
    ) -> BoxFuture<'a, Result<DigitizerApplied, DriverError>> {
        Box::pin(self.configure_impl(settings))
    }

    fn arm_and_wait(&mut self, wait_s: f64) -> BoxFuture<'_, Result<(), DriverError>> {
        Box::pin(self.acquire_impl(wait_s))
    }

    fn read_channel(&mut self, channel: u8) -> BoxFuture<'_, Result<ChannelTrace, DriverError>> {
        Box::pin(self.fetch_impl(channel))
    }

    fn read_reference(&mut self) -> BoxFuture<'_, Result<String, DriverError>> {
        Box::pin(self.reference_clock_impl())
    }
}
