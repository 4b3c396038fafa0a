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
use super::capability::{Digitizer, DigitizerApplied, DigitizerSettings};
use super::error::{session, DriverError};
use super::io::{open_session, BoxFuture, InstrumentIo};
use super::limits::{close, within};
use super::scpi::Scpi;
use super::trace::{ChannelTrace, IqCapture, NativeFile, SegmentTiming};
use crate::address::Resource;
use crate::catalog::{DigitizerLimits, InstrumentModel};
use crate::session::{parse_f64, register_error_text, DeviceError, Identity, SessionError};
use crate::transport::Journal;

pub(crate) use self::vendor::check_vendor;

/// Channel that carries I.
pub(crate) const I_CHANNEL: u8 = 1;
/// Channel that carries Q.
pub(crate) const Q_CHANNEL: u8 = 2;
/// INR bit 0: a new acquisition completed.
const INR_NEW_ACQUISITION: i64 = 1;
/// Relative tolerance on the read-back sample rate.
const RATE_TOLERANCE: f64 = 1e-6;
/// Slack on the WAIT timeout before the reply itself is considered late, seconds.
const WAIT_SLACK_S: f64 = 5.0;

/// A connected LeCroy scope.
pub struct Lecroy {
    scpi: Scpi,
    model: InstrumentModel,
    limits: DigitizerLimits,
    identity: Identity,
    vbs_prefix: Option<String>,
    /// Segments per acquisition and points per segment as last configured.
    segments: u32,
    points: u64,
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
        let limits = model
            .digitizer
            .clone()
            .ok_or_else(|| DriverError::Catalog {
                key: model.instrument.key.clone(),
                reason: "the model has no [digitizer] section; it is not a scope".into(),
            })?;
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
            scpi,
            vbs_prefix: model.quirks.vbs_reply_prefix.clone(),
            model: model.clone(),
            limits,
            identity,
            segments: 1,
            points: 0,
        })
    }

    pub fn model(&self) -> &InstrumentModel {
        &self.model
    }

    /// The timebase's reference as the scope reports it (`RCLK?`: `INTERNAL` or `EXTERNAL`).
    pub(crate) async fn reference_clock(&mut self) -> Result<String, DriverError> {
        let text = self.scpi.ask(commands::REFERENCE_QUERY).await?;
        Ok(text.trim().trim_start_matches("RCLK").trim().to_string())
    }

    /// A `VBS?` number, with the catalog's `VBS ` reply prefix stripped when present.
    async fn ask_vbs_number(&mut self, query: &str) -> Result<f64, DriverError> {
        let text = self.scpi.ask(query).await?;
        let mut body = text.trim();
        if let Some(prefix) = &self.vbs_prefix {
            body = body.strip_prefix(prefix.as_str()).unwrap_or(body);
        }
        parse_f64(body.trim()).ok_or_else(|| self.scpi.reply_error(query, "a number", &text))
    }

    /// Reads one error register (which clears it): its entry, if it holds an error.
    async fn register_error(&mut self, register: &str) -> Result<Option<DeviceError>, DriverError> {
        let code = self.scpi.ask_i64(register).await?;
        let code = i32::try_from(code).map_err(|_| {
            self.scpi
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
        self.scpi.refused_if_any(batch, errors)
    }

    fn validate(&self, s: &DigitizerSettings) -> Result<(), DriverError> {
        let l = &self.limits;
        let n = self.scpi.name();
        if !l
            .sample_rates
            .iter()
            .any(|r| close(*r, s.sample_rate_hz, RATE_TOLERANCE))
        {
            return Err(DriverError::OutOfLimits {
                instrument: n.to_string(),
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
                instrument: n.to_string(),
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
        if s.segments == 0 || (s.segments > 1 && s.segments > l.max_sequence_segments) {
            let allowed = if l.max_sequence_segments > 1 {
                format!(
                    "1..={} (the catalog's max_sequence_segments)",
                    l.max_sequence_segments
                )
            } else {
                "1: the catalog gives this model no sequence mode (max_sequence_segments)".into()
            };
            return Err(DriverError::OutOfLimits {
                instrument: n.to_string(),
                field: "segments",
                value: s.segments.to_string(),
                allowed,
            });
        }
        if points * f64::from(s.segments) > l.max_points_per_channel as f64 {
            return Err(DriverError::OutOfLimits {
                instrument: n.to_string(),
                field: "segments",
                value: format!("{} segments of {points} points", s.segments),
                allowed: format!(
                    "at most {} points per channel in all segments together",
                    l.max_points_per_channel
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
        for register in [commands::COMMAND_ERRORS, commands::EXECUTION_ERRORS] {
            if let Some(stale) = self.register_error(register).await? {
                tracing::warn!(instrument = %self.scpi.name(), "error register entry from before this configuration: {stale}");
            }
        }
        for command in [
            commands::HEADERS_OFF,
            commands::WORD_FORMAT,
            commands::LSB_FIRST,
            commands::WHOLE_RECORD,
        ] {
            self.scpi.send(command).await?;
        }
        self.check("the transfer format").await?;
        for (ch, vdiv, offset) in [
            (I_CHANNEL, s.i_volts_per_div, s.i_offset_v),
            (Q_CHANNEL, s.q_volts_per_div, s.q_offset_v),
        ] {
            self.scpi.send(&commands::trace_on(ch)).await?;
            self.scpi.send(&commands::volts_per_div(ch, vdiv)).await?;
            self.scpi.send(&commands::offset(ch, offset)).await?;
        }
        if s.external_reference {
            self.scpi.send(commands::EXTERNAL_REFERENCE).await?;
        }
        self.check("the channel settings").await?;
        // Always set the sample mode: a scope left in sequence mode would otherwise record
        // several triggers where one is expected.
        if s.segments > 1 {
            self.scpi.send(commands::SEQUENCE).await?;
            self.scpi.send(&commands::segments(s.segments)).await?;
        } else {
            self.scpi.send(commands::REAL_TIME).await?;
        }
        self.check("the sample mode").await?;
        if s.segments > 1 {
            let applied = self.ask_vbs_number(commands::SEGMENTS_QUERY).await?;
            if applied != f64::from(s.segments) {
                return Err(DriverError::NotApplied {
                    instrument: self.scpi.name().to_string(),
                    setting: "sequence segments",
                    wanted: s.segments.to_string(),
                    applied: applied.to_string(),
                });
            }
        }
        self.segments = s.segments;
        self.scpi.send(commands::FIXED_RATE).await?;
        self.scpi
            .send(&commands::sample_rate(s.sample_rate_hz))
            .await?;
        self.scpi
            .send(&commands::hor_scale(s.record_s() / divisions))
            .await?;
        self.check("the sample rate and record length").await?;
        let rate = self.ask_vbs_number(commands::SAMPLING_RATE_QUERY).await?;
        if !close(rate, s.sample_rate_hz, RATE_TOLERANCE) {
            return Err(DriverError::NotApplied {
                instrument: self.scpi.name().to_string(),
                setting: "sample rate (Sa/s)",
                wanted: s.sample_rate_hz.to_string(),
                applied: rate.to_string(),
            });
        }
        let hor_scale = self.ask_vbs_number(commands::HOR_SCALE_QUERY).await?;
        let record_s = hor_scale * divisions;
        if record_s < s.record_s() * (1.0 - 1e-9) {
            return Err(DriverError::NotApplied {
                instrument: self.scpi.name().to_string(),
                setting: "record length (s)",
                wanted: s.record_s().to_string(),
                applied: record_s.to_string(),
            });
        }
        // The record starts pre_trigger_s before the trigger: the scope puts the trigger at the
        // grid's centre for a delay of 0, so move it by half the record.
        let trigger_delay_s = s.pre_trigger_s - divisions / 2.0 * hor_scale;
        self.scpi
            .send(&commands::edge_trigger(commands::EXTERNAL))
            .await?;
        self.scpi
            .send(&commands::trigger_level(
                commands::EXTERNAL,
                s.trigger_level_v,
            ))
            .await?;
        self.scpi
            .send(&commands::trigger_slope(
                commands::EXTERNAL,
                s.trigger_slope,
            ))
            .await?;
        self.scpi
            .send(&commands::trigger_delay(trigger_delay_s))
            .await?;
        self.check("the trigger settings").await?;
        self.points = (record_s * rate).round() as u64;
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
        within(self.scpi.name(), "wait_s", wait_s, 0.0, 1.0e5, "s")?;
        // Reading INR clears it, so bit 0 afterwards means this acquisition.
        self.scpi.ask_i64(commands::STATUS).await?;
        let query = commands::single_shot(wait_s);
        let allowed = Duration::from_secs_f64(wait_s + WAIT_SLACK_S)
            + Duration::from_millis(self.model.timeouts.read_ms);
        self.scpi.complete_within(&query, allowed).await?;
        let inr = self.scpi.ask_i64(commands::STATUS).await?;
        if inr & INR_NEW_ACQUISITION == 0 {
            // Disarm so a late edge does not complete an acquisition nobody reads.
            self.scpi.send(commands::STOP).await?;
            return Err(DriverError::NoTrigger {
                instrument: self.scpi.name().to_string(),
                source_name: commands::EXTERNAL.to_string(),
                waited_s: wait_s,
                safe_state: None,
            });
        }
        Ok(())
    }

    async fn fetch_impl(&mut self, channel: u8) -> Result<ChannelTrace, DriverError> {
        if channel == 0 || channel > self.limits.channels {
            return Err(DriverError::BadSettings {
                instrument: self.scpi.name().to_string(),
                field: "channel",
                reason: format!(
                    "C{channel} does not exist; allowed C1..=C{}",
                    self.limits.channels
                ),
            });
        }
        let query = commands::waveform(channel);
        let block = self.scpi.query_block(&query).await?;
        let payload: Bytes = block.into_payload();
        let trace = Trace::decode(channel, payload).map_err(|source| DriverError::Waveform {
            instrument: self.scpi.name().to_string(),
            channel,
            source,
        })?;
        Ok(neutral(trace))
    }

    /// Both channels of the last acquisition, each checked to hold the configured segments.
    async fn fetch_iq(&mut self) -> Result<IqCapture, DriverError> {
        let i = self.fetch_impl(I_CHANNEL).await?;
        let q = self.fetch_impl(Q_CHANNEL).await?;
        for t in [&i, &q] {
            // A scope short of memory for the whole sequence shortens the segments instead.
            let short = (t.segment_len() as u64).saturating_add(1) < self.points;
            if short
                || t.segment_count() != self.segments as usize
                || t.codes.len() != i.codes.len()
            {
                return Err(DriverError::NotApplied {
                    instrument: self.scpi.name().to_string(),
                    setting: "segments of the record (C1 and C2)",
                    wanted: format!("{} of {} points", self.segments, self.points),
                    applied: format!(
                        "C{}: {} segments, {} points",
                        t.channel,
                        t.segment_count(),
                        t.codes.len()
                    ),
                });
            }
        }
        Ok(IqCapture { i, q })
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

    fn fetch(&mut self, channel: u8) -> BoxFuture<'_, Result<ChannelTrace, DriverError>> {
        Box::pin(self.fetch_impl(channel))
    }

    fn capture_iq(&mut self, wait_s: f64) -> BoxFuture<'_, Result<IqCapture, DriverError>> {
        Box::pin(async move {
            self.acquire_impl(wait_s).await?;
            self.fetch_iq().await
        })
    }

    fn stop(&mut self) -> BoxFuture<'_, Result<(), DriverError>> {
        Box::pin(async move { self.scpi.send(commands::STOP).await })
    }

    fn reference_clock(&mut self) -> BoxFuture<'_, Result<String, DriverError>> {
        Box::pin(Lecroy::reference_clock(self))
    }
}
