//! Keysight Infiniium (UXR class) driver, over HiSLIP or VXI-11 with the same SCPI commands.
//!
//! I on channel 1, Q on channel 2, the AWG's marker on the auxiliary trigger input (the catalog's
//! `[vendor] trigger_source`); a fixed sample rate and record length (`:ACQuire:SRATe:ANALog`,
//! `:ACQuire:POINts:ANALog`), the record starting `pre_trigger_s` before the trigger. One
//! acquisition is armed with `:SINGle` and watched with the Acquisition Done Event Register
//! (`:ADER?`) until the caller's wait runs out. With more than one segment the scope runs in
//! segmented memory: one segment per trigger, all of them read in one `:WAVeform:DATA?` block
//! (`:WAVeform:SEGMented:ALL ON`) with their time tags. Waveforms are 16-bit words
//! (`:WAVeform:FORMat WORD`, LSB first) scaled by `:WAVeform:PREamble?`, handed up as
//! vendor-neutral [`ChannelTrace`]s. The scope writes no file of its own here: a capture saves
//! the SigMF recording only (no `.trc`). The SCPI error queue is read after each batch.

pub(crate) mod commands;

use std::time::{Duration, Instant};

use serde::Deserialize;

use super::capability::{DigitizerApplied, DigitizerSettings};
use super::error::{session, DriverError};
use super::io::{open_session, BoxFuture, InstrumentIo};
use super::scope_core::{ScopeCore, ScopeFamily, I_CHANNEL, Q_CHANNEL};
use super::scpi::Scpi;
use super::trace::{ChannelTrace, SegmentTiming};
use crate::address::Resource;
use crate::catalog::InstrumentModel;
use crate::session::{parse_f64, parse_i64, SCPI_ERROR_QUERY};
use crate::transport::Journal;

/// `<format>` of the Infiniium preamble for WORD data (0 ASCii, 1 BYTE, 2 WORD, ...).
const PREAMBLE_WORD: i64 = 2;
/// Fields of the preamble the driver reads (format .. Y reference).
const PREAMBLE_MIN_FIELDS: usize = 10;

/// The `[vendor]` table of an Infiniium catalog file.
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
struct Vendor {
    /// The trigger input the AWG's marker drives (`AUX` on the UXR).
    trigger_source: String,
    /// How often `:ADER?` is asked while an acquisition is armed, milliseconds.
    acquisition_poll_ms: u64,
}

fn vendor(model: &InstrumentModel) -> Result<Vendor, DriverError> {
    Vendor::deserialize(toml::Value::Table(model.vendor.clone())).map_err(|e| {
        DriverError::Catalog {
            key: model.instrument.key.clone(),
            reason: format!(
                "[vendor] of a keysight-infiniium model: {} (fields: trigger_source = \"AUX\", \
                 acquisition_poll_ms = 1 ..= 1000)",
                e.to_string().trim()
            ),
        }
    })
}

/// Checks the `[vendor]` table of an Infiniium catalog entry.
pub(crate) fn check_vendor(model: &InstrumentModel) -> Result<(), DriverError> {
    let v = vendor(model)?;
    let bad = |reason: &str| DriverError::Catalog {
        key: model.instrument.key.clone(),
        reason: reason.to_string(),
    };
    if !(1..=1000).contains(&v.acquisition_poll_ms) {
        return Err(bad("[vendor] acquisition_poll_ms must be 1 ..= 1000"));
    }
    let digitizer = model
        .digitizer
        .as_ref()
        .ok_or_else(|| bad("the model has no [digitizer] section; it is not a scope"))?;
    if !digitizer.trigger_sources.contains(&v.trigger_source) {
        return Err(bad(
            "[vendor] trigger_source must be one of [digitizer] trigger_sources",
        ));
    }
    Ok(())
}

/// A connected Infiniium scope: the shared scope core and its `[vendor]` table.
pub struct KeysightUxr {
    core: ScopeCore,
    vendor: Vendor,
}

/// The scaling and timing of one `:WAVeform:PREamble?`.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Preamble {
    points: u64,
    x_increment: f64,
    x_origin: f64,
    y_increment: f64,
    y_origin: f64,
    y_reference: f64,
}

impl KeysightUxr {
    /// Opens the resource (HiSLIP or VXI-11), identifies the scope and returns the driver.
    ///
    /// # Errors
    /// The session cannot be opened, or `*IDN?` is not this model.
    pub async fn open(
        resource: Resource,
        model: &InstrumentModel,
        journal: Option<Journal>,
        name: &str,
    ) -> Result<KeysightUxr, DriverError> {
        let session = open_session(resource, model, SCPI_ERROR_QUERY, journal, name)
            .await
            .map_err(session(name))?;
        KeysightUxr::connect(Box::new(session), model, name).await
    }

    /// Identifies the scope on an open session (or a scripted fake).
    ///
    /// # Errors
    /// The catalog entry is no Infiniium digitizer, or `*IDN?` is not this model.
    pub async fn connect(
        io: Box<dyn InstrumentIo>,
        model: &InstrumentModel,
        name: &str,
    ) -> Result<KeysightUxr, DriverError> {
        check_vendor(model)?;
        let vendor = vendor(model)?;
        let limits = ScopeCore::limits_of(model)?;
        let mut scpi = Scpi::new(io, name);
        scpi.send(commands::HEADERS_OFF).await?;
        let identity = scpi.identify(model).await?;
        Ok(KeysightUxr {
            core: ScopeCore::new(scpi, model, limits, identity),
            vendor,
        })
    }

    async fn ask_number(&mut self, query: &str) -> Result<f64, DriverError> {
        let text = self.core.scpi.ask(query).await?;
        self.core.scpi.number_in(query, &text)
    }

    async fn configure_impl(
        &mut self,
        s: &DigitizerSettings,
        points: u64,
    ) -> Result<DigitizerApplied, DriverError> {
        let stale = self.core.scpi.drain_errors().await?;
        for e in stale {
            tracing::warn!(instrument = %self.core.scpi.name(), "error queue entry from before this configuration: {e}");
        }
        for command in [
            commands::HEADERS_OFF,
            commands::WORD_FORMAT,
            commands::LSB_FIRST,
            commands::STREAMING_OFF,
        ] {
            self.core.scpi.send(command).await?;
        }
        self.core.scpi.check("the transfer format").await?;
        for (ch, vdiv, offset) in [
            (I_CHANNEL, s.i_volts_per_div, s.i_offset_v),
            (Q_CHANNEL, s.q_volts_per_div, s.q_offset_v),
        ] {
            self.core.scpi.send(&commands::channel_on(ch)).await?;
            self.core.scpi.send(&commands::scale(ch, vdiv)).await?;
            self.core.scpi.send(&commands::offset(ch, offset)).await?;
        }
        if s.external_reference {
            self.core.scpi.send(commands::EXTERNAL_REFERENCE).await?;
        }
        self.core.scpi.check("the channel settings").await?;
        // Always set the mode: a scope left in segmented memory would record several triggers
        // where one is expected.
        if s.segments > 1 {
            self.core.scpi.send(commands::SEGMENTED).await?;
            self.core.scpi.send(&commands::segments(s.segments)).await?;
            self.core.scpi.send(commands::ALL_SEGMENTS).await?;
        } else {
            self.core.scpi.send(commands::REAL_TIME).await?;
        }
        self.core.scpi.check("the acquisition mode").await?;
        if s.segments > 1 {
            let applied = self.ask_number(commands::SEGMENTS_QUERY).await?;
            self.core.check_segments(s.segments, applied)?;
        }
        let divisions = f64::from(self.core.limits.horizontal_divisions.max(1));
        self.core
            .scpi
            .send(&commands::sample_rate(s.sample_rate_hz))
            .await?;
        self.core.scpi.send(&commands::points(points)).await?;
        self.core.scpi.send(commands::REFERENCE_LEFT).await?;
        self.core
            .scpi
            .send(&commands::hor_scale(s.record_s() / divisions))
            .await?;
        self.core
            .scpi
            .send(&commands::position(-s.pre_trigger_s))
            .await?;
        self.core
            .scpi
            .check("the sample rate and record length")
            .await?;
        let rate = self.ask_number(commands::SAMPLE_RATE_QUERY).await?;
        self.core.check_rate(s.sample_rate_hz, rate)?;
        let applied_points = self.ask_number(commands::POINTS_QUERY).await?;
        if !(applied_points.is_finite() && applied_points >= points as f64) {
            return Err(self
                .core
                .not_applied("points per channel", points, applied_points));
        }
        let applied_points = applied_points as u64;
        let source = self.vendor.trigger_source.clone();
        for command in [
            commands::EDGE_MODE.to_string(),
            commands::edge_source(&source),
            commands::trigger_level(&source, s.trigger_level_v),
            commands::trigger_slope(s.trigger_slope),
            commands::TRIGGERED_SWEEP.to_string(),
        ] {
            self.core.scpi.send(&command).await?;
        }
        self.core.scpi.check("the trigger settings").await?;
        let record_s = applied_points as f64 / rate;
        Ok(DigitizerApplied {
            sample_rate_hz: rate,
            hor_scale_s: record_s / divisions,
            record_s,
            points: applied_points,
            trigger_delay_s: -s.pre_trigger_s,
            trigger_source: source,
            trigger_level_v: s.trigger_level_v,
            segments: s.segments,
        })
    }

    async fn acquire_impl(&mut self, wait_s: f64) -> Result<(), DriverError> {
        // Reading the register clears it: a done bit afterwards means this acquisition.
        self.core.scpi.ask_i64(commands::ACQUISITION_DONE).await?;
        self.core.scpi.send(commands::SINGLE).await?;
        let deadline = Instant::now() + Duration::from_secs_f64(wait_s);
        let poll = Duration::from_millis(self.vendor.acquisition_poll_ms);
        loop {
            let done = self.core.scpi.ask_i64(commands::ACQUISITION_DONE).await?;
            match done {
                1 => return Ok(()),
                0 => {}
                other => {
                    return Err(self.core.scpi.reply_error(
                        commands::ACQUISITION_DONE,
                        "0 or 1",
                        &other.to_string(),
                    ))
                }
            }
            let now = Instant::now();
            if now >= deadline {
                break;
            }
            tokio::time::sleep(poll.min(deadline - now)).await;
        }
        // Disarm so a late edge does not complete an acquisition nobody reads.
        self.core.scpi.send(commands::STOP).await?;
        Err(DriverError::NoTrigger {
            instrument: self.core.scpi.name().to_string(),
            source_name: self.vendor.trigger_source.clone(),
            waited_s: wait_s,
            safe_state: None,
        })
    }

    async fn preamble(&mut self) -> Result<Preamble, DriverError> {
        let text = self.core.scpi.ask(commands::PREAMBLE).await?;
        let fields: Vec<&str> = text.trim().split(',').map(str::trim).collect();
        let bad = |scpi: &Scpi| {
            scpi.reply_error(
                commands::PREAMBLE,
                "the Infiniium preamble: format 2 (WORD), type, points, count, X increment, X \
                 origin, X reference, Y increment, Y origin, Y reference, ...",
                &text,
            )
        };
        if fields.len() < PREAMBLE_MIN_FIELDS || parse_i64(fields[0]) != Some(PREAMBLE_WORD) {
            return Err(bad(&self.core.scpi));
        }
        let number = |k: usize| parse_f64(fields[k]).filter(|v| v.is_finite());
        let (Some(points), Some(xi), Some(xo), Some(yi), Some(yo), Some(yr)) = (
            parse_i64(fields[2]).and_then(|p| u64::try_from(p).ok()),
            number(4),
            number(5),
            number(7),
            number(8),
            number(9),
        ) else {
            return Err(bad(&self.core.scpi));
        };
        if !(xi > 0.0 && yi > 0.0) {
            return Err(bad(&self.core.scpi));
        }
        Ok(Preamble {
            points,
            x_increment: xi,
            x_origin: xo,
            y_increment: yi,
            y_origin: yo,
            y_reference: yr,
        })
    }

    /// The segments' trigger times, seconds from the first (one per segment).
    async fn time_tags(&mut self, segments: usize) -> Result<Vec<f64>, DriverError> {
        if segments < 2 {
            return Ok(vec![0.0]);
        }
        let text = self.core.scpi.ask(commands::TIME_TAGS).await?;
        let tags: Option<Vec<f64>> = text
            .trim()
            .split(',')
            .map(|t| parse_f64(t.trim()).filter(|v| v.is_finite()))
            .collect();
        match tags {
            Some(t) if t.len() == segments => Ok(t),
            _ => Err(self.core.scpi.reply_error(
                commands::TIME_TAGS,
                "one time tag per segment, comma separated",
                &text,
            )),
        }
    }

    async fn fetch_impl(&mut self, channel: u8) -> Result<ChannelTrace, DriverError> {
        self.core.scpi.send(&commands::source(channel)).await?;
        let pre = self.preamble().await?;
        let block = self.core.scpi.query_block(commands::DATA).await?;
        let bytes = block.payload();
        let words = bytes.len() / 2;
        let per_segment = pre.points.max(1) as usize;
        if bytes.len() % 2 != 0 || words == 0 || words % per_segment != 0 {
            return Err(self.core.scpi.reply_error(
                commands::DATA,
                "a block of 16-bit words, a whole number of segments of the preamble's points",
                &format!(
                    "a block of {} bytes ({} points per segment)",
                    bytes.len(),
                    pre.points
                ),
            ));
        }
        let codes: Vec<i16> = bytes
            .chunks_exact(2)
            .map(|w| i16::from_le_bytes([w[0], w[1]]))
            .collect();
        let segments = words / per_segment;
        let tags = self.time_tags(segments).await?;
        let segments = tags
            .into_iter()
            .map(|t| SegmentTiming {
                trigger_time_s: Some(t),
                first_sample_s: pre.x_origin,
            })
            .collect();
        Ok(ChannelTrace {
            channel,
            codes,
            volts_per_code: pre.y_increment,
            // volts = (code - Y reference) * Y increment + Y origin.
            offset_v: pre.y_reference * pre.y_increment - pre.y_origin,
            sample_interval_s: pre.x_increment,
            segments,
            native: None,
        })
    }

    async fn reference_clock_impl(&mut self) -> Result<String, DriverError> {
        let text = self.core.scpi.ask(commands::REFERENCE_QUERY).await?;
        let on = self
            .core
            .scpi
            .bool_in(commands::REFERENCE_QUERY, text.trim())?;
        Ok(if on { "EXTERNAL" } else { "INTERNAL" }.to_string())
    }
}

/// The Infiniium's own commands around the shared scope core.
impl ScopeFamily for KeysightUxr {
    const CHANNEL: &'static str = "channel ";
    const STOP: &'static str = commands::STOP;

    fn core(&self) -> &ScopeCore {
        &self.core
    }

    fn core_mut(&mut self) -> &mut ScopeCore {
        &mut self.core
    }

    fn trigger_source(&self) -> &str {
        &self.vendor.trigger_source
    }

    fn send_settings<'a>(
        &'a mut self,
        settings: &'a DigitizerSettings,
        points: u64,
    ) -> BoxFuture<'a, Result<DigitizerApplied, DriverError>> {
        Box::pin(self.configure_impl(settings, points))
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
