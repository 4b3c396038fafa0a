//! LeCroy waveforms: the WAVEDESC descriptor (template `LECROY_2_3`, 346 bytes, instruments.md
//! section 2.6), the arrays behind it, and `.trc` files.
//!
//! - [`WaveDesc::decode`]: every field of the descriptor, in either byte order (COMM_ORDER).
//! - [`Trace::decode`]: a `WF? ALL` block payload: descriptor, USER_TEXT, TRIGTIME and RIS_TIME
//!   arrays, data array 1 (8-bit or 16-bit codes); the raw block kept so it can be saved as `.trc`.
//! - `Trace::from_file_bytes`: a `.trc` file as scopes and other tools write it: `#9<len>` or no
//!   file header, WAVEDESC after a short prefix (`C1:WF ALL,`), trailing bytes ignored.
//! - [`Trace::segments`]: the segments of a sequence-mode record (SUBARRAY_COUNT > 1), each with
//!   its trigger time and trigger offset from the TRIGTIME array.
//! - [`BlockBuilder`]: writes blocks (tests, golden files).
//!
//! Pure: no I/O. Every length field is checked against the bytes at hand before it is used, so a
//! truncated or inconsistent block gives a [`TrcError`] naming the field, never a panic, and
//! nothing is allocated beyond the size of the input.
//!
//! Scaling: `volts = VERTICAL_GAIN * code - VERTICAL_OFFSET`, `t_i = i * HORIZ_INTERVAL +
//! HORIZ_OFFSET` (HORIZ_OFFSET is the time from the trigger to the first sample, negative when
//! the record starts before the trigger). In a sequence, segment `k` uses its own TRIGGER_OFFSET
//! instead of HORIZ_OFFSET (they are equal for the first segment).

mod builder;
mod file;
mod trace;

pub use builder::BlockBuilder;
pub use trace::{Segment, SegmentTime, Trace};

/// Bytes of the descriptor in template `LECROY_2_3`.
pub(crate) const WAVEDESC_LEN: usize = 346;
const NAME: &[u8] = b"WAVEDESC";
/// How far into a block the descriptor name may start (some firmware puts a short prefix first).
const NAME_SEARCH: usize = 64;

/// What the bytes being decoded are: the hint for a truncation depends on it.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Input {
    /// A `WF?` block read from a scope.
    Block,
    /// A `.trc` file (byte positions are counted from the start of the file).
    File,
}

impl Input {
    fn noun(self) -> &'static str {
        match self {
            Input::Block => "waveform block",
            Input::File => "file",
        }
    }
    fn hint(self) -> &'static str {
        match self {
            Input::Block => "read the waveform again (raise the read timeout if the link is slow)",
            Input::File => "the file was cut short: copy or save it again",
        }
    }
}

/// Why a waveform block or `.trc` file cannot be decoded.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum TrcError {
    #[error("the waveform block has no WAVEDESC descriptor in its first {NAME_SEARCH} bytes; it is not a LeCroy waveform")]
    NoDescriptor,
    #[error("the {noun} is truncated: {field} needs bytes up to {needed}, the {noun} holds {have}; {hint}", noun = input.noun(), hint = input.hint())]
    Truncated {
        field: &'static str,
        needed: u64,
        have: u64,
        input: Input,
    },
    #[error("WAVEDESC field {field} = {value} is not valid: {reason}")]
    BadField {
        field: &'static str,
        value: String,
        reason: &'static str,
    },
    /// Fields that contradict each other (the reason says which and how).
    #[error("WAVEDESC field {field} = {value} is not valid: {reason}")]
    Inconsistent {
        field: &'static str,
        value: String,
        reason: String,
    },
    #[error("WAVE_ARRAY_COUNT says {count} points but WAVE_ARRAY_1 holds {bytes} bytes of {width}-byte samples")]
    CountMismatch { count: u64, bytes: u64, width: u64 },
    #[error("a .trc file starts with `#9` and nine length digits; this one starts with {start:?}")]
    BadFileHeader { start: String },
}

impl crate::exit::Classify for TrcError {
    fn exit_class(&self) -> crate::exit::ExitClass {
        crate::exit::ExitClass::Instrument
    }
}

/// Byte order of the multi-byte fields and samples (COMM_ORDER).
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize)]
pub enum ByteOrder {
    HiFirst,
    LoFirst,
}

impl ByteOrder {
    /// The name LeCroy's template gives it.
    pub fn name(self) -> &'static str {
        match self {
            ByteOrder::HiFirst => "HIFIRST",
            ByteOrder::LoFirst => "LOFIRST",
        }
    }
}

/// TRIGGER_TIME (offset 296): when the (first) trigger came, by the scope's clock, as stored.
#[derive(Debug, Clone, Copy, PartialEq, Default, serde::Serialize)]
pub struct TriggerTime {
    /// Seconds within the minute, with the fraction (0 <= s < 60 on a sane file).
    pub seconds: f64,
    pub minute: u8,
    pub hour: u8,
    pub day: u8,
    pub month: u8,
    pub year: i16,
}

impl TriggerTime {
    /// `YYYY-MM-DDTHH:MM:SS.ffffff` (scope local time; microseconds truncated, as lecroyscope).
    pub fn iso(&self) -> String {
        let whole = self.seconds.floor();
        let micros = ((self.seconds - whole) * 1e6).floor().clamp(0.0, 999_999.0);
        format!(
            "{:04}-{:02}-{:02}T{:02}:{:02}:{:02}.{:06}",
            self.year, self.month, self.day, self.hour, self.minute, whole as i64, micros as u32
        )
    }
}

/// Every field of the `LECROY_2_3` descriptor (reserved ones left out).
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct WaveDesc {
    pub template_name: String,
    /// 0: 8-bit samples, 1: 16-bit samples.
    pub comm_type: i16,
    pub order: ByteOrder,
    pub wave_descriptor: u32,
    pub user_text: u32,
    pub res_desc1: u32,
    pub trigtime_array: u32,
    pub ris_time_array: u32,
    pub res_array1: u32,
    pub wave_array_1: u32,
    pub wave_array_2: u32,
    pub res_array2: u32,
    pub res_array3: u32,
    pub instrument_name: String,
    pub instrument_number: i32,
    pub trace_label: String,
    pub wave_array_count: u32,
    pub points_per_screen: i32,
    pub first_valid_pnt: i32,
    pub last_valid_pnt: i32,
    pub first_point: i32,
    pub sparsing_factor: i32,
    pub segment_index: i32,
    pub subarray_count: i32,
    pub sweeps_per_acq: i32,
    pub points_per_pair: i16,
    pub pair_offset: i16,
    pub vertical_gain: f32,
    pub vertical_offset: f32,
    pub max_value: f32,
    pub min_value: f32,
    pub nominal_bits: i16,
    pub nom_subarray_count: i16,
    pub horiz_interval: f32,
    pub horiz_offset: f64,
    pub pixel_offset: f64,
    pub vertunit: String,
    pub horunit: String,
    pub horiz_uncertainty: f32,
    pub trigger_time: TriggerTime,
    pub acq_duration: f32,
    pub record_type: i16,
    pub processing_done: i16,
    pub ris_sweeps: i16,
    pub timebase: i16,
    pub vert_coupling: i16,
    pub probe_att: f32,
    pub fixed_vert_gain: i16,
    pub bandwidth_limit: i16,
    pub vertical_vernier: f32,
    pub acq_vert_offset: f32,
    pub wave_source: i16,
}

struct Reader<'a> {
    desc: &'a [u8],
    order: ByteOrder,
}

impl Reader<'_> {
    fn bytes<const N: usize>(&self, offset: usize) -> [u8; N] {
        let mut out = [0u8; N];
        out.copy_from_slice(&self.desc[offset..offset + N]);
        if self.order == ByteOrder::HiFirst {
            out.reverse();
        }
        out
    }
    fn i16(&self, offset: usize) -> i16 {
        i16::from_le_bytes(self.bytes(offset))
    }
    fn i32(&self, offset: usize) -> i32 {
        i32::from_le_bytes(self.bytes(offset))
    }
    fn f32(&self, offset: usize) -> f32 {
        f32::from_le_bytes(self.bytes(offset))
    }
    fn f64(&self, offset: usize) -> f64 {
        f64::from_le_bytes(self.bytes(offset))
    }
    fn text(&self, offset: usize, len: usize) -> String {
        text(&self.desc[offset..offset + len])
    }
    fn length(&self, field: &'static str, offset: usize) -> Result<u32, TrcError> {
        let v = self.i32(offset);
        u32::try_from(v).map_err(|_| TrcError::BadField {
            field,
            value: v.to_string(),
            reason: "a length cannot be negative",
        })
    }
}

/// NUL-terminated (or padded) text, trimmed; bytes that are not UTF-8 are replaced.
fn text(raw: &[u8]) -> String {
    let end = raw.iter().position(|b| *b == 0).unwrap_or(raw.len());
    String::from_utf8_lossy(&raw[..end]).trim().to_string()
}

/// COMM_ORDER: the byte order of everything after it.
fn byte_order(desc: &[u8]) -> Result<ByteOrder, TrcError> {
    Ok(match (desc[34], desc[35]) {
        (1, 0) => ByteOrder::LoFirst,
        (0, 0) => ByteOrder::HiFirst,
        (a, b) => {
            return Err(TrcError::BadField {
                field: "COMM_ORDER",
                value: format!("bytes {a:#04x} {b:#04x}"),
                reason: "must be 0 (HIFIRST) or 1 (LOFIRST)",
            })
        }
    })
}

/// COMM_TYPE (bytes or words) and the descriptor's own length, checked.
fn data_layout(r: &Reader<'_>) -> Result<(i16, u32), TrcError> {
    let comm_type = r.i16(32);
    if !(0..=1).contains(&comm_type) {
        return Err(TrcError::BadField {
            field: "COMM_TYPE",
            value: comm_type.to_string(),
            reason: "must be 0 (byte) or 1 (word)",
        });
    }
    let wave_descriptor = r.length("WAVE_DESCRIPTOR", 36)?;
    if (wave_descriptor as usize) < WAVEDESC_LEN {
        return Err(TrcError::BadField {
            field: "WAVE_DESCRIPTOR",
            value: wave_descriptor.to_string(),
            reason: "the descriptor of template LECROY_2_3 is 346 bytes",
        });
    }
    Ok((comm_type, wave_descriptor))
}

impl WaveDesc {
    /// Decodes the descriptor at the start of `desc` (at least `WAVEDESC_LEN` bytes).
    pub fn decode(desc: &[u8]) -> Result<WaveDesc, TrcError> {
        if desc.len() < WAVEDESC_LEN {
            return Err(TrcError::Truncated {
                field: "WAVEDESC",
                needed: WAVEDESC_LEN as u64,
                have: desc.len() as u64,
                input: Input::Block,
            });
        }
        let r = Reader {
            desc,
            order: byte_order(desc)?,
        };
        let (comm_type, wave_descriptor) = data_layout(&r)?;
        let d = WaveDesc {
            template_name: r.text(16, 16),
            comm_type,
            order: r.order,
            wave_descriptor,
            user_text: r.length("USER_TEXT", 40)?,
            res_desc1: r.length("RES_DESC1", 44)?,
            trigtime_array: r.length("TRIGTIME_ARRAY", 48)?,
            ris_time_array: r.length("RIS_TIME_ARRAY", 52)?,
            res_array1: r.length("RES_ARRAY1", 56)?,
            wave_array_1: r.length("WAVE_ARRAY_1", 60)?,
            wave_array_2: r.length("WAVE_ARRAY_2", 64)?,
            res_array2: r.length("RES_ARRAY2", 68)?,
            res_array3: r.length("RES_ARRAY3", 72)?,
            instrument_name: r.text(76, 16),
            instrument_number: r.i32(92),
            trace_label: r.text(96, 16),
            wave_array_count: r.length("WAVE_ARRAY_COUNT", 116)?,
            points_per_screen: r.i32(120),
            first_valid_pnt: r.i32(124),
            last_valid_pnt: r.i32(128),
            first_point: r.i32(132),
            sparsing_factor: r.i32(136),
            segment_index: r.i32(140),
            subarray_count: r.i32(144),
            sweeps_per_acq: r.i32(148),
            points_per_pair: r.i16(152),
            pair_offset: r.i16(154),
            vertical_gain: r.f32(156),
            vertical_offset: r.f32(160),
            max_value: r.f32(164),
            min_value: r.f32(168),
            nominal_bits: r.i16(172),
            nom_subarray_count: r.i16(174),
            horiz_interval: r.f32(176),
            horiz_offset: r.f64(180),
            pixel_offset: r.f64(188),
            vertunit: r.text(196, 48),
            horunit: r.text(244, 48),
            horiz_uncertainty: r.f32(292),
            trigger_time: TriggerTime {
                seconds: r.f64(296),
                minute: desc[304],
                hour: desc[305],
                day: desc[306],
                month: desc[307],
                year: r.i16(308),
            },
            acq_duration: r.f32(312),
            record_type: r.i16(316),
            processing_done: r.i16(318),
            ris_sweeps: r.i16(322),
            timebase: r.i16(324),
            vert_coupling: r.i16(326),
            probe_att: r.f32(328),
            fixed_vert_gain: r.i16(332),
            bandwidth_limit: r.i16(334),
            vertical_vernier: r.f32(336),
            acq_vert_offset: r.f32(340),
            wave_source: r.i16(344),
        };
        d.check_values()?;
        Ok(d)
    }

    /// The values the data cannot be read without: finite gains and offsets, a positive sample
    /// interval, a segment count that is not negative.
    fn check_values(&self) -> Result<(), TrcError> {
        let finite = |field, v: f64| {
            if v.is_finite() {
                Ok(())
            } else {
                Err(TrcError::BadField {
                    field,
                    value: v.to_string(),
                    reason: "must be a finite number",
                })
            }
        };
        finite("VERTICAL_GAIN", f64::from(self.vertical_gain))?;
        finite("VERTICAL_OFFSET", f64::from(self.vertical_offset))?;
        finite("HORIZ_OFFSET", self.horiz_offset)?;
        if !(self.horiz_interval.is_finite() && self.horiz_interval > 0.0) {
            return Err(TrcError::BadField {
                field: "HORIZ_INTERVAL",
                value: self.horiz_interval.to_string(),
                reason: "the sample interval must be a positive number",
            });
        }
        if self.subarray_count < 0 {
            return Err(TrcError::BadField {
                field: "SUBARRAY_COUNT",
                value: self.subarray_count.to_string(),
                reason: "a segment count cannot be negative",
            });
        }
        Ok(())
    }

    /// Bytes per sample of the data arrays.
    pub(crate) fn sample_width(&self) -> u64 {
        if self.comm_type == 1 {
            2
        } else {
            1
        }
    }

    /// The channel the trace came from, `C1`..`C4`, from WAVE_SOURCE (None for 9, "unknown", and
    /// anything else).
    pub fn source_channel(&self) -> Option<u8> {
        match self.wave_source {
            0..=3 => Some(self.wave_source as u8 + 1),
            _ => None,
        }
    }

    /// RECORD_TYPE by its template name (`single_sweep`, `sequence_obsolete`, `centered_RIS`, ...).
    pub fn record_type_name(&self) -> &'static str {
        const NAMES: [&str; 10] = [
            "single_sweep",
            "interleaved",
            "histogram",
            "graph",
            "filter_coefficient",
            "complex",
            "extrema",
            "sequence_obsolete",
            "centered_RIS",
            "peak_detect",
        ];
        usize::try_from(self.record_type)
            .ok()
            .and_then(|i| NAMES.get(i))
            .copied()
            .unwrap_or("unknown")
    }

    /// VERT_COUPLING by its template name.
    pub fn coupling_name(&self) -> &'static str {
        match self.vert_coupling {
            0 => "DC_50_Ohms",
            1 | 3 => "ground",
            2 => "DC_1MOhm",
            4 => "AC_1MOhm",
            _ => "unknown",
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_descriptor_field_reads_at_its_offset_in_both_orders() {
        for order in [ByteOrder::LoFirst, ByteOrder::HiFirst] {
            let b = BlockBuilder {
                order,
                trigger_time: TriggerTime {
                    seconds: 38.475_715_5,
                    minute: 29,
                    hour: 16,
                    day: 13,
                    month: 10,
                    year: 2022,
                },
                source: 2,
                ..BlockBuilder::default()
            };
            let d = WaveDesc::decode(&b.build(&[1, 2])).unwrap();
            assert_eq!(d.order, order);
            assert_eq!(d.trigger_time.year, 2022);
            assert_eq!(d.trigger_time.iso(), "2022-10-13T16:29:38.475715");
            assert_eq!(d.source_channel(), Some(3));
            assert_eq!(d.record_type_name(), "single_sweep");
            assert_eq!(d.subarray_count, 1);
            assert_eq!(d.vertunit, "V");
            assert_eq!(d.horunit, "S");
        }
    }

    #[test]
    fn a_negative_segment_count_is_named() {
        let mut block = BlockBuilder::default().build(&[1, 2]);
        block[144..148].copy_from_slice(&(-2i32).to_le_bytes());
        let e = WaveDesc::decode(&block).unwrap_err();
        assert!(e.to_string().contains("SUBARRAY_COUNT"), "{e}");
    }
}
