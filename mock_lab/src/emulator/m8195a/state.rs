//! The M8195A's settings, waveform memory and the rules the real instrument enforces.
//!
//! Everything here is plain data plus checks; limits come from the catalog ([`AwgModel`]). Errors are
//! SCPI errors with the standard code and a detail that says what was wrong and what is allowed.

use std::collections::BTreeMap;
use std::sync::Arc;

use crate::catalog::{AwgModel, DacMode};
use crate::emulator::scpi::error_queue::ScpiError;

/// Largest segment the emulator stores (it keeps samples in RAM): 64 Mi samples per channel.
pub(crate) const EMULATOR_MAX_SEGMENT_SAMPLES: u64 = 64 * 1024 * 1024;

/// Where a channel plays from.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Memory {
    Internal,
    Extended,
}

impl Memory {
    pub fn keyword(self) -> &'static str {
        match self {
            Memory::Internal => "INT",
            Memory::Extended => "EXT",
        }
    }
}

/// One waveform segment of one channel.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Segment {
    /// Samples (int8 DAC codes).
    pub samples: Vec<i8>,
    /// Marker bytes, one per sample (bit0 -> first marker channel, bit1 -> second); only on
    /// channel 1 in DAC modes with markers, empty otherwise.
    pub markers: Vec<u8>,
}

/// Settings and memory of one channel.
#[derive(Debug, Clone, PartialEq)]
pub struct Channel {
    pub memory: Memory,
    pub segments: BTreeMap<u32, Segment>,
    pub selected: u32,
    pub amplitude_vpp: f64,
    pub offset_v: f64,
    pub output: bool,
}

/// What one channel outputs, for the scene physics.
#[derive(Debug, Clone, PartialEq)]
pub struct ChannelPlayback {
    pub number: u8,
    pub output_on: bool,
    /// Peak-to-peak amplitude (signal channels) or marker high-low (marker channels), in volts.
    pub amplitude_vpp: f64,
    pub offset_v: f64,
    pub memory: Memory,
    /// Samples per second this channel's memory is read at.
    pub sample_rate: f64,
    /// The selected segment's samples (empty for marker channels and channels without a waveform).
    pub samples: Arc<[i8]>,
}

/// What the AWG plays right now.
#[derive(Debug, Clone, PartialEq)]
pub struct Playback {
    /// `:INIT:IMM` was accepted and no `:ABOR` (or `*RST`) followed.
    pub running: bool,
    /// Continuous (`:INIT:CONT 1`) rather than triggered play.
    pub continuous: bool,
    /// DAC mode keyword as the query returns it (e.g. `DCM`).
    pub dac_mode: String,
    pub divider: u32,
    /// DAC raster in Sa/s.
    pub dac_rate: f64,
    /// Channels 1..=4 in order.
    pub channels: Vec<ChannelPlayback>,
    /// Channel 1's marker bytes (one per sample of channel 1) in modes with markers.
    pub markers: Arc<[u8]>,
    /// The channels carrying marker bit 0 and bit 1 in this DAC mode.
    pub marker_channels: Vec<u8>,
    /// Increases on every change of anything above, so consumers can cache.
    pub generation: u64,
}

impl Playback {
    /// The channel with number `n` (1-based).
    pub fn channel(&self, n: u8) -> Option<&ChannelPlayback> {
        self.channels.iter().find(|c| c.number == n)
    }

    /// Whether a marker pulse appears on a live output: running, a marker channel switched on, and
    /// at least one marker bit set in the data.
    pub fn marker_active(&self) -> bool {
        self.running
            && self.marker_channels.iter().enumerate().any(|(bit, ch)| {
                self.channel(*ch).is_some_and(|c| c.output_on)
                    && self.markers.iter().any(|m| m & (1 << bit) != 0)
            })
    }
}

/// The whole instrument state.
#[derive(Debug, Clone)]
pub struct AwgState {
    pub dac_mode: String,
    pub divider: u32,
    pub raster: f64,
    pub function_mode: &'static str,
    pub continuous: bool,
    pub gate: bool,
    pub running: bool,
    pub channels: Vec<Channel>,
    pub ref_source: &'static str,
    pub ref_frequency: f64,
    pub generation: u64,
}

fn conflict(detail: impl AsRef<str>) -> ScpiError {
    ScpiError::new(-221, detail)
}

fn out_of_range(detail: impl AsRef<str>) -> ScpiError {
    ScpiError::new(-222, detail)
}

impl AwgState {
    /// The power-on / `*RST` state \[I\]: SINGLE mode, DIV1, raster at the catalog default, internal
    /// memory, default amplitude, outputs off, stopped, continuous ARB mode.
    pub fn reset(model: &AwgModel) -> AwgState {
        let l = &model.limits;
        let first_mode = l
            .dac_modes
            .first()
            .map(|m| m.keyword.clone())
            .unwrap_or_default();
        let first_divider = l.dividers.first().map(|d| d.divider).unwrap_or(1);
        let mut state = AwgState {
            dac_mode: first_mode,
            divider: first_divider,
            raster: l.dac_rate_default,
            function_mode: "ARB",
            continuous: true,
            gate: false,
            running: false,
            channels: (1..=l.channels)
                .map(|_| Channel {
                    memory: Memory::Internal,
                    segments: BTreeMap::new(),
                    selected: 1,
                    amplitude_vpp: l.amplitude_vpp_default,
                    offset_v: 0.0,
                    output: false,
                })
                .collect(),
            ref_source: "INT",
            ref_frequency: 100e6,
            generation: 0,
        };
        state.force_extended_channels(model);
        state
    }

    pub fn mode<'m>(&self, model: &'m AwgModel) -> Option<&'m DacMode> {
        model
            .limits
            .dac_modes
            .iter()
            .find(|m| m.keyword == self.dac_mode)
    }

    fn touch(&mut self) {
        self.generation += 1;
    }

    fn channel_mut(&mut self, ch: u8) -> &mut Channel {
        &mut self.channels[usize::from(ch - 1)]
    }

    pub fn channel(&self, ch: u8) -> &Channel {
        &self.channels[usize::from(ch - 1)]
    }

    fn force_extended_channels(&mut self, model: &AwgModel) {
        let forced = self
            .mode(model)
            .map(|m| m.extended_only_channels.clone())
            .unwrap_or_default();
        for ch in forced {
            if usize::from(ch) <= self.channels.len() {
                self.channel_mut(ch).memory = Memory::Extended;
            }
        }
    }

    fn refuse_while_running(&self, what: &str) -> Result<(), ScpiError> {
        if self.running {
            Err(conflict(format!(
                "{what} is not allowed while the output runs; send :ABOR first"
            )))
        } else {
            Ok(())
        }
    }

    fn is_signal(&self, model: &AwgModel, ch: u8) -> bool {
        self.mode(model)
            .is_some_and(|m| m.signal_channels.contains(&ch))
    }

    fn is_marker(&self, model: &AwgModel, ch: u8) -> bool {
        self.mode(model)
            .is_some_and(|m| m.marker_channels.contains(&ch))
    }

    fn interleaved(&self, model: &AwgModel, ch: u8) -> bool {
        ch == 1
            && self
                .mode(model)
                .is_some_and(|m| !m.marker_channels.is_empty())
    }

    fn require_signal(&self, model: &AwgModel, ch: u8) -> Result<(), ScpiError> {
        if self.is_signal(model, ch) {
            Ok(())
        } else {
            Err(conflict(format!(
                "channel {ch} carries no waveform in DAC mode {}",
                self.dac_mode
            )))
        }
    }

    /// `(granularity, minimum length, capacity)` for a channel's current memory.
    fn segment_rules(&self, model: &AwgModel, ch: u8) -> (u64, u64, u64) {
        let l = &model.limits;
        let div = match self.channel(ch).memory {
            Memory::Extended => self.divider,
            Memory::Internal => 1,
        };
        let (granularity, min) = l
            .divider(div)
            .map(|d| (d.granularity, d.min_segment_samples))
            .unwrap_or((1, 1));
        let capacity = match self.channel(ch).memory {
            Memory::Extended => l.extended_memory_samples,
            Memory::Internal => l.internal_memory_samples,
        };
        (granularity, min, capacity)
    }

    /// The channels a segment command on `ch` applies to: all extended signal channels when `ch` is
    /// on extended memory (segments are defined on all of them at once), else just `ch`.
    fn segment_channels(&self, model: &AwgModel, ch: u8) -> Vec<u8> {
        if self.channel(ch).memory == Memory::Extended {
            self.mode(model)
                .map(|m| m.signal_channels.clone())
                .unwrap_or_default()
                .into_iter()
                .filter(|c| self.channel(*c).memory == Memory::Extended)
                .collect()
        } else {
            vec![ch]
        }
    }

    pub(crate) fn set_dac_mode(
        &mut self,
        model: &AwgModel,
        keyword: &str,
    ) -> Result<(), ScpiError> {
        self.refuse_while_running("changing the DAC mode")?;
        if keyword != self.dac_mode {
            // Channel roles and channel 1's data format change: the memory is cleared \[I\].
            self.dac_mode = keyword.to_string();
            for c in &mut self.channels {
                c.segments.clear();
                c.output = false;
            }
            self.force_extended_channels(model);
            self.touch();
        }
        Ok(())
    }

    pub(crate) fn set_divider(&mut self, divider: u32) -> Result<(), ScpiError> {
        self.refuse_while_running("changing the sample rate divider")?;
        if divider != self.divider {
            // Granularity changes with the divider: extended segments are cleared \[I\].
            self.divider = divider;
            for c in &mut self.channels {
                if c.memory == Memory::Extended {
                    c.segments.clear();
                }
            }
            self.touch();
        }
        Ok(())
    }

    pub(crate) fn set_memory(
        &mut self,
        model: &AwgModel,
        ch: u8,
        memory: Memory,
    ) -> Result<(), ScpiError> {
        self.refuse_while_running("changing the memory mode")?;
        let forced = self
            .mode(model)
            .is_some_and(|m| m.extended_only_channels.contains(&ch));
        if forced && memory == Memory::Internal {
            return Err(conflict(format!(
                "channel {ch} always plays from extended memory in DAC mode {}",
                self.dac_mode
            )));
        }
        if self.channel(ch).memory != memory {
            let c = self.channel_mut(ch);
            c.memory = memory;
            c.segments.clear();
            self.touch();
        }
        Ok(())
    }

    pub(crate) fn set_raster(&mut self, rate: f64) {
        if rate != self.raster {
            self.raster = rate;
            self.touch();
        }
    }

    pub fn define(
        &mut self,
        model: &AwgModel,
        ch: u8,
        id: u64,
        length: u64,
        fill: Option<i8>,
    ) -> Result<(), ScpiError> {
        self.require_signal(model, ch)?;
        self.refuse_while_running("defining a segment")?;
        let max_id = model.limits.max_segment_id;
        if id == 0 || id > u64::from(max_id) {
            return Err(out_of_range(format!(
                "segment id {id} is outside 1..={max_id}"
            )));
        }
        let (granularity, min, capacity) = self.segment_rules(model, ch);
        let memory = self.channel(ch).memory;
        let where_ = match memory {
            Memory::Extended => format!("extended memory at DIV{}", self.divider),
            Memory::Internal => "internal memory".to_string(),
        };
        if length % granularity != 0 {
            return Err(out_of_range(format!(
                "segment length {length} is not a multiple of the granularity {granularity} of {where_}"
            )));
        }
        if length < min {
            return Err(out_of_range(format!(
                "segment length {length} is below the minimum {min} of {where_}"
            )));
        }
        if length > capacity {
            return Err(out_of_range(format!(
                "segment length {length} exceeds the {capacity}-sample {where_}"
            )));
        }
        if length > EMULATOR_MAX_SEGMENT_SAMPLES {
            return Err(ScpiError::new(
                -225,
                format!("the emulator stores at most {EMULATOR_MAX_SEGMENT_SAMPLES} samples per segment"),
            ));
        }
        let id = id as u32;
        let targets = self.segment_channels(model, ch);
        if let Some(taken) = targets
            .iter()
            .find(|c| self.channel(**c).segments.contains_key(&id))
        {
            return Err(conflict(format!(
                "segment {id} is already defined on channel {taken}; delete it first (:TRAC{taken}:DEL {id})"
            )));
        }
        let fill = fill.unwrap_or(0);
        for target in targets {
            let markers = if self.interleaved(model, target) {
                vec![0u8; length as usize]
            } else {
                Vec::new()
            };
            self.channel_mut(target).segments.insert(
                id,
                Segment {
                    samples: vec![fill; length as usize],
                    markers,
                },
            );
        }
        self.touch();
        Ok(())
    }

    /// Writes samples (and, on channel 1 in marker modes, marker bytes) at a sample offset.
    pub fn write(
        &mut self,
        model: &AwgModel,
        ch: u8,
        id: u64,
        offset: u64,
        samples: &[i8],
        markers: Option<&[u8]>,
    ) -> Result<(), ScpiError> {
        self.require_signal(model, ch)?;
        let id32 = u32::try_from(id).unwrap_or(u32::MAX);
        if self.running && self.channel(ch).selected == id32 {
            return Err(conflict(
                "writing the playing segment is not allowed while the output runs; send :ABOR first",
            ));
        }
        let (granularity, _, _) = self.segment_rules(model, ch);
        let Some(segment) = self.channel(ch).segments.get(&id32) else {
            return Err(out_of_range(format!(
                "segment {id} is not defined on channel {ch}; define it with :TRAC{ch}:DEF"
            )));
        };
        if offset % granularity != 0 {
            return Err(out_of_range(format!(
                "offset {offset} is not a multiple of the granularity {granularity}"
            )));
        }
        let length = segment.samples.len() as u64;
        let end = offset.saturating_add(samples.len() as u64);
        if end > length {
            return Err(ScpiError::new(
                -223,
                format!(
                    "{} samples at offset {offset} overrun segment {id} of {length} samples",
                    samples.len()
                ),
            ));
        }
        let interleaved = self.interleaved(model, ch);
        let Some(segment) = self.channel_mut(ch).segments.get_mut(&id32) else {
            return Err(out_of_range(format!(
                "segment {id} is not defined on channel {ch}"
            )));
        };
        let range = offset as usize..end as usize;
        segment.samples[range.clone()].copy_from_slice(samples);
        if interleaved {
            if let Some(m) = markers {
                segment.markers[range].copy_from_slice(m);
            }
        }
        self.touch();
        Ok(())
    }

    pub fn read(
        &self,
        ch: u8,
        id: u64,
        offset: u64,
        count: u64,
        interleaved: bool,
    ) -> Result<String, ScpiError> {
        let id32 = u32::try_from(id).unwrap_or(u32::MAX);
        let segment =
            self.channel(ch).segments.get(&id32).ok_or_else(|| {
                out_of_range(format!("segment {id} is not defined on channel {ch}"))
            })?;
        let len = segment.samples.len() as u64;
        if offset.saturating_add(count) > len {
            return Err(out_of_range(format!(
                "offset {offset} + {count} samples exceeds the segment length {len}"
            )));
        }
        let range = offset as usize..(offset + count) as usize;
        let values: Vec<String> = if interleaved {
            range
                .flat_map(|i| {
                    [
                        segment.samples[i].to_string(),
                        segment.markers[i].to_string(),
                    ]
                })
                .collect()
        } else {
            segment.samples[range]
                .iter()
                .map(|s| s.to_string())
                .collect()
        };
        Ok(values.join(","))
    }

    pub fn catalog(&self, ch: u8) -> String {
        let segments = &self.channel(ch).segments;
        if segments.is_empty() {
            return "0,0".to_string();
        }
        segments
            .iter()
            .map(|(id, s)| format!("{id},{}", s.samples.len()))
            .collect::<Vec<_>>()
            .join(",")
    }

    pub fn free(&self, model: &AwgModel, ch: u8) -> String {
        let (_, _, capacity) = self.segment_rules(model, ch);
        let used: u64 = self
            .channel(ch)
            .segments
            .values()
            .map(|s| s.samples.len() as u64)
            .sum();
        let free = capacity.saturating_sub(used);
        format!("{free},{free}")
    }

    pub(crate) fn delete(
        &mut self,
        model: &AwgModel,
        ch: u8,
        id: Option<u64>,
    ) -> Result<(), ScpiError> {
        self.refuse_while_running("deleting segments")?;
        let targets = self.segment_channels(model, ch);
        match id {
            None => {
                for t in targets {
                    self.channel_mut(t).segments.clear();
                }
            }
            Some(id) => {
                let id32 = u32::try_from(id).unwrap_or(u32::MAX);
                if !self.channel(ch).segments.contains_key(&id32) {
                    return Err(out_of_range(format!(
                        "segment {id} is not defined on channel {ch}"
                    )));
                }
                for t in targets {
                    self.channel_mut(t).segments.remove(&id32);
                }
            }
        }
        self.touch();
        Ok(())
    }

    pub fn select(&mut self, model: &AwgModel, ch: u8, id: u64) -> Result<(), ScpiError> {
        self.require_signal(model, ch)?;
        let id32 = u32::try_from(id).unwrap_or(u32::MAX);
        if !self.channel(ch).segments.contains_key(&id32) {
            return Err(out_of_range(format!(
                "segment {id} is not defined on channel {ch}"
            )));
        }
        self.channel_mut(ch).selected = id32;
        self.touch();
        Ok(())
    }

    /// `(min, max)` of amplitude and offset for a channel in the current mode.
    pub(crate) fn level_limits(&self, model: &AwgModel, ch: u8) -> ((f64, f64), (f64, f64)) {
        let l = &model.limits;
        if self.is_marker(model, ch) {
            (
                (l.marker_amplitude_v_min, l.marker_amplitude_v_max),
                (l.marker_offset_v_min, l.marker_offset_v_max),
            )
        } else {
            (
                (l.amplitude_vpp_min, l.amplitude_vpp_max),
                (l.offset_v_min, l.offset_v_max),
            )
        }
    }

    pub(crate) fn set_amplitude(&mut self, ch: u8, value: f64) {
        self.channel_mut(ch).amplitude_vpp = value;
        self.touch();
    }

    pub(crate) fn set_offset(&mut self, ch: u8, value: f64) {
        self.channel_mut(ch).offset_v = value;
        self.touch();
    }

    /// Whether a signal channel has a selected segment to play.
    fn has_waveform(&self, ch: u8) -> bool {
        let c = self.channel(ch);
        c.segments.contains_key(&c.selected)
    }

    pub(crate) fn set_output(
        &mut self,
        model: &AwgModel,
        ch: u8,
        on: bool,
    ) -> Result<(), ScpiError> {
        if on {
            if self.is_marker(model, ch) {
                if !self.has_waveform(1) {
                    return Err(conflict(format!(
                        "marker output {ch} needs a waveform with markers on channel 1 first"
                    )));
                }
            } else if self.is_signal(model, ch) {
                if !self.has_waveform(ch) {
                    return Err(conflict(format!(
                        "channel {ch} has no waveform: define and select a segment before switching the output on"
                    )));
                }
            } else {
                return Err(conflict(format!(
                    "channel {ch} is not used in DAC mode {}",
                    self.dac_mode
                )));
            }
        }
        if self.channel(ch).output != on {
            self.channel_mut(ch).output = on;
            self.touch();
        }
        Ok(())
    }

    pub fn start(&mut self, model: &AwgModel) -> Result<(), ScpiError> {
        let mode = self
            .mode(model)
            .ok_or_else(|| conflict("no DAC mode selected"))?;
        if !mode.dividers.contains(&self.divider) {
            let allowed: Vec<String> = mode.dividers.iter().map(|d| format!("DIV{d}")).collect();
            return Err(conflict(format!(
                "DAC mode {} allows {} only (set :INST:MEM:EXT:RDIV)",
                mode.keyword,
                allowed.join("|")
            )));
        }
        if let Some(missing) = mode
            .signal_channels
            .iter()
            .find(|c| !self.has_waveform(**c))
        {
            return Err(conflict(format!(
                "channel {missing} has no waveform: define, write and select a segment before :INIT:IMM"
            )));
        }
        if !self.running {
            self.running = true;
            self.touch();
        }
        Ok(())
    }

    pub fn stop(&mut self) {
        if self.running {
            self.running = false;
            self.touch();
        }
    }

    /// The channel's memory sample rate.
    pub(crate) fn channel_rate(&self, ch: u8) -> f64 {
        match self.channel(ch).memory {
            Memory::Extended => self.raster / f64::from(self.divider),
            Memory::Internal => self.raster,
        }
    }

    pub fn playback(&self, model: &AwgModel) -> Playback {
        let mode = self.mode(model);
        let channels = (1..=self.channels.len() as u8)
            .map(|n| {
                let c = self.channel(n);
                let samples: Arc<[i8]> = if self.is_signal(model, n) {
                    c.segments
                        .get(&c.selected)
                        .map(|s| Arc::from(s.samples.as_slice()))
                        .unwrap_or_else(|| Arc::from(Vec::new()))
                } else {
                    Arc::from(Vec::new())
                };
                ChannelPlayback {
                    number: n,
                    output_on: c.output,
                    amplitude_vpp: c.amplitude_vpp,
                    offset_v: c.offset_v,
                    memory: c.memory,
                    sample_rate: self.channel_rate(n),
                    samples,
                }
            })
            .collect();
        let ch1 = self.channel(1);
        let markers: Arc<[u8]> = ch1
            .segments
            .get(&ch1.selected)
            .map(|s| Arc::from(s.markers.as_slice()))
            .unwrap_or_else(|| Arc::from(Vec::new()));
        Playback {
            running: self.running,
            continuous: self.continuous,
            dac_mode: self.dac_mode.clone(),
            divider: self.divider,
            dac_rate: self.raster,
            channels,
            markers,
            marker_channels: mode.map(|m| m.marker_channels.clone()).unwrap_or_default(),
            generation: self.generation,
        }
    }

    /// Whether channel 1's data is interleaved `[sample, marker]` bytes in the current mode.
    pub(crate) fn channel_interleaved(&self, model: &AwgModel, ch: u8) -> bool {
        self.interleaved(model, ch)
    }
}
