//! Keysight M8195A driver: I on channel 1 with the marker byte interleaved, Q on channel 2, the
//! marker on channels 3 and 4 (DAC mode DCMarker), extended memory with the raster divided to the
//! requested rate (16 GSa/s = 64 GSa/s / 4), segments padded to the granularity and downloaded in
//! chunks, the error queue checked after every configuration batch.
//!
//! Every value is checked against the catalog before anything is sent ([`DriverError::Limit`]).

pub mod commands;

use crate::catalog::{AwgLimits, DividerLimits, InstrumentModel};
use crate::session::{BlockForm, Identity, Session};

use super::{identity_matches, Awg, AwgApplied, AwgSetup, DriverError, IqWaveform};

const NAME: &str = "M8195A";
/// The DAC mode this driver uses: channels 1 and 2 carry I and Q, 3 and 4 channel 1's markers.
pub const DAC_MODE: &str = "DCM";
const I_CHANNEL: u8 = 1;
const Q_CHANNEL: u8 = 2;
const SEGMENT: u32 = 1;
/// Marker byte for a high marker: bit0 drives channel 3, bit1 channel 4; both pulse together.
const MARKER_HIGH: u8 = 0b11;

/// A connected M8195A.
pub struct M8195a {
    session: Session,
    limits: AwgLimits,
    key: String,
    identity: Identity,
    /// The divider the driver last configured.
    divider: Option<u32>,
}

fn limit(parameter: &'static str, value: impl ToString, allowed: impl Into<String>) -> DriverError {
    DriverError::Limit {
        instrument: NAME,
        parameter,
        value: value.to_string(),
        allowed: allowed.into(),
    }
}

impl M8195a {
    /// Checks `*IDN?` against the catalog entry and returns the driver.
    pub async fn connect(
        mut session: Session,
        model: &InstrumentModel,
    ) -> Result<Self, DriverError> {
        let limits = model.awg.clone().ok_or_else(|| DriverError::Catalog {
            instrument: NAME,
            key: model.instrument.key.clone(),
            what: "[awg] section",
        })?;
        if limits.dac_mode(DAC_MODE).is_none() {
            return Err(DriverError::Catalog {
                instrument: NAME,
                key: model.instrument.key.clone(),
                what: "DCM entry in [[awg.dac_mode]]",
            });
        }
        let identity = session.idn().await?;
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
        Ok(M8195a {
            session,
            limits,
            key: model.instrument.key.clone(),
            identity,
            divider: None,
        })
    }

    pub fn identity(&self) -> &Identity {
        &self.identity
    }

    pub fn catalog_key(&self) -> &str {
        &self.key
    }

    /// The session, for commands this driver does not wrap.
    pub fn session(&mut self) -> &mut Session {
        &mut self.session
    }

    pub fn into_session(self) -> Session {
        self.session
    }

    /// The divider and DAC raster that give `rate` from extended memory in DCM mode: the smallest
    /// allowed divider whose raster `rate x divider` lies in the catalog's DAC range.
    pub fn plan_rate(&self, rate: f64) -> Result<(&DividerLimits, f64), DriverError> {
        let l = &self.limits;
        let mode = l.dac_mode(DAC_MODE).ok_or_else(|| DriverError::Catalog {
            instrument: NAME,
            key: self.key.clone(),
            what: "DCM entry in [[awg.dac_mode]]",
        })?;
        let mut dividers: Vec<&DividerLimits> = l
            .dividers
            .iter()
            .filter(|d| mode.dividers.contains(&d.divider))
            .collect();
        dividers.sort_by_key(|d| d.divider);
        let allowed = dividers
            .iter()
            .map(|d| {
                format!(
                    "{:.4e}..={:.4e}",
                    l.dac_rate_min / f64::from(d.divider),
                    l.dac_rate_max / f64::from(d.divider)
                )
            })
            .collect::<Vec<_>>()
            .join(" or ");
        if !(rate.is_finite() && rate > 0.0) {
            return Err(limit("sample_rate", rate, format!("Sa/s in {allowed}")));
        }
        dividers
            .into_iter()
            .map(|d| (d, rate * f64::from(d.divider)))
            .find(|(_, raster)| *raster >= l.dac_rate_min && *raster <= l.dac_rate_max)
            .ok_or_else(|| limit("sample_rate", rate, format!("Sa/s in {allowed}")))
    }

    /// Segment length for `samples`: rounded up to the granularity, at least the minimum length.
    pub fn padded_length(divider: &DividerLimits, samples: u64) -> u64 {
        samples
            .div_ceil(divider.granularity)
            .saturating_mul(divider.granularity)
            .max(divider.min_segment_samples)
    }

    fn check_setup(&self, setup: &AwgSetup) -> Result<(), DriverError> {
        let l = &self.limits;
        if !(setup.amplitude_vpp >= l.amplitude_vpp_min
            && setup.amplitude_vpp <= l.amplitude_vpp_max)
        {
            return Err(limit(
                "amplitude_vpp",
                setup.amplitude_vpp,
                format!("{} ..= {} Vpp", l.amplitude_vpp_min, l.amplitude_vpp_max),
            ));
        }
        let swing = setup.marker_high_v - setup.marker_low_v;
        if !(swing >= l.marker_amplitude_v_min && swing <= l.marker_amplitude_v_max) {
            return Err(limit(
                "marker_high_v - marker_low_v",
                swing,
                format!(
                    "{} ..= {} V",
                    l.marker_amplitude_v_min, l.marker_amplitude_v_max
                ),
            ));
        }
        let offset = (setup.marker_high_v + setup.marker_low_v) / 2.0;
        if !(offset >= l.marker_offset_v_min && offset <= l.marker_offset_v_max) {
            return Err(limit(
                "marker offset (high + low) / 2",
                offset,
                format!("{} ..= {} V", l.marker_offset_v_min, l.marker_offset_v_max),
            ));
        }
        Ok(())
    }

    async fn send_all(&mut self, batch: &[String], what: &str) -> Result<(), DriverError> {
        for command in batch {
            self.session.write(command).await?;
        }
        self.session.check_errors(Some(what)).await?;
        Ok(())
    }

    async fn current_divider(&mut self) -> Result<&DividerLimits, DriverError> {
        let divider = match self.divider {
            Some(d) => d,
            None => {
                let text = self.session.query(commands::DIVIDER_QUERY).await?;
                parse_divider(&text).ok_or_else(|| DriverError::BadReply {
                    instrument: NAME,
                    request: commands::DIVIDER_QUERY.into(),
                    expected: "DIV1, DIV2 or DIV4",
                    reply: text.clone(),
                })?
            }
        };
        self.limits
            .divider(divider)
            .ok_or_else(|| limit("divider", divider, "a divider of the catalog"))
    }

    fn check_waveform(
        &self,
        waveform: &IqWaveform,
        divider: &DividerLimits,
    ) -> Result<u64, DriverError> {
        let n = waveform.i.len();
        if n == 0 {
            return Err(limit("waveform length", 0, "at least 1 sample"));
        }
        if waveform.q.len() != n || waveform.marker.len() != n {
            return Err(limit(
                "waveform lengths (i, q, marker)",
                format!("({n}, {}, {})", waveform.q.len(), waveform.marker.len()),
                "three equal lengths",
            ));
        }
        let padded = Self::padded_length(divider, n as u64);
        if padded > self.limits.extended_memory_samples {
            return Err(limit(
                "waveform length",
                n,
                format!("at most {} samples", self.limits.extended_memory_samples),
            ));
        }
        Ok(padded)
    }
}

fn parse_divider(text: &str) -> Option<u32> {
    text.trim()
        .trim_matches('"')
        .to_ascii_uppercase()
        .strip_prefix("DIV")?
        .parse()
        .ok()
}

impl Awg for M8195a {
    async fn configure(&mut self, setup: &AwgSetup) -> Result<AwgApplied, DriverError> {
        self.check_setup(setup)?;
        let (divider, raster) = self.plan_rate(setup.sample_rate)?;
        let (divider_value, divider_keyword) = (divider.divider, divider.keyword.clone());
        let marker_amplitude = setup.marker_high_v - setup.marker_low_v;
        let marker_offset = (setup.marker_high_v + setup.marker_low_v) / 2.0;
        let batch = vec![
            commands::ABORT.to_string(),
            commands::dac_mode(DAC_MODE),
            commands::divider(&divider_keyword),
            commands::memory_extended(I_CHANNEL),
            commands::memory_extended(Q_CHANNEL),
            commands::raster(raster),
            commands::FUNCTION_ARB.to_string(),
            commands::CONTINUOUS_ON.to_string(),
            commands::GATE_OFF.to_string(),
            commands::amplitude(I_CHANNEL, setup.amplitude_vpp),
            commands::amplitude(Q_CHANNEL, setup.amplitude_vpp),
            commands::marker_amplitude(3, marker_amplitude),
            commands::marker_offset(3, marker_offset),
            commands::marker_amplitude(4, marker_amplitude),
            commands::marker_offset(4, marker_offset),
        ];
        self.send_all(&batch, "configure").await?;
        self.divider = Some(divider_value);
        self.applied().await
    }

    async fn load(&mut self, waveform: &IqWaveform) -> Result<u64, DriverError> {
        let divider = self.current_divider().await?.clone();
        let padded = self.check_waveform(waveform, &divider)?;
        let n = padded as usize;
        let mut i_marker = Vec::with_capacity(2 * n);
        for k in 0..n {
            let sample = waveform.i.get(k).copied().unwrap_or(0);
            let marker = waveform.marker.get(k).copied().unwrap_or(false);
            i_marker.push(sample as u8);
            i_marker.push(if marker { MARKER_HIGH } else { 0 });
        }
        let mut q = Vec::with_capacity(n);
        q.extend(waveform.q.iter().map(|s| *s as u8));
        q.resize(n, 0);

        let setup = [
            commands::ABORT.to_string(),
            commands::delete_all(I_CHANNEL),
            commands::define(I_CHANNEL, SEGMENT, padded),
        ];
        self.send_all(&setup, "segment definition").await?;
        let chunk = (self.limits.download_chunk_samples as usize).max(divider.granularity as usize);
        let mut offset = 0usize;
        while offset < n {
            let end = (offset + chunk).min(n);
            let header = commands::data_header(I_CHANNEL, SEGMENT, offset as u64);
            self.session
                .write_block(&header, &i_marker[2 * offset..2 * end], BlockForm::Definite)
                .await?;
            let header = commands::data_header(Q_CHANNEL, SEGMENT, offset as u64);
            self.session
                .write_block(&header, &q[offset..end], BlockForm::Definite)
                .await?;
            offset = end;
        }
        self.session.opc().await?;
        let select = [
            commands::select(I_CHANNEL, SEGMENT),
            commands::select(Q_CHANNEL, SEGMENT),
        ];
        self.send_all(&select, "waveform download").await?;
        Ok(padded)
    }

    async fn set_outputs(&mut self, on: bool) -> Result<(), DriverError> {
        let batch: Vec<String> = (1..=4).map(|ch| commands::output(ch, on)).collect();
        self.send_all(&batch, if on { "outputs on" } else { "outputs off" })
            .await
    }

    async fn run(&mut self) -> Result<(), DriverError> {
        self.send_all(&[commands::RUN.to_string()], commands::RUN)
            .await
    }

    async fn stop(&mut self) -> Result<(), DriverError> {
        self.send_all(&[commands::ABORT.to_string()], commands::ABORT)
            .await
    }

    async fn applied(&mut self) -> Result<AwgApplied, DriverError> {
        let dac_mode = self.session.query_string(commands::DAC_MODE_QUERY).await?;
        let divider_text = self.session.query(commands::DIVIDER_QUERY).await?;
        let divider = parse_divider(&divider_text).ok_or_else(|| DriverError::BadReply {
            instrument: NAME,
            request: commands::DIVIDER_QUERY.into(),
            expected: "DIV1, DIV2 or DIV4",
            reply: divider_text.clone(),
        })?;
        let dac_rate = self.session.query_f64(commands::RASTER_QUERY).await?;
        let catalog = self
            .session
            .query(&commands::catalog_query(I_CHANNEL))
            .await?;
        let segment_samples = catalog
            .split(',')
            .nth(1)
            .and_then(|s| s.trim().parse::<u64>().ok())
            .ok_or_else(|| DriverError::BadReply {
                instrument: NAME,
                request: commands::catalog_query(I_CHANNEL),
                expected: "<id>,<length>[,...]",
                reply: catalog.clone(),
            })?;
        let mut amplitude_vpp = [0.0; 2];
        for (slot, ch) in amplitude_vpp.iter_mut().zip([I_CHANNEL, Q_CHANNEL]) {
            *slot = self
                .session
                .query_f64(&commands::amplitude_query(ch))
                .await?;
        }
        let mut outputs = [false; 4];
        for (slot, ch) in outputs.iter_mut().zip(1u8..) {
            *slot = self.session.query_bool(&commands::output_query(ch)).await?;
        }
        Ok(AwgApplied {
            dac_mode,
            divider,
            dac_rate,
            sample_rate: dac_rate / f64::from(divider.max(1)),
            segment_samples,
            amplitude_vpp,
            outputs,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn padding_follows_granularity_and_minimum() {
        let d = DividerLimits {
            divider: 4,
            keyword: "DIV4".into(),
            granularity: 64,
            min_segment_samples: 320,
        };
        assert_eq!(M8195a::padded_length(&d, 1), 320);
        assert_eq!(M8195a::padded_length(&d, 320), 320);
        assert_eq!(M8195a::padded_length(&d, 321), 384);
        assert_eq!(M8195a::padded_length(&d, 160_000), 160_000);
    }

    #[test]
    fn divider_replies() {
        assert_eq!(parse_divider("DIV4"), Some(4));
        assert_eq!(parse_divider("div2\n"), Some(2));
        assert_eq!(parse_divider("4"), None);
    }

    #[test]
    fn raster_is_written_in_full_precision() {
        assert_eq!(commands::raster(64e9), ":FREQ:RAST 6.4E10");
        assert_eq!(commands::raster(53.76e9), ":FREQ:RAST 5.376E10");
    }
}
