//! Pure planning for the M8195A: settings checked against the catalog, the clock (raster and
//! divider) chosen, the segment padded and cut into chunks, channel 1's bytes interleaved with the
//! marker. Nothing here talks to the instrument, so every check runs before anything is sent.

use crate::catalog::{AwgLimits, DacMode, DividerLimits};
use crate::driver::capability::{AwgSettings, IqWaveform};
use crate::driver::error::DriverError;
use crate::driver::limits::within;

/// The DAC mode the driver uses: I and Q on two channels, channel 1's marker bits on a third.
pub(crate) const DAC_MODE: &str = "DCM";
/// The segment the driver defines (one continuously looped segment).
pub(crate) const SEGMENT_ID: u32 = 1;
/// Marker byte bit that drives the first marker channel (M1 = bit0 -> channel 3 in DCM).
pub(crate) const MARKER_BIT: u8 = 0x01;

/// External reference input range of the M8195A, Hz [V-src: instruments.md section 1.4, "ext ref
/// 10-300 MHz"]. Kept here until the catalog schema has a field for it.
pub(crate) const EXTERNAL_REFERENCE_HZ: (f64, f64) = (10e6, 300e6);

/// Channels and clock for a given sample rate.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct ClockPlan {
    pub dac_mode: String,
    pub divider: DividerLimits,
    pub dac_rate_hz: f64,
    pub sample_rate_hz: f64,
    pub i_channel: u8,
    pub q_channel: u8,
    pub marker_channel: u8,
}

fn catalog_error(key: &str, reason: String) -> DriverError {
    DriverError::Catalog {
        key: key.to_string(),
        reason,
    }
}

/// The DAC mode with I/Q and a marker, from the catalog.
pub(crate) fn iq_marker_mode<'a>(
    limits: &'a AwgLimits,
    key: &str,
) -> Result<&'a DacMode, DriverError> {
    let mode = limits.dac_mode(DAC_MODE).ok_or_else(|| {
        catalog_error(
            key,
            format!("the driver needs DAC mode {DAC_MODE} (I/Q with markers); add it under [[awg.dac_mode]]"),
        )
    })?;
    if mode.signal_channels.len() < 2 || mode.marker_channels.is_empty() {
        return Err(catalog_error(
            key,
            format!(
                "DAC mode {DAC_MODE} must list two signal channels and at least one marker channel"
            ),
        ));
    }
    Ok(mode)
}

/// Checks every level against the catalog and picks the divider and raster for the sample rate.
pub(crate) fn plan_clock(
    limits: &AwgLimits,
    key: &str,
    instrument: &str,
    settings: &AwgSettings,
) -> Result<ClockPlan, DriverError> {
    let mode = iq_marker_mode(limits, key)?;
    let rate = settings.sample_rate_hz;
    let candidates: Vec<&DividerLimits> = limits
        .dividers
        .iter()
        .filter(|d| mode.dividers.contains(&d.divider))
        .collect();
    let chosen = candidates.iter().find(|d| {
        let dac = rate * f64::from(d.divider);
        rate.is_finite() && dac >= limits.dac_rate_min && dac <= limits.dac_rate_max
    });
    let Some(divider) = chosen else {
        let allowed = candidates
            .iter()
            .map(|d| {
                let div = f64::from(d.divider);
                format!(
                    "{} ..= {} Sa/s ({})",
                    limits.dac_rate_min / div,
                    limits.dac_rate_max / div,
                    d.keyword
                )
            })
            .collect::<Vec<_>>()
            .join(", or ");
        return Err(DriverError::OutOfLimits {
            instrument: instrument.to_string(),
            field: "sample_rate_hz",
            value: format!("{rate} Sa/s"),
            allowed,
        });
    };
    let levels = [
        (
            "i_amplitude_vpp",
            settings.i_amplitude_vpp,
            limits.amplitude_vpp_min,
            limits.amplitude_vpp_max,
            "Vpp",
        ),
        (
            "q_amplitude_vpp",
            settings.q_amplitude_vpp,
            limits.amplitude_vpp_min,
            limits.amplitude_vpp_max,
            "Vpp",
        ),
        (
            "i_offset_v",
            settings.i_offset_v,
            limits.offset_v_min,
            limits.offset_v_max,
            "V",
        ),
        (
            "q_offset_v",
            settings.q_offset_v,
            limits.offset_v_min,
            limits.offset_v_max,
            "V",
        ),
        (
            "marker_amplitude_v",
            settings.marker_amplitude_v,
            limits.marker_amplitude_v_min,
            limits.marker_amplitude_v_max,
            "V",
        ),
        (
            "marker_offset_v",
            settings.marker_offset_v,
            limits.marker_offset_v_min,
            limits.marker_offset_v_max,
            "V",
        ),
    ];
    for (field, value, min, max, unit) in levels {
        within(instrument, field, value, min, max, unit)?;
    }
    if let crate::driver::capability::ReferenceClock::External { frequency_hz } =
        settings.reference_clock
    {
        within(
            instrument,
            "reference_clock.frequency_hz",
            frequency_hz,
            EXTERNAL_REFERENCE_HZ.0,
            EXTERNAL_REFERENCE_HZ.1,
            "Hz",
        )?;
    }
    Ok(ClockPlan {
        dac_mode: mode.keyword.clone(),
        divider: (*divider).clone(),
        dac_rate_hz: rate * f64::from(divider.divider),
        sample_rate_hz: rate,
        i_channel: mode.signal_channels[0],
        q_channel: mode.signal_channels[1],
        marker_channel: mode.marker_channels[0],
    })
}

/// How a waveform goes into memory.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) struct DownloadPlan {
    pub samples: u64,
    /// Length after zero padding to the granularity and the minimum segment length.
    pub padded: u64,
    /// Samples per `:TRAC:DATA` chunk (a multiple of the granularity).
    pub chunk: u64,
    pub marker_high: u64,
}

impl DownloadPlan {
    /// `(offset, length)` of each chunk, in samples, ascending.
    pub(crate) fn chunks(&self) -> Vec<(u64, u64)> {
        let mut out = Vec::new();
        let mut offset = 0;
        while offset < self.padded {
            let len = self.chunk.min(self.padded - offset);
            out.push((offset, len));
            offset += len;
        }
        out
    }
}

/// Checks the waveform against the catalog and plans padding and chunks.
pub(crate) fn plan_download(
    limits: &AwgLimits,
    clock: &ClockPlan,
    instrument: &str,
    waveform: &IqWaveform,
) -> Result<DownloadPlan, DriverError> {
    let bad = |field: &'static str, reason: String| DriverError::BadSettings {
        instrument: instrument.to_string(),
        field,
        reason,
    };
    if waveform.i.is_empty() {
        return Err(bad("waveform.i", "the waveform is empty".into()));
    }
    if waveform.i.len() != waveform.q.len() {
        return Err(bad(
            "waveform.q",
            format!(
                "I has {} samples and Q {}; both channels play one segment and need the same length",
                waveform.i.len(),
                waveform.q.len()
            ),
        ));
    }
    let (lo, hi) = (limits.sample_min, limits.sample_max);
    for (field, data) in [("waveform.i", &waveform.i), ("waveform.q", &waveform.q)] {
        if let Some((n, v)) = data
            .iter()
            .enumerate()
            .find(|(_, v)| i32::from(**v) < lo || i32::from(**v) > hi)
        {
            return Err(DriverError::OutOfLimits {
                instrument: instrument.to_string(),
                field,
                value: format!("{v} at sample {n}"),
                allowed: format!("DAC codes {lo} ..= {hi}"),
            });
        }
    }
    let d = &clock.divider;
    let granularity = d.granularity.max(1);
    let samples = waveform.i.len() as u64;
    let padded = samples
        .max(d.min_segment_samples)
        .div_ceil(granularity)
        .saturating_mul(granularity);
    if padded > limits.extended_memory_samples {
        return Err(DriverError::OutOfLimits {
            instrument: instrument.to_string(),
            field: "waveform.i",
            value: format!("{samples} samples ({padded} padded)"),
            allowed: format!(
                "at most {} samples of extended memory",
                limits.extended_memory_samples
            ),
        });
    }
    let spacing = u64::from(limits.marker_min_edge_spacing_dac_samples);
    let div = u64::from(d.divider);
    let high = waveform.marker_high_samples as u64;
    let min_high = spacing.div_ceil(div);
    if high < min_high || padded.saturating_sub(high) < min_high {
        return Err(DriverError::OutOfLimits {
            instrument: instrument.to_string(),
            field: "waveform.marker_high_samples",
            value: high.to_string(),
            allowed: format!(
                "{min_high} ..= {} samples (marker edges at least {spacing} DAC samples apart at {})",
                padded.saturating_sub(min_high),
                d.keyword
            ),
        });
    }
    let chunk = (limits.download_chunk_samples / granularity).max(1) * granularity;
    Ok(DownloadPlan {
        samples,
        padded,
        chunk,
        marker_high: high,
    })
}

/// Channel 1's bytes for `offset..offset+len`: `[sample, marker]` pairs, zero past the waveform.
pub(crate) fn interleaved_chunk(i: &[i8], marker_high: u64, offset: u64, len: u64) -> Vec<u8> {
    let mut out = Vec::with_capacity(2 * len as usize);
    for n in offset..offset + len {
        let sample = i.get(n as usize).copied().unwrap_or(0);
        let marker = if n < marker_high { MARKER_BIT } else { 0 };
        out.push(sample as u8);
        out.push(marker);
    }
    out
}

/// A plain channel's bytes for `offset..offset+len`, zero past the waveform.
pub(crate) fn plain_chunk(q: &[i8], offset: u64, len: u64) -> Vec<u8> {
    (offset..offset + len)
        .map(|n| q.get(n as usize).copied().unwrap_or(0) as u8)
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::catalog::Catalog;

    fn limits() -> AwgLimits {
        Catalog::embedded()
            .unwrap()
            .get("keysight-m8195a")
            .unwrap()
            .awg
            .clone()
            .unwrap()
    }

    #[test]
    fn sixteen_gigasamples_is_64_gsa_divided_by_four() {
        let plan = plan_clock(&limits(), "k", "awg", &AwgSettings::default()).unwrap();
        assert_eq!(plan.divider.keyword, "DIV4");
        assert_eq!(plan.dac_rate_hz, 64e9);
        assert_eq!(
            (plan.i_channel, plan.q_channel, plan.marker_channel),
            (1, 2, 3)
        );
    }

    #[test]
    fn unreachable_rates_list_every_allowed_range() {
        let settings = AwgSettings {
            sample_rate_hz: 20e9,
            ..AwgSettings::default()
        };
        let e = plan_clock(&limits(), "k", "awg", &settings).unwrap_err();
        let text = e.to_string();
        assert!(
            text.contains("sample_rate_hz") && text.contains("DIV4") && text.contains("DIV1"),
            "{text}"
        );
    }

    #[test]
    fn segments_are_padded_to_granularity_and_minimum() {
        let l = limits();
        let clock = plan_clock(&l, "k", "awg", &AwgSettings::default()).unwrap();
        let wf = |n: usize| IqWaveform {
            i: vec![1; n],
            q: vec![2; n],
            marker_high_samples: 32,
        };
        assert_eq!(
            plan_download(&l, &clock, "awg", &wf(100)).unwrap().padded,
            320
        );
        assert_eq!(
            plan_download(&l, &clock, "awg", &wf(1000)).unwrap().padded,
            1024
        );
        assert_eq!(
            plan_download(&l, &clock, "awg", &wf(1024)).unwrap().padded,
            1024
        );
        let big = plan_download(&l, &clock, "awg", &wf(1_100_000)).unwrap();
        assert_eq!(
            big.chunks(),
            vec![(0, 512_000), (512_000, 512_000), (1_024_000, 76_032)]
        );
        assert!(big.chunks().iter().all(|(o, _)| o % 64 == 0));
    }

    #[test]
    fn marker_pulse_must_respect_the_edge_spacing() {
        let l = limits();
        let clock = plan_clock(&l, "k", "awg", &AwgSettings::default()).unwrap();
        let wf = IqWaveform {
            i: vec![0; 1024],
            q: vec![0; 1024],
            marker_high_samples: 8,
        };
        let e = plan_download(&l, &clock, "awg", &wf).unwrap_err();
        assert!(e.to_string().contains("marker_high_samples"), "{e}");
        let mismatch = IqWaveform {
            i: vec![0; 1024],
            q: vec![0; 1000],
            marker_high_samples: 64,
        };
        assert!(plan_download(&l, &clock, "awg", &mismatch).is_err());
    }

    #[test]
    fn channel_one_interleaves_sample_and_marker() {
        let bytes = interleaved_chunk(&[-1, 2, 3], 2, 0, 4);
        assert_eq!(bytes, vec![0xFF, 1, 2, 1, 3, 0, 0, 0]);
        assert_eq!(plain_chunk(&[-128, 127], 1, 3), vec![127, 0, 0]);
    }
}
