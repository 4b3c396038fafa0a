//! The `LECROY_2_3` WAVEDESC descriptor (346 bytes) and the `#9` waveform block, encoded byte by byte
//! at the offsets of instruments.md section 2.6, in either byte order (COMM_ORDER).

/// Size of the `LECROY_2_3` descriptor.
pub(crate) const WAVEDESC_LEN: usize = 346;

/// Byte order of every multi-byte field and of WORD samples.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ByteOrder {
    /// `COMM_ORDER HI` (big endian), the scope's default.
    HiFirst,
    /// `COMM_ORDER LO` (little endian).
    LoFirst,
}

/// Sample width of the data array (COMM_FORMAT).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum SampleWidth {
    /// 8-bit samples: the upper byte of the scope's 16-bit values.
    Byte,
    /// 16-bit signed samples.
    Word,
}

/// The trigger time stamp of a WAVEDESC (TRIGGER_TIME at offset 296).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TriggerTimestamp {
    pub seconds: f64,
    pub minutes: u8,
    pub hours: u8,
    pub day: u8,
    pub month: u8,
    pub year: i16,
}

/// The descriptor fields the emulator fills; the rest are fixed (see [`encode`]).
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct WaveDesc {
    pub width: SampleWidth,
    pub order: ByteOrder,
    pub instrument_name: String,
    pub points: u32,
    pub points_per_screen: u32,
    pub first_point: u32,
    pub sparsing: u32,
    pub segment_index: u32,
    /// Segments in the data array (SUBARRAY_COUNT); 1 unless in sequence mode.
    pub subarray_count: u32,
    /// The TRIGTIME array: per segment, the trigger time after the first segment's and the time
    /// from that trigger to the segment's first point, seconds (empty unless in sequence mode).
    pub trigger_times: Vec<(f64, f64)>,
    pub vertical_gain: f32,
    pub vertical_offset: f32,
    pub max_value: f32,
    pub min_value: f32,
    pub nominal_bits: i16,
    pub horiz_interval: f32,
    pub horiz_offset: f64,
    pub pixel_offset: f64,
    pub trigger_time: TriggerTimestamp,
    pub acq_duration: f32,
    pub timebase: i16,
    pub fixed_vert_gain: i16,
    pub probe_att: f32,
    pub acq_vert_offset: f32,
    /// 0..=3 for C1..C4.
    pub wave_source: i16,
}

impl WaveDesc {
    /// Bytes of the TRIGTIME array: two f64 per entry.
    pub(crate) fn trigtime_bytes(&self) -> u32 {
        u32::try_from(self.trigger_times.len() * 16).unwrap_or(u32::MAX)
    }

    /// The TRIGTIME array in the descriptor's byte order.
    fn trigtime_array(&self) -> Vec<u8> {
        let mut out = Vec::with_capacity(self.trigtime_bytes() as usize);
        for &(time, offset) in &self.trigger_times {
            for v in [time, offset] {
                out.extend_from_slice(&match self.order {
                    ByteOrder::HiFirst => v.to_be_bytes(),
                    ByteOrder::LoFirst => v.to_le_bytes(),
                });
            }
        }
        out
    }
    /// Bytes of data array 1.
    pub(crate) fn array_bytes(&self) -> u32 {
        match self.width {
            SampleWidth::Byte => self.points,
            SampleWidth::Word => self.points.saturating_mul(2),
        }
    }
}

struct Writer {
    buf: [u8; WAVEDESC_LEN],
    order: ByteOrder,
}

impl Writer {
    fn bytes(&mut self, offset: usize, data: &[u8]) {
        self.buf[offset..offset + data.len()].copy_from_slice(data);
    }
    fn string(&mut self, offset: usize, size: usize, text: &str) {
        let bytes = text.as_bytes();
        let n = bytes.len().min(size - 1); // always NUL-terminated
        self.bytes(offset, &bytes[..n]);
    }
    fn i16(&mut self, offset: usize, v: i16) {
        let b = match self.order {
            ByteOrder::HiFirst => v.to_be_bytes(),
            ByteOrder::LoFirst => v.to_le_bytes(),
        };
        self.bytes(offset, &b);
    }
    fn i32(&mut self, offset: usize, v: i32) {
        let b = match self.order {
            ByteOrder::HiFirst => v.to_be_bytes(),
            ByteOrder::LoFirst => v.to_le_bytes(),
        };
        self.bytes(offset, &b);
    }
    fn u32(&mut self, offset: usize, v: u32) {
        self.i32(offset, i32::try_from(v).unwrap_or(i32::MAX));
    }
    fn f32(&mut self, offset: usize, v: f32) {
        let b = match self.order {
            ByteOrder::HiFirst => v.to_be_bytes(),
            ByteOrder::LoFirst => v.to_le_bytes(),
        };
        self.bytes(offset, &b);
    }
    fn f64(&mut self, offset: usize, v: f64) {
        let b = match self.order {
            ByteOrder::HiFirst => v.to_be_bytes(),
            ByteOrder::LoFirst => v.to_le_bytes(),
        };
        self.bytes(offset, &b);
    }
}

/// Encodes the 346-byte descriptor.
pub(crate) fn encode(d: &WaveDesc) -> [u8; WAVEDESC_LEN] {
    let mut w = Writer {
        buf: [0; WAVEDESC_LEN],
        order: d.order,
    };
    w.string(0, 16, "WAVEDESC");
    w.string(16, 16, "LECROY_2_3");
    w.i16(32, matches!(d.width, SampleWidth::Word).into());
    w.i16(34, matches!(d.order, ByteOrder::LoFirst).into());
    w.i32(36, WAVEDESC_LEN as i32); // WAVE_DESCRIPTOR
    w.i32(40, 0); // USER_TEXT
    w.i32(44, 0); // RES_DESC1
    w.u32(48, d.trigtime_bytes()); // TRIGTIME_ARRAY
    w.i32(52, 0); // RIS_TIME_ARRAY
    w.i32(56, 0); // RES_ARRAY1
    w.u32(60, d.array_bytes()); // WAVE_ARRAY_1
    w.i32(64, 0); // WAVE_ARRAY_2
    w.i32(68, 0); // RES_ARRAY2
    w.i32(72, 0); // RES_ARRAY3
    w.string(76, 16, &d.instrument_name);
    w.i32(92, 1); // INSTRUMENT_NUMBER
    w.string(96, 16, ""); // TRACE_LABEL
    w.u32(116, d.points); // WAVE_ARRAY_COUNT
    w.u32(120, d.points_per_screen);
    w.i32(124, 0); // FIRST_VALID_PNT
    w.u32(128, d.points.saturating_sub(1)); // LAST_VALID_PNT
    w.u32(132, d.first_point);
    w.u32(136, d.sparsing);
    w.u32(140, d.segment_index);
    w.u32(144, d.subarray_count.max(1)); // SUBARRAY_COUNT
    w.i32(148, 1); // SWEEPS_PER_ACQ
    w.i16(152, 0); // POINTS_PER_PAIR
    w.i16(154, 0); // PAIR_OFFSET
    w.f32(156, d.vertical_gain);
    w.f32(160, d.vertical_offset);
    w.f32(164, d.max_value);
    w.f32(168, d.min_value);
    w.i16(172, d.nominal_bits);
    w.i16(
        174,
        i16::try_from(d.subarray_count.max(1)).unwrap_or(i16::MAX),
    ); // NOM_SUBARRAY_COUNT
    w.f32(176, d.horiz_interval);
    w.f64(180, d.horiz_offset);
    w.f64(188, d.pixel_offset);
    w.string(196, 48, "V");
    w.string(244, 48, "S");
    w.f32(292, 1e-12); // HORIZ_UNCERTAINTY
    let t = d.trigger_time;
    w.f64(296, t.seconds);
    w.bytes(304, &[t.minutes, t.hours, t.day, t.month]);
    w.i16(308, t.year);
    w.i16(310, 0);
    w.f32(312, d.acq_duration);
    w.i16(316, 0); // RECORD_TYPE single_sweep
    w.i16(318, 0); // PROCESSING_DONE none
    w.i16(320, 0); // RESERVED5
    w.i16(322, 1); // RIS_SWEEPS
    w.i16(324, d.timebase);
    w.i16(326, 0); // VERT_COUPLING DC50
    w.f32(328, d.probe_att);
    w.i16(332, d.fixed_vert_gain);
    w.i16(334, 0); // BANDWIDTH_LIMIT off
    w.f32(336, 1.0); // VERTICAL_VERNIER
    w.f32(340, d.acq_vert_offset);
    w.i16(344, d.wave_source);
    w.buf
}

/// Encodes samples (16-bit scope values) in the requested width and order.
#[cfg(test)]
pub(crate) fn encode_samples(values: &[i16], width: SampleWidth, order: ByteOrder) -> Vec<u8> {
    let mut out = Vec::new();
    encode_samples_into(&mut out, values, width, order);
    out
}

/// Appends the samples, encoded, to `out` (a record is millions of samples: written once, in
/// place, rather than encoded apart and copied).
fn encode_samples_into(out: &mut Vec<u8>, values: &[i16], width: SampleWidth, order: ByteOrder) {
    match width {
        SampleWidth::Byte => out.extend(values.iter().map(|v| (v >> 8) as i8 as u8)),
        SampleWidth::Word => {
            out.reserve(values.len() * 2);
            for v in values {
                out.extend_from_slice(&match order {
                    ByteOrder::HiFirst => v.to_be_bytes(),
                    ByteOrder::LoFirst => v.to_le_bytes(),
                });
            }
        }
    }
}

/// `#9<9 digits>` + WAVEDESC + data array: the block of `WF? ALL` and the content of a `.trc` file.
/// Appended to `out` (a reply's header before it): a record is tens of megabytes, and a copy
/// of it into the reply cost as much as building it (the kernel zeroing fresh pages).
pub(crate) fn waveform_block_into(out: &mut Vec<u8>, desc: &WaveDesc, values: &[i16]) {
    let trigtime = desc.trigtime_array();
    let data_len = match desc.width {
        SampleWidth::Byte => values.len(),
        SampleWidth::Word => values.len() * 2,
    };
    let len = WAVEDESC_LEN + trigtime.len() + data_len;
    out.reserve_exact(11 + len);
    out.extend_from_slice(format!("#9{len:09}").as_bytes());
    out.extend_from_slice(&encode(desc));
    // Array order after the descriptor: USER_TEXT (none), TRIGTIME, RIS_TIME (none), data.
    out.extend_from_slice(&trigtime);
    encode_samples_into(out, values, desc.width, desc.order);
}

/// The 1-2-5 enum index used by TIMEBASE (from 1 ps/div) and FIXED_VERT_GAIN (from 1 uV/div).
pub(crate) fn one_two_five_index(value: f64, unit: f64) -> i16 {
    if value.is_nan() || value <= 0.0 {
        return 0;
    }
    let steps = (value / unit).log10();
    let decade = steps.floor();
    let mantissa = 10f64.powf(steps - decade);
    let within = if mantissa < 1.5 {
        0.0
    } else if mantissa < 3.5 {
        1.0
    } else if mantissa < 7.5 {
        2.0
    } else {
        3.0
    };
    (decade * 3.0 + within).clamp(0.0, f64::from(i16::MAX)) as i16
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn one_two_five() {
        assert_eq!(one_two_five_index(1e-12, 1e-12), 0);
        assert_eq!(one_two_five_index(2e-12, 1e-12), 1);
        assert_eq!(one_two_five_index(5e-12, 1e-12), 2);
        assert_eq!(one_two_five_index(1e-7, 1e-12), 15);
    }

    #[test]
    fn byte_width_keeps_the_upper_byte() {
        assert_eq!(
            encode_samples(
                &[0x7f00, -256, 0x0100],
                SampleWidth::Byte,
                ByteOrder::HiFirst
            ),
            [0x7f, 0xff, 0x01]
        );
        assert_eq!(
            encode_samples(&[0x1234], SampleWidth::Word, ByteOrder::LoFirst),
            [0x34, 0x12]
        );
    }
}
