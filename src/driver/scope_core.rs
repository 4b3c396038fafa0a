//! What every scope (digitizer) driver shares, written once: the settings checked against the
//! catalog's `[digitizer]` limits before anything is sent, the segments and points remembered
//! from `configure` to check what `capture_iq` reads, and the [`Digitizer`] impl itself. A
//! family ([`ScopeFamily`]) supplies only its own commands: sending checked settings and reading
//! back what applied, arming, reading one channel, asking for its reference.

use super::capability::{Digitizer, DigitizerApplied, DigitizerSettings};
use super::error::DriverError;
use super::io::BoxFuture;
use super::limits::{close, within};
use super::scpi::Scpi;
use super::trace::{ChannelTrace, IqCapture};
use crate::catalog::{DigitizerLimits, InstrumentModel};
use crate::session::Identity;

/// Channel that carries I.
pub(crate) const I_CHANNEL: u8 = 1;
/// Channel that carries Q.
pub(crate) const Q_CHANNEL: u8 = 2;
/// Relative tolerance on the read-back sample rate.
pub(crate) const RATE_TOLERANCE: f64 = 1e-6;
/// The longest acquisition wait a caller may ask for, seconds.
const MOST_WAIT_S: f64 = 1.0e5;

/// A scope family's own part: its commands, in its own words. Everything else is [`ScopeCore`]'s
/// and the [`Digitizer`] impl below.
pub(crate) trait ScopeFamily: Send {
    /// How the family's manuals write a channel before its number (`C` in `C1`, `channel ` in
    /// `channel 1`), for errors in its words.
    const CHANNEL: &'static str;
    /// The command that disarms it.
    const STOP: &'static str;
    fn core(&self) -> &ScopeCore;
    fn core_mut(&mut self) -> &mut ScopeCore;
    /// The trigger input the AWG's marker drives, as `[digitizer] trigger_sources` spells it.
    fn trigger_source(&self) -> &str;
    /// Sends settings already checked against the limits (`points` per segment) and reads back
    /// what the scope applied.
    fn send_settings<'a>(
        &'a mut self,
        settings: &'a DigitizerSettings,
        points: u64,
    ) -> BoxFuture<'a, Result<DigitizerApplied, DriverError>>;
    /// Arms one acquisition and waits up to `wait_s` (already checked) for its triggers.
    fn arm_and_wait(&mut self, wait_s: f64) -> BoxFuture<'_, Result<(), DriverError>>;
    /// Reads one channel (known to exist) of the last acquisition.
    fn read_channel(&mut self, channel: u8) -> BoxFuture<'_, Result<ChannelTrace, DriverError>>;
    /// The timebase's reference as the scope says it (`INTERNAL` or `EXTERNAL`).
    fn read_reference(&mut self) -> BoxFuture<'_, Result<String, DriverError>>;
}

/// A connected scope's state that is no family's own.
pub(crate) struct ScopeCore {
    pub(crate) scpi: Scpi,
    pub(crate) model: InstrumentModel,
    pub(crate) limits: DigitizerLimits,
    identity: Identity,
    /// Segments per acquisition and points per segment as last configured.
    segments: u32,
    points: u64,
}

impl ScopeCore {
    /// The model's `[digitizer]` limits, checked to be there before the scope is asked anything.
    pub(crate) fn limits_of(model: &InstrumentModel) -> Result<DigitizerLimits, DriverError> {
        model.digitizer.clone().ok_or_else(|| DriverError::Catalog {
            key: model.instrument.key.clone(),
            reason: "the model has no [digitizer] section; it is not a scope".into(),
        })
    }

    pub(crate) fn new(
        scpi: Scpi,
        model: &InstrumentModel,
        limits: DigitizerLimits,
        identity: Identity,
    ) -> ScopeCore {
        ScopeCore {
            scpi,
            model: model.clone(),
            limits,
            identity,
            segments: 1,
            points: 0,
        }
    }

    fn name(&self) -> &str {
        self.scpi.name()
    }

    fn out_of_limits(&self, field: &'static str, value: String, allowed: String) -> DriverError {
        DriverError::OutOfLimits {
            instrument: self.name().to_string(),
            field,
            value,
            allowed,
        }
    }

    fn catalog(&self, reason: String) -> DriverError {
        DriverError::Catalog {
            key: self.model.instrument.key.clone(),
            reason,
        }
    }

    /// Checks `s` against the catalog's limits (nothing sent); the points of one segment.
    fn validate(&self, s: &DigitizerSettings, source: &str, ch: &str) -> Result<u64, DriverError> {
        let l = &self.limits;
        let n = self.name();
        if !l
            .sample_rates
            .iter()
            .any(|r| close(*r, s.sample_rate_hz, RATE_TOLERANCE))
        {
            return Err(self.out_of_limits(
                "sample_rate_hz",
                format!("{} Sa/s", s.sample_rate_hz),
                format!("one of {:?} Sa/s", l.sample_rates),
            ));
        }
        let positive = f64::MIN_POSITIVE;
        within(n, "repetition_s", s.repetition_s, positive, f64::MAX, "s")?;
        within(n, "longest_echo_s", s.longest_echo_s, 0.0, f64::MAX, "s")?;
        within(n, "pre_trigger_s", s.pre_trigger_s, 0.0, f64::MAX, "s")?;
        let most = l.max_points_per_channel as f64;
        let points = (s.record_s() * s.sample_rate_hz).ceil();
        if points > most {
            return Err(self.out_of_limits(
                "repetition_s + longest_echo_s + pre_trigger_s",
                format!("{} s = {points} points", s.record_s()),
                format!(
                    "at most {} points per channel ({} s at {} Sa/s)",
                    l.max_points_per_channel,
                    most / s.sample_rate_hz,
                    s.sample_rate_hz
                ),
            ));
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
            return Err(self.out_of_limits("segments", s.segments.to_string(), allowed));
        }
        if points * f64::from(s.segments) > most {
            return Err(self.out_of_limits(
                "segments",
                format!("{} segments of {points} points", s.segments),
                format!(
                    "at most {} points per channel in all segments together",
                    l.max_points_per_channel
                ),
            ));
        }
        let (vdiv_min, vdiv_max) = (l.volts_per_div_min, l.volts_per_div_max);
        within(
            n,
            "i_volts_per_div",
            s.i_volts_per_div,
            vdiv_min,
            vdiv_max,
            "V/div",
        )?;
        within(
            n,
            "q_volts_per_div",
            s.q_volts_per_div,
            vdiv_min,
            vdiv_max,
            "V/div",
        )?;
        within(
            n,
            "i_offset_v",
            s.i_offset_v,
            l.offset_v_min,
            l.offset_v_max,
            "V",
        )?;
        within(
            n,
            "q_offset_v",
            s.q_offset_v,
            l.offset_v_min,
            l.offset_v_max,
            "V",
        )?;
        let (level_min, level_max) = (l.ext_trigger_level_v_min, l.ext_trigger_level_v_max);
        within(
            n,
            "trigger_level_v",
            s.trigger_level_v,
            level_min,
            level_max,
            "V",
        )?;
        if !l.trigger_sources.iter().any(|t| t == source) {
            return Err(self.catalog(format!(
                "trigger_sources lacks {source} (the input the AWG's marker drives)"
            )));
        }
        if l.channels < Q_CHANNEL {
            return Err(self.catalog(format!(
                "the driver needs two channels (I on {ch}{I_CHANNEL}, Q on {ch}{Q_CHANNEL})"
            )));
        }
        Ok(points as u64)
    }

    /// The read-back sample rate, refused unless it is the one asked for.
    pub(crate) fn check_rate(&self, wanted: f64, applied: f64) -> Result<(), DriverError> {
        if close(applied, wanted, RATE_TOLERANCE) {
            return Ok(());
        }
        Err(self.not_applied("sample rate (Sa/s)", wanted, applied))
    }

    /// The read-back segment count, refused unless it is the one asked for.
    pub(crate) fn check_segments(&self, wanted: u32, applied: f64) -> Result<(), DriverError> {
        if applied == f64::from(wanted) {
            return Ok(());
        }
        Err(self.not_applied("segments", wanted, applied))
    }

    pub(crate) fn not_applied(
        &self,
        setting: &'static str,
        wanted: impl ToString,
        applied: impl ToString,
    ) -> DriverError {
        DriverError::NotApplied {
            instrument: self.name().to_string(),
            setting,
            wanted: wanted.to_string(),
            applied: applied.to_string(),
        }
    }

    fn check_channel(&self, channel: u8, ch: &str) -> Result<(), DriverError> {
        let last = self.limits.channels;
        if (1..=last).contains(&channel) {
            return Ok(());
        }
        Err(DriverError::BadSettings {
            instrument: self.name().to_string(),
            field: "channel",
            reason: format!("{ch}{channel} does not exist; allowed {ch}1 ..= {ch}{last}"),
        })
    }

    /// I and Q, each checked to hold the configured segments: a scope short of memory for the
    /// whole sequence shortens the segments instead of refusing.
    fn check_iq(
        &self,
        i: ChannelTrace,
        q: ChannelTrace,
        ch: &str,
    ) -> Result<IqCapture, DriverError> {
        for t in [&i, &q] {
            let short = (t.segment_len() as u64).saturating_add(1) < self.points;
            if short
                || t.segment_count() != self.segments as usize
                || t.codes.len() != i.codes.len()
            {
                return Err(self.not_applied(
                    "segments of the record (I and Q)",
                    format!("{} of {} points", self.segments, self.points),
                    format!(
                        "{ch}{}: {} segments, {} points",
                        t.channel,
                        t.segment_count(),
                        t.codes.len()
                    ),
                ));
            }
        }
        Ok(IqCapture { i, q })
    }
}

/// Every scope family is a [`Digitizer`]: the core's checks around the family's commands.
impl<T: ScopeFamily> Digitizer for T {
    fn identity(&self) -> &Identity {
        &self.core().identity
    }

    fn configure<'a>(
        &'a mut self,
        settings: &'a DigitizerSettings,
    ) -> BoxFuture<'a, Result<DigitizerApplied, DriverError>> {
        Box::pin(async move {
            let points = self
                .core()
                .validate(settings, self.trigger_source(), T::CHANNEL)?;
            let applied = self.send_settings(settings, points).await?;
            let core = self.core_mut();
            core.segments = applied.segments;
            core.points = applied.points;
            Ok(applied)
        })
    }

    fn acquire(&mut self, wait_s: f64) -> BoxFuture<'_, Result<(), DriverError>> {
        Box::pin(async move {
            within(self.core().name(), "wait_s", wait_s, 0.0, MOST_WAIT_S, "s")?;
            self.arm_and_wait(wait_s).await
        })
    }

    fn fetch(&mut self, channel: u8) -> BoxFuture<'_, Result<ChannelTrace, DriverError>> {
        Box::pin(async move {
            self.core().check_channel(channel, T::CHANNEL)?;
            self.read_channel(channel).await
        })
    }

    fn capture_iq(&mut self, wait_s: f64) -> BoxFuture<'_, Result<IqCapture, DriverError>> {
        Box::pin(async move {
            Digitizer::acquire(self, wait_s).await?;
            let i = Digitizer::fetch(self, I_CHANNEL).await?;
            let q = Digitizer::fetch(self, Q_CHANNEL).await?;
            self.core().check_iq(i, q, T::CHANNEL)
        })
    }

    fn stop(&mut self) -> BoxFuture<'_, Result<(), DriverError>> {
        Box::pin(async move { self.core_mut().scpi.send(T::STOP).await })
    }

    fn reference_clock(&mut self) -> BoxFuture<'_, Result<String, DriverError>> {
        self.read_reference()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::catalog::Catalog;
    use crate::driver::scripted::Scripted;

    fn core(key: &str) -> ScopeCore {
        let model = Catalog::embedded().unwrap().get(key).unwrap().clone();
        let limits = ScopeCore::limits_of(&model).unwrap();
        let identity = Identity {
            manufacturer: String::new(),
            model: String::new(),
            serial: String::new(),
            firmware: String::new(),
        };
        let scpi = Scpi::new(Box::new(Scripted::new("scope")), "scope");
        ScopeCore::new(scpi, &model, limits, identity)
    }

    #[test]
    fn settings_are_checked_once_for_every_family_in_its_words() {
        let mut lecroy = core("lecroy-labmaster10zi-a");
        let ok = DigitizerSettings::default();
        let points = lecroy.validate(&ok, "EX", "C").unwrap();
        assert_eq!(points, (ok.record_s() * ok.sample_rate_hz).ceil() as u64);
        let e = lecroy.validate(&ok, "AUX9", "C").unwrap_err().to_string();
        assert!(e.contains("trigger_sources lacks AUX9"), "{e}");
        lecroy.limits.max_sequence_segments = 0;
        let two = DigitizerSettings { segments: 2, ..ok };
        let e = lecroy.validate(&two, "EX", "C").unwrap_err().to_string();
        assert!(e.contains("no sequence mode"), "{e}");
        let e = lecroy.check_channel(9, "C").unwrap_err().to_string();
        assert!(
            e.contains("C9 does not exist") && e.contains("C1 ..= C"),
            "{e}"
        );
        let uxr = core("keysight-uxr0334a");
        let e = uxr.check_channel(0, "channel ").unwrap_err().to_string();
        assert!(e.contains("channel 0 does not exist"), "{e}");
    }
}
