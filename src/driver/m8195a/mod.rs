//! Keysight M8195A driver: I on channel 1 (sample/marker bytes interleaved), Q on channel 2, the
//! marker on channel 3, in DAC mode DCM from extended memory (16 GSa/s = 64 GSa/s raster / 4).
//!
//! Every limit comes from the catalog and is checked before anything is sent ([`plan`]); every
//! configuration batch ends with an error-queue check; the clock, DAC mode and segment table are
//! read back and compared with what was asked. Spellings live in [`commands`].

pub(crate) mod commands;
pub(crate) mod plan;

use std::time::Duration;

use self::plan::{ClockPlan, DownloadPlan, SEGMENT_ID};
use super::capability::{
    Awg, AwgApplied, AwgSettings, IqWaveform, LoadedSegment, OutputState, ReferenceClock,
    SegmentEntry,
};
use super::error::{session, DriverError};
use super::io::{open_session, BoxFuture, InstrumentIo};
use super::limits::close;
use super::permit::RfPermit;
use super::scpi::Scpi;
use crate::address::Resource;
use crate::catalog::{AwgLimits, InstrumentModel};
use crate::session::{parse_i64, Identity, SCPI_ERROR_QUERY};
use crate::transport::Journal;

/// Relative tolerance when comparing a read-back rate with the requested one.
const RATE_TOLERANCE: f64 = 1e-9;

/// A connected M8195A.
pub struct M8195a {
    scpi: Scpi,
    model: InstrumentModel,
    limits: AwgLimits,
    identity: Identity,
    clock: Option<ClockPlan>,
}

impl M8195a {
    /// Opens the resource (raw socket, HiSLIP or VXI-11) with the model's timeouts and connects.
    ///
    /// # Errors
    ///
    /// [`DriverError::Session`] when the link cannot be opened, and every error of
    /// [`connect`](M8195a::connect).
    pub async fn open(
        resource: Resource,
        model: &InstrumentModel,
        journal: Option<Journal>,
        name: &str,
    ) -> Result<M8195a, DriverError> {
        let session = open_session(resource, model, SCPI_ERROR_QUERY, journal, name)
            .await
            .map_err(session(name))?;
        M8195a::connect(Box::new(session), model, name).await
    }

    /// Checks `*IDN?` against the catalog model and returns the driver.
    ///
    /// # Errors
    ///
    /// [`DriverError::Catalog`] when the model has no `[awg]` section or no I/Q + marker mode;
    /// [`DriverError::Session`] when the link fails; [`DriverError::Reply`] or
    /// [`DriverError::WrongInstrument`] when `*IDN?` is unreadable or not the catalog model.
    pub async fn connect(
        io: Box<dyn InstrumentIo>,
        model: &InstrumentModel,
        name: &str,
    ) -> Result<M8195a, DriverError> {
        let limits = model.awg.clone().ok_or_else(|| DriverError::Catalog {
            key: model.instrument.key.clone(),
            reason: "the model has no [awg] section; it is not an AWG".into(),
        })?;
        plan::iq_marker_mode(&limits, &model.instrument.key)?;
        let mut scpi = Scpi::new(io, name);
        let identity = scpi.identify(model).await?;
        Ok(M8195a {
            scpi,
            model: model.clone(),
            limits,
            identity,
            clock: None,
        })
    }

    pub fn model(&self) -> &InstrumentModel {
        &self.model
    }

    /// The longest wait for `*OPC?` after a download: the catalog's operation-complete time.
    fn operation_complete(&self) -> Duration {
        Duration::from_millis(self.model.timeouts.operation_complete_ms)
    }

    /// Stale entries in the error queue belong to whoever used the instrument before: they are
    /// logged, not blamed on this configuration.
    async fn drain_stale_errors(&mut self) -> Result<(), DriverError> {
        for e in self.scpi.drain_errors().await? {
            tracing::warn!(instrument = %self.scpi.name(), "error queue entry from before this configuration: {e}");
        }
        Ok(())
    }

    async fn configure_impl(&mut self, settings: &AwgSettings) -> Result<AwgApplied, DriverError> {
        let clock = plan::plan_clock(
            &self.limits,
            &self.model.instrument.key,
            self.scpi.name(),
            settings,
        )?;
        self.drain_stale_errors().await?;
        self.clock = None;
        self.scpi.send(commands::ABORT).await?;
        match settings.reference_clock {
            ReferenceClock::Internal => self.scpi.send(commands::REFERENCE_INTERNAL).await?,
            ReferenceClock::External { frequency_hz } => {
                self.scpi.send(commands::REFERENCE_EXTERNAL).await?;
                self.scpi
                    .send(&commands::reference_frequency(frequency_hz))
                    .await?;
            }
        }
        self.scpi.send(&commands::dac_mode(&clock.dac_mode)).await?;
        self.scpi
            .send(&commands::divider(&clock.divider.keyword))
            .await?;
        for ch in [clock.i_channel, clock.q_channel] {
            self.scpi.send(&commands::extended_memory(ch)).await?;
        }
        self.scpi.send(&commands::raster(clock.dac_rate_hz)).await?;
        self.scpi.send(commands::FUNCTION_ARB).await?;
        self.scpi.send(commands::CONTINUOUS).await?;
        self.scpi.send(commands::GATE_OFF).await?;
        self.scpi.check("the DAC mode and sample clock").await?;
        let (i, q, m) = (clock.i_channel, clock.q_channel, clock.marker_channel);
        let levels = [
            commands::amplitude(i, settings.i_amplitude_vpp),
            commands::offset(i, settings.i_offset_v),
            commands::amplitude(q, settings.q_amplitude_vpp),
            commands::offset(q, settings.q_offset_v),
            commands::marker_amplitude(m, settings.marker_amplitude_v),
            commands::offset(m, settings.marker_offset_v),
        ];
        for command in &levels {
            self.scpi.send(command).await?;
        }
        self.scpi.check("the amplitudes and marker levels").await?;
        self.clock = Some(clock.clone());
        let applied = self.applied_impl().await?;
        self.verify_clock(&clock, &applied)?;
        Ok(applied)
    }

    fn verify_clock(&self, clock: &ClockPlan, applied: &AwgApplied) -> Result<(), DriverError> {
        let mismatch = |setting, wanted: String, got: String| DriverError::NotApplied {
            instrument: self.scpi.name().to_string(),
            setting,
            wanted,
            applied: got,
        };
        if !applied.dac_mode.eq_ignore_ascii_case(&clock.dac_mode) {
            return Err(mismatch(
                "DAC mode",
                clock.dac_mode.clone(),
                applied.dac_mode.clone(),
            ));
        }
        if applied.divider != clock.divider.divider {
            return Err(mismatch(
                "sample rate divider",
                clock.divider.keyword.clone(),
                format!("DIV{}", applied.divider),
            ));
        }
        if !close(applied.dac_rate_hz, clock.dac_rate_hz, RATE_TOLERANCE) {
            return Err(mismatch(
                "DAC raster (Sa/s)",
                clock.dac_rate_hz.to_string(),
                applied.dac_rate_hz.to_string(),
            ));
        }
        Ok(())
    }

    fn require_clock(&self) -> Result<ClockPlan, DriverError> {
        self.clock.clone().ok_or_else(|| DriverError::Sequence {
            instrument: self.scpi.name().to_string(),
            what: "configure the AWG (DAC mode, divider) before loading a waveform: the granularity depends on it".into(),
        })
    }

    async fn load_impl(&mut self, waveform: &IqWaveform) -> Result<LoadedSegment, DriverError> {
        let clock = self.require_clock()?;
        let plan = plan::plan_download(&self.limits, &clock, self.scpi.name(), waveform)?;
        self.scpi.send(commands::ABORT).await?;
        self.scpi
            .send(&commands::delete_all(clock.i_channel))
            .await?;
        self.scpi
            .send(&commands::define(clock.i_channel, SEGMENT_ID, plan.padded))
            .await?;
        let chunks = self.download(&clock, &plan, waveform).await?;
        let waited = self.operation_complete();
        self.scpi.complete_within(commands::OPC, waited).await?;
        self.scpi
            .send(&commands::select(clock.i_channel, SEGMENT_ID))
            .await?;
        self.scpi
            .send(&commands::select(clock.q_channel, SEGMENT_ID))
            .await?;
        self.scpi
            .check("the segment definition and download")
            .await?;
        let listed = self.segments(clock.i_channel).await?;
        let expected = SegmentEntry {
            id: SEGMENT_ID,
            samples: plan.padded,
        };
        if !listed.contains(&expected) {
            return Err(DriverError::NotApplied {
                instrument: self.scpi.name().to_string(),
                setting: "segment table",
                wanted: format!("segment {} of {} samples", SEGMENT_ID, plan.padded),
                applied: format!("{listed:?}"),
            });
        }
        Ok(LoadedSegment {
            segment_id: SEGMENT_ID,
            samples: plan.samples,
            padded_samples: plan.padded,
            marker_high_samples: plan.marker_high,
            chunks_per_channel: chunks,
        })
    }

    /// Channel 1 (I + marker) in ascending chunks, then channel 2 (Q).
    async fn download(
        &mut self,
        clock: &ClockPlan,
        plan: &DownloadPlan,
        waveform: &IqWaveform,
    ) -> Result<usize, DriverError> {
        let chunks = plan.chunks();
        for &(offset, len) in &chunks {
            let bytes = plan::interleaved_chunk(&waveform.i, plan.marker_high, offset, len);
            let header = commands::data_header(clock.i_channel, SEGMENT_ID, offset);
            self.scpi.write_block(&header, &bytes).await?;
        }
        for &(offset, len) in &chunks {
            let bytes = plan::plain_chunk(&waveform.q, offset, len);
            let header = commands::data_header(clock.q_channel, SEGMENT_ID, offset);
            self.scpi.write_block(&header, &bytes).await?;
        }
        Ok(chunks.len())
    }

    async fn segments(&mut self, channel: u8) -> Result<Vec<SegmentEntry>, DriverError> {
        let query = commands::catalog_query(channel);
        let text = self.scpi.ask(&query).await?;
        parse_catalog(&text).ok_or_else(|| {
            self.scpi
                .reply_error(&query, "id,length[,id,length...]", &text)
        })
    }

    fn signal_channels(&self) -> (u8, u8, u8) {
        match &self.clock {
            Some(c) => (c.i_channel, c.q_channel, c.marker_channel),
            None => (1, 2, 3),
        }
    }

    async fn enable_impl(&mut self) -> Result<(), DriverError> {
        let (i, q, m) = self.signal_channels();
        // On (for the live view) from the first output sent on, until a switch-off took.
        crate::driver::rf_state::set(self.scpi.name(), true);
        for ch in [i, q, m] {
            self.scpi.send(&commands::output(ch, true)).await?;
        }
        self.scpi.check("switching the outputs on").await
    }

    async fn outputs_off_impl(&mut self) -> Result<(), DriverError> {
        for ch in 1..=self.limits.channels {
            self.scpi.send(&commands::output(ch, false)).await?;
        }
        self.scpi.check("switching the outputs off").await?;
        crate::driver::rf_state::set(self.scpi.name(), false);
        Ok(())
    }

    /// Everything [`AwgApplied`] holds, read in one compound query (a campaign reads it before
    /// every step: one round trip instead of twelve).
    async fn applied_impl(&mut self) -> Result<AwgApplied, DriverError> {
        let (i, q, m) = self.signal_channels();
        let catalog = commands::catalog_query(i);
        let amplitudes = [commands::amplitude_query(i), commands::amplitude_query(q)];
        let marker = [
            commands::marker_amplitude_query(m),
            commands::offset_query(m),
        ];
        let outputs = [i, q, m].map(commands::output_query);
        let queries: Vec<&str> = [
            commands::DAC_MODE_QUERY,
            commands::DIVIDER_QUERY,
            commands::RASTER_QUERY,
            &catalog,
            &amplitudes[0],
            &amplitudes[1],
            &marker[0],
            &marker[1],
            commands::REFERENCE_QUERY,
        ]
        .into_iter()
        .chain(outputs.iter().map(String::as_str))
        .collect();
        let r = self.scpi.ask_each(&queries).await?;
        let divider = parse_divider(&r[1]).ok_or_else(|| {
            self.scpi
                .reply_error(commands::DIVIDER_QUERY, "DIV1, DIV2 or DIV4", &r[1])
        })?;
        let segments = parse_catalog(&r[3]).ok_or_else(|| {
            self.scpi
                .reply_error(&catalog, "id,length[,id,length...]", &r[3])
        })?;
        let number = |k: usize| self.scpi.number_in(queries[k], &r[k]);
        let dac_rate_hz = number(2)?;
        let mut states = Vec::new();
        for (k, channel) in [i, q, m].into_iter().enumerate() {
            let on = self.scpi.bool_in(queries[9 + k], &r[9 + k])?;
            states.push(OutputState { channel, on });
        }
        Ok(AwgApplied {
            dac_mode: r[0].clone(),
            divider,
            dac_rate_hz,
            sample_rate_hz: dac_rate_hz / f64::from(divider),
            segments,
            i_amplitude_vpp: number(4)?,
            q_amplitude_vpp: number(5)?,
            marker_amplitude_v: number(6)?,
            marker_offset_v: number(7)?,
            reference_source: r[8].clone(),
            outputs: states,
        })
    }

    /// Every output off (each tried even if another fails), then `:ABOR`, then the error queue.
    async fn safe_state_impl(&mut self) -> Result<(), DriverError> {
        let mut first_error = None;
        for ch in 1..=self.limits.channels {
            if let Err(e) = self.scpi.send(&commands::output(ch, false)).await {
                tracing::error!(instrument = %self.scpi.name(), "safe state: output {ch} off failed: {e}");
                first_error.get_or_insert(e);
            }
        }
        if first_error.is_none() {
            crate::driver::rf_state::set(self.scpi.name(), false);
        }
        if let Err(e) = self.scpi.send(commands::ABORT).await {
            tracing::error!(instrument = %self.scpi.name(), "safe state: {} failed: {e}", commands::ABORT);
            first_error.get_or_insert(e);
        }
        if let Err(e) = self.scpi.check("the safe-state sequence").await {
            first_error.get_or_insert(e);
        }
        first_error.map_or(Ok(()), Err)
    }
}

/// `:TRAC:CAT?` -> `id,len[,id,len...]`; `0,0` means no segment.
pub(crate) fn parse_catalog(text: &str) -> Option<Vec<SegmentEntry>> {
    let numbers: Vec<i64> = text
        .trim()
        .split(',')
        .map(|t| parse_i64(t.trim()))
        .collect::<Option<_>>()?;
    if numbers.len() % 2 != 0 {
        return None;
    }
    let mut out = Vec::new();
    for pair in numbers.chunks_exact(2) {
        let (id, len) = (pair[0], pair[1]);
        if id == 0 && len == 0 {
            continue;
        }
        out.push(SegmentEntry {
            id: u32::try_from(id).ok()?,
            samples: u64::try_from(len).ok()?,
        });
    }
    Some(out)
}

/// `DIV4` (or `4`) -> 4.
pub(crate) fn parse_divider(text: &str) -> Option<u32> {
    let t = text.trim().trim_matches('"');
    let digits = t
        .strip_prefix("DIV")
        .or_else(|| t.strip_prefix("div"))
        .unwrap_or(t);
    digits.parse().ok().filter(|d| [1, 2, 4].contains(d))
}

impl Awg for M8195a {
    fn identity(&self) -> &Identity {
        &self.identity
    }

    fn configure<'a>(
        &'a mut self,
        settings: &'a AwgSettings,
    ) -> BoxFuture<'a, Result<AwgApplied, DriverError>> {
        Box::pin(self.configure_impl(settings))
    }

    fn load<'a>(
        &'a mut self,
        waveform: &'a IqWaveform,
    ) -> BoxFuture<'a, Result<LoadedSegment, DriverError>> {
        Box::pin(self.load_impl(waveform))
    }

    fn enable_outputs<'a>(
        &'a mut self,
        _permit: &'a RfPermit,
    ) -> BoxFuture<'a, Result<(), DriverError>> {
        Box::pin(self.enable_impl())
    }

    fn enable_marker(&mut self) -> BoxFuture<'_, Result<(), DriverError>> {
        Box::pin(async move {
            let (_, _, m) = self.signal_channels();
            self.scpi.send(&commands::output(m, true)).await?;
            self.scpi.check("switching the marker output on").await
        })
    }

    fn outputs_off(&mut self) -> BoxFuture<'_, Result<(), DriverError>> {
        Box::pin(self.outputs_off_impl())
    }

    fn run(&mut self) -> BoxFuture<'_, Result<(), DriverError>> {
        Box::pin(async move {
            self.scpi.send(commands::RUN).await?;
            self.scpi.check("starting the playback").await
        })
    }

    fn stop(&mut self) -> BoxFuture<'_, Result<(), DriverError>> {
        Box::pin(async move {
            self.scpi.send(commands::ABORT).await?;
            self.scpi.check("stopping the playback").await
        })
    }

    fn applied(&mut self) -> BoxFuture<'_, Result<AwgApplied, DriverError>> {
        Box::pin(self.applied_impl())
    }

    fn safe_state(&mut self) -> BoxFuture<'_, Result<(), DriverError>> {
        Box::pin(self.safe_state_impl())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn catalog_replies_parse() {
        assert_eq!(parse_catalog("0,0"), Some(vec![]));
        assert_eq!(
            parse_catalog("1,16384"),
            Some(vec![SegmentEntry {
                id: 1,
                samples: 16384
            }])
        );
        assert_eq!(parse_catalog("1"), None);
        assert_eq!(parse_catalog("x,y"), None);
        assert_eq!(parse_divider("DIV4"), Some(4));
        assert_eq!(parse_divider("DIV3"), None);
    }
}
