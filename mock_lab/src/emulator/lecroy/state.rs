//! The scope's settings, its last acquisition and how both turn into WAVEDESC blocks.

use super::trigger::{AcquisitionRequest, Capture, Slope, TriggerSetup};
use super::wavedesc::{
    one_two_five_index, waveform_block_into, ByteOrder, SampleWidth, TriggerTimestamp, WaveDesc,
};
use crate::catalog::DigitizerModel;
use std::borrow::Cow;

/// Most points per channel the emulator records (it keeps them in RAM); larger requests adapt.
pub const EMULATOR_MAX_POINTS: u64 = 8 * 1024 * 1024;

/// Response header form (`COMM_HEADER`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum HeaderMode {
    Off,
    Short,
    Long,
}

/// Trigger mode (`TRIG_MODE`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum TriggerMode {
    Auto,
    Normal,
    Single,
    Stop,
}

impl TriggerMode {
    pub fn keyword(self) -> &'static str {
        match self {
            TriggerMode::Auto => "AUTO",
            TriggerMode::Normal => "NORM",
            TriggerMode::Single => "SINGLE",
            TriggerMode::Stop => "STOP",
        }
    }
    pub fn automation(self) -> &'static str {
        match self {
            TriggerMode::Auto => "Auto",
            TriggerMode::Normal => "Normal",
            TriggerMode::Single => "Single",
            TriggerMode::Stop => "Stopped",
        }
    }
}

/// How one acquisition records (`app.Acquisition.Horizontal.SampleMode`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum SampleMode {
    /// One record per trigger.
    RealTime,
    /// `segments` records, one per trigger, read together (`WF? ALL`, TRIGTIME array).
    Sequence,
}

impl SampleMode {
    pub fn automation(self) -> &'static str {
        match self {
            SampleMode::RealTime => "RealTime",
            SampleMode::Sequence => "Sequence",
        }
    }
}

/// Time the scope needs after a segment before it can trigger again \[I\]: a marker edge that
/// comes sooner is missed, and the segment waits for the next one.
pub const SEQUENCE_REARM_S: f64 = 1e-6;

/// The remote-control protocol enabled on the scope (Utilities > Remote): only one at a time.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum RemoteInterface {
    Vicp,
    Vxi11,
}

impl RemoteInterface {
    pub fn label(self) -> &'static str {
        match self {
            RemoteInterface::Vicp => "TCPIP (VICP)",
            RemoteInterface::Vxi11 => "LXI (VXI-11)",
        }
    }
}

/// Vertical settings of one channel.
#[derive(Debug, Clone, PartialEq)]
pub struct ChannelSettings {
    pub volts_per_div: f64,
    pub offset_v: f64,
    pub on: bool,
}

/// One recorded channel: 16-bit scope values plus the scaling at acquisition time.
#[derive(Debug, Clone, PartialEq)]
pub struct RecordedChannel {
    pub values: Vec<i16>,
    /// Volts per 16-bit code (WORD); BYTE uses 256 times this.
    pub gain_word: f64,
    pub offset_v: f64,
    pub volts_per_div: f64,
}

/// The last completed acquisition.
#[derive(Debug, Clone, PartialEq)]
pub struct Acquisition {
    pub sample_rate: f64,
    pub first_point_s: f64,
    pub hor_scale: f64,
    pub trigger_time: TriggerTimestamp,
    /// Every segment's values one after the other (one segment unless in sequence mode).
    pub channels: Vec<Option<RecordedChannel>>,
    /// Each segment's trigger time after the first segment's, seconds (one entry, 0, unless in
    /// sequence mode).
    pub segment_times: Vec<f64>,
    /// The acquisition was forced (FRTR / AUTO without an edge).
    pub forced: bool,
}

/// An acquisition being recorded: each segment is quantised to the ADC as it arrives and its
/// volts dropped, so a long sequence holds only its codes (16 segments of an OFDM record held
/// 160 MB of volts until the last came, all of it pages the kernel had to zero).
pub(crate) struct Recording {
    points: usize,
    /// Per channel (None when off): its ADC and the codes so far.
    channels: Vec<Option<(Adc, RecordedChannel)>>,
    /// The first segment's trigger time and edge period.
    first: Option<(TriggerTimestamp, Option<f64>)>,
    segments: usize,
}

impl Recording {
    /// Quantises one segment's capture onto the record (`points` per channel; a channel that
    /// saw nothing, or less than the record, reads 0 V).
    pub(crate) fn push(&mut self, capture: Capture) {
        let points = self.points;
        let volts = &capture.channels;
        // The channels on threads of their own: independent, and millions of samples each.
        std::thread::scope(|scope| {
            for (i, channel) in self.channels.iter_mut().enumerate() {
                let Some((adc, recorded)) = channel.as_mut() else {
                    continue;
                };
                let volts = volts.get(i).and_then(Option::as_deref).unwrap_or_default();
                scope.spawn(move || {
                    let held = volts.len().min(points);
                    let values = &mut recorded.values;
                    values.extend(volts[..held].iter().map(|&v| adc.code(f64::from(v))));
                    values.resize(values.len() + points - held, adc.code(0.0));
                });
            }
        });
        self.first
            .get_or_insert((capture.trigger_time, capture.edge_period_s));
        self.segments += 1;
    }

    /// Segments recorded so far.
    pub(crate) fn segments(&self) -> usize {
        self.segments
    }

    /// The first segment's edge period (the AWG's repetition), when its edges repeat.
    pub(crate) fn edge_period_s(&self) -> Option<f64> {
        self.first.and_then(|(_, period)| period)
    }
}

/// `WAVEFORM_SETUP`: sparsing, number of points (0 = all), first point, segment.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct TransferWindow {
    pub sparsing: u32,
    pub points: u32,
    pub first: u32,
    pub segment: u32,
}

/// All settings and the acquisition state.
#[derive(Debug, Clone)]
pub struct ScopeState {
    pub header: HeaderMode,
    pub width: SampleWidth,
    pub order: ByteOrder,
    pub window: TransferWindow,
    pub trigger_type: String,
    pub trigger_source: String,
    pub trigger_levels: Vec<(String, f64)>,
    pub trigger_slopes: Vec<(String, Slope)>,
    pub trigger_mode: TriggerMode,
    pub trigger_delay_s: f64,
    pub hor_scale: f64,
    pub max_samples: u64,
    pub maximize: String,
    pub requested_rate: f64,
    pub sample_mode: SampleMode,
    /// Segments per acquisition in sequence mode (`NumSegments`).
    pub segments: u32,
    pub channels: Vec<ChannelSettings>,
    /// Sticky header path (`C1:`, `EX:` ...).
    pub path: String,
    pub armed: bool,
    /// Increases on every arming, so a completion that raced a re-arm is dropped.
    pub arm_id: u64,
    /// INR bit0 latch: a new acquisition completed since the last `INR?`.
    pub new_acquisition: bool,
    /// The `arm_id` of the last completed acquisition.
    pub completed_arm_id: u64,
    pub acquisition: Option<Acquisition>,
    pub esr: u8,
    pub ese: u8,
    pub sre: u8,
    pub cmr: u8,
    pub exr: u8,
    /// A setting was adapted to what the scope can do (STB bit 2, VAB).
    pub value_adapted: bool,
    pub remote: RemoteInterface,
    /// The timebase's reference (`REFERENCE_CLOCK`): `INTERNAL` or `EXTERNAL`.
    pub reference_clock: String,
}

impl ScopeState {
    /// Power-on / `*RST` settings \[I\]: headers SHORT, BYTE transfers, HI first, edge trigger on C1 in
    /// AUTO mode, 50 ns/div, catalog default V/div on every channel, all channels on.
    pub fn reset(model: &DigitizerModel, remote: RemoteInterface) -> ScopeState {
        let l = &model.limits;
        ScopeState {
            header: HeaderMode::Short,
            width: SampleWidth::Byte,
            order: ByteOrder::HiFirst,
            window: TransferWindow::default(),
            trigger_type: "EDGE".into(),
            trigger_source: "C1".into(),
            trigger_levels: Vec::new(),
            trigger_slopes: Vec::new(),
            trigger_mode: TriggerMode::Auto,
            trigger_delay_s: 0.0,
            hor_scale: 50e-9,
            max_samples: l.max_points_per_channel,
            maximize: "SetMaximumMemory".into(),
            requested_rate: l.sample_rates[0],
            sample_mode: SampleMode::RealTime,
            segments: 10,
            channels: (0..l.channels)
                .map(|_| ChannelSettings {
                    volts_per_div: l.volts_per_div_default,
                    offset_v: 0.0,
                    on: true,
                })
                .collect(),
            path: "C1".into(),
            armed: false,
            arm_id: 0,
            new_acquisition: false,
            completed_arm_id: 0,
            acquisition: None,
            esr: 0,
            ese: 0,
            sre: 0,
            cmr: 0,
            exr: 0,
            value_adapted: false,
            remote,
            reference_clock: "INTERNAL".into(),
        }
    }

    /// The fixed sample rate (the first of the catalog's rates).
    pub fn sample_rate(model: &DigitizerModel) -> f64 {
        model.limits.sample_rates[0]
    }

    /// Points per channel (per segment in sequence mode) for the current timebase:
    /// `divisions x s/div x rate`, capped by the memory setting and the catalog (which sequence
    /// mode shares among its segments) and by the emulator's own limit per record.
    pub(crate) fn record_points(&self, model: &DigitizerModel) -> u64 {
        let l = &model.limits;
        let wanted = (f64::from(l.horizontal_divisions) * self.hor_scale * Self::sample_rate(model))
            .round()
            .max(1.0) as u64;
        let memory = self.max_samples.min(l.max_points_per_channel);
        wanted
            .min(memory / u64::from(self.segments_per_acquisition()))
            .min(EMULATOR_MAX_POINTS)
    }

    /// Sets the horizontal scale; a window longer than the record can hold is adapted (the
    /// scope records fewer points and says so in VAB).
    pub(crate) fn set_hor_scale(&mut self, model: &DigitizerModel, s_per_div: f64) {
        self.hor_scale = s_per_div;
        let l = &model.limits;
        let wanted = f64::from(l.horizontal_divisions) * s_per_div * Self::sample_rate(model);
        if wanted.round() as u64 > self.record_points(model) {
            self.value_adapted = true;
        }
    }

    /// Triggers one acquisition records.
    pub(crate) fn segments_per_acquisition(&self) -> u32 {
        match self.sample_mode {
            SampleMode::RealTime => 1,
            SampleMode::Sequence => self.segments.max(1),
        }
    }

    /// Time of the first point relative to the trigger: the trigger sits mid-grid at zero delay,
    /// positive delays show more pre-trigger time, negative ones move the grid after the trigger \[I\].
    pub fn first_point_s(&self, model: &DigitizerModel) -> f64 {
        -(f64::from(model.limits.horizontal_divisions) / 2.0) * self.hor_scale
            - self.trigger_delay_s
    }

    pub fn level(&self, source: &str) -> f64 {
        self.trigger_levels
            .iter()
            .find(|(s, _)| s == source)
            .map(|(_, v)| *v)
            .unwrap_or(0.0)
    }

    pub(crate) fn set_level(&mut self, source: &str, value: f64) {
        self.trigger_levels.retain(|(s, _)| s != source);
        self.trigger_levels.push((source.to_string(), value));
    }

    pub fn slope(&self, source: &str) -> Slope {
        self.trigger_slopes
            .iter()
            .find(|(s, _)| s == source)
            .map(|(_, v)| *v)
            .unwrap_or(Slope::Positive)
    }

    pub(crate) fn set_slope(&mut self, source: &str, slope: Slope) {
        self.trigger_slopes.retain(|(s, _)| s != source);
        self.trigger_slopes.push((source.to_string(), slope));
    }

    pub fn request(&self, model: &DigitizerModel) -> AcquisitionRequest {
        AcquisitionRequest {
            sample_rate: Self::sample_rate(model),
            points: self.record_points(model) as usize,
            first_point_s: self.first_point_s(model),
            trigger: TriggerSetup {
                source: self.trigger_source.clone(),
                level_v: self.level(&self.trigger_source),
                slope: self.slope(&self.trigger_source),
            },
            channels_on: self.channels.iter().map(|c| c.on).collect(),
        }
    }

    /// Changing the trigger mode arms (SINGLE, NORM, AUTO) or stops the acquisition system.
    pub(crate) fn set_trigger_mode(&mut self, mode: TriggerMode) {
        self.trigger_mode = mode;
        if mode == TriggerMode::Stop {
            self.armed = false;
        } else {
            self.arm();
        }
    }

    pub fn arm(&mut self) {
        if self.trigger_mode == TriggerMode::Stop {
            self.trigger_mode = TriggerMode::Single;
        }
        self.armed = true;
        self.arm_id += 1;
    }

    /// Starts recording an acquisition of up to `segments` segments with the channels' settings
    /// now (the scope quantises at acquisition time).
    pub(crate) fn recording(
        &self,
        model: &DigitizerModel,
        request: &AcquisitionRequest,
        segments: u32,
    ) -> Recording {
        let l = &model.limits;
        let adc_step = 1i32 << (16 - u32::from(l.adc_bits.clamp(1, 16)));
        let points = request.points;
        let channels = self
            .channels
            .iter()
            .map(|settings| {
                settings.on.then(|| {
                    let gain_word =
                        settings.volts_per_div / (f64::from(l.codes_per_division) * 256.0);
                    let recorded = RecordedChannel {
                        values: Vec::with_capacity(segments as usize * points),
                        gain_word,
                        offset_v: settings.offset_v,
                        volts_per_div: settings.volts_per_div,
                    };
                    (Adc::new(settings.offset_v, gain_word, adc_step), recorded)
                })
            })
            .collect();
        Recording {
            points,
            channels,
            first: None,
            segments: 0,
        }
    }

    /// Stores a completed acquisition (its segments triggered at `segment_times`) and updates
    /// the trigger state.
    pub(crate) fn complete(
        &mut self,
        request: &AcquisitionRequest,
        recording: Recording,
        segment_times: Vec<f64>,
        forced: bool,
    ) {
        let trigger_time = recording.first.map_or(NO_TRIGGER_TIME, |(t, _)| t);
        let channels = recording
            .channels
            .into_iter()
            .map(|c| c.map(|(_, recorded)| recorded))
            .collect();
        self.acquisition = Some(Acquisition {
            sample_rate: request.sample_rate,
            first_point_s: request.first_point_s,
            hor_scale: self.hor_scale,
            trigger_time,
            channels,
            segment_times,
            forced,
        });
        self.new_acquisition = true;
        self.completed_arm_id = self.arm_id;
        if self.trigger_mode == TriggerMode::Single {
            self.armed = false;
            self.trigger_mode = TriggerMode::Stop;
        }
    }

    /// `INR?` value: bit0 new acquisition (cleared by the read), bit13 trigger ready (armed).
    pub(crate) fn read_inr(&mut self) -> u16 {
        let mut inr = 0u16;
        if self.new_acquisition {
            inr |= 1;
        }
        if self.armed {
            inr |= 1 << 13;
        }
        self.new_acquisition = false;
        inr
    }

    /// `*STB?`: bit2 VAB, bit5 ESB, bit6 MSS.
    pub fn status_byte(&self) -> u8 {
        let mut stb = 0u8;
        if self.value_adapted {
            stb |= 0x04;
        }
        if self.esr & self.ese != 0 {
            stb |= 0x20;
        }
        if stb & self.sre != 0 {
            stb |= 0x40;
        }
        stb
    }

    /// What `WAVEFORM_SETUP` picks of a recorded channel: the values (SN 0 every segment of a
    /// sequence, k only the k-th, 1-based \[I\]; then first point, sparsing and count within
    /// each), the points of one segment, and the TRIGTIME entries of the segments picked.
    fn window_of<'a>(
        &self,
        acq: &Acquisition,
        c: &'a RecordedChannel,
    ) -> (Cow<'a, [i16]>, u32, Vec<(f64, f64)>) {
        let count = acq.segment_times.len().max(1);
        let seg_len = c.values.len() / count;
        let chosen: Vec<usize> = match self.window.segment as usize {
            0 => (0..count).collect(),
            k if k <= count => vec![k - 1],
            _ => Vec::new(),
        };
        let first = self.window.first as usize;
        let sparsing = self.window.sparsing.max(1) as usize;
        let per_segment = seg_len.saturating_sub(first).div_ceil(sparsing);
        let per_segment = match self.window.points {
            0 => per_segment,
            n => per_segment.min(n as usize),
        };
        let values =
            if chosen.len() == count && first == 0 && sparsing == 1 && per_segment == seg_len {
                // The whole record, as recorded: lent, not copied (it is millions of samples).
                Cow::Borrowed(&c.values[..count * seg_len])
            } else {
                let mut values = Vec::with_capacity(chosen.len() * per_segment);
                for &k in &chosen {
                    let segment = &c.values[k * seg_len..(k + 1) * seg_len];
                    values.extend(
                        segment
                            .iter()
                            .skip(first)
                            .step_by(sparsing)
                            .take(per_segment)
                            .copied(),
                    );
                }
                Cow::Owned(values)
            };
        let offset = acq.first_point_s + f64::from(self.window.first) / acq.sample_rate;
        let times = if acq.segment_times.len() > 1 {
            chosen
                .iter()
                .map(|&k| (acq.segment_times[k], offset))
                .collect()
        } else {
            Vec::new()
        };
        (values, seg_len as u32, times)
    }

    /// The `#9` block of `Cn:WF? ALL` for channel index `ch` (0 = C1), honouring COMM_FORMAT,
    /// COMM_ORDER and WAVEFORM_SETUP. Without an acquisition (or with the trace off) the block holds
    /// a descriptor with zero points \[I\].
    pub fn waveform(&self, model: &DigitizerModel, ch: usize, instrument_name: &str) -> Vec<u8> {
        let mut out = Vec::new();
        self.waveform_into(&mut out, model, ch, instrument_name);
        out
    }

    /// [`waveform`](Self::waveform) appended to `out`.
    pub(crate) fn waveform_into(
        &self,
        out: &mut Vec<u8>,
        model: &DigitizerModel,
        ch: usize,
        instrument_name: &str,
    ) {
        let rate = Self::sample_rate(model);
        let recorded = self
            .acquisition
            .as_ref()
            .and_then(|a| a.channels.get(ch)?.as_ref().map(|c| (a, c)));
        let sparsing = self.window.sparsing.max(1);
        let (values, desc_base, trigger_times) = match &recorded {
            Some((acq, c)) => {
                let (values, seg_len, times) = self.window_of(acq, c);
                (values, Some((acq, c, seg_len)), times)
            }
            None => (Cow::Borrowed(&[][..]), None, Vec::new()),
        };
        let byte = self.width == SampleWidth::Byte;
        let word_to_desc = if byte { 256.0 } else { 1.0 };
        let (gain, offset, vdiv, first_s, hor_scale, trigger_time, total) = match desc_base {
            Some((acq, c, total)) => (
                c.gain_word * word_to_desc,
                c.offset_v,
                c.volts_per_div,
                acq.first_point_s + f64::from(self.window.first) / acq.sample_rate,
                acq.hor_scale,
                acq.trigger_time,
                total,
            ),
            None => {
                let s = &self.channels[ch];
                let gain = s.volts_per_div / f64::from(model.limits.codes_per_division) / 256.0;
                (
                    gain * word_to_desc,
                    s.offset_v,
                    s.volts_per_div,
                    self.first_point_s(model),
                    self.hor_scale,
                    NO_TRIGGER_TIME,
                    0,
                )
            }
        };
        let (max_value, min_value) = if byte {
            (127.0, -128.0)
        } else {
            (32512.0, -32768.0)
        };
        let desc = WaveDesc {
            width: self.width,
            order: self.order,
            instrument_name: instrument_name.to_string(),
            points: values.len() as u32,
            points_per_screen: total,
            first_point: self.window.first,
            sparsing,
            segment_index: self.window.segment,
            subarray_count: trigger_times.len().max(1) as u32,
            trigger_times,
            vertical_gain: gain as f32,
            vertical_offset: offset as f32,
            max_value,
            min_value,
            nominal_bits: i16::from(model.limits.adc_bits),
            horiz_interval: (f64::from(sparsing) / rate) as f32,
            horiz_offset: first_s,
            pixel_offset: first_s,
            trigger_time,
            acq_duration: (f64::from(total) / rate) as f32,
            timebase: one_two_five_index(hor_scale, 1e-12),
            fixed_vert_gain: one_two_five_index(vdiv, 1e-6),
            probe_att: 1.0,
            acq_vert_offset: offset as f32,
            wave_source: ch as i16,
        };
        waveform_block_into(out, &desc, &values);
    }
}

/// The trigger time written before any acquisition (and into offline ones: no wall clock, so
/// reproducible).
pub(crate) const NO_TRIGGER_TIME: TriggerTimestamp = TriggerTimestamp {
    seconds: 0.0,
    minutes: 0,
    hours: 0,
    day: 1,
    month: 1,
    year: 2026,
};

/// Volts to a 16-bit scope value: `volts = gain * value - offset`, rounded to the ADC resolution
/// and clipped to the ADC range.
/// The scope's ADC for one channel: volts to 16-bit words holding `16 - log2(adc_step)` bits.
#[derive(Debug, Clone, Copy)]
struct Adc {
    offset_v: f64,
    gain_word: f64,
    adc_step: i32,
    step_f: f64,
    min: f64,
    max: f64,
}

impl Adc {
    fn new(offset_v: f64, gain_word: f64, adc_step: i32) -> Adc {
        Adc {
            offset_v,
            gain_word,
            adc_step,
            step_f: f64::from(adc_step),
            min: f64::from(i32::from(i16::MIN) / adc_step),
            max: f64::from((i32::from(i16::MAX) + 1) / adc_step - 1),
        }
    }

    /// Rounds half away from zero, as `f64::round`, without its library call (a record is
    /// millions of samples): add just under one half toward the sign, clip, truncate.
    fn code(&self, volts: f64) -> i16 {
        let value = (volts + self.offset_v) / self.gain_word / self.step_f;
        let nudged = value + 0.499_999_999_999_999_94_f64.copysign(value);
        (nudged.clamp(self.min, self.max) as i32 * self.adc_step) as i16
    }
}

#[cfg(test)]
fn quantise(volts: f64, offset_v: f64, gain_word: f64, adc_step: i32) -> i16 {
    Adc::new(offset_v, gain_word, adc_step).code(volts)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn quantisation_rounds_to_the_adc_and_clips() {
        let gain = 0.05 / (25.0 * 256.0);
        assert_eq!(quantise(0.0, 0.0, gain, 256), 0);
        assert_eq!(quantise(0.05, 0.0, gain, 256), 25 * 256);
        assert_eq!(quantise(10.0, 0.0, gain, 256), 127 * 256);
        assert_eq!(quantise(-10.0, 0.0, gain, 256), -128 * 256);
        assert_eq!(quantise(-0.05, 0.05, gain, 256), 0);
    }

    #[test]
    fn the_fast_rounding_matches_f64_round() {
        let adc = Adc::new(0.0, 1.0, 1);
        let mut x = -40_000.0_f64;
        while x < 40_000.0 {
            for v in [x, x + 0.5, x - 0.5, x + 0.499_999_999_999_9, x + 0.25] {
                let want = v.round().clamp(adc.min, adc.max) as i16;
                assert_eq!(adc.code(v), want, "{v}");
            }
            x += 0.75;
        }
    }
}
