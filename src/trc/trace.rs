//! A decoded waveform block: descriptor, the optional arrays in their order (USER_TEXT, TRIGTIME,
//! RIS_TIME, RES_ARRAY1), data array 1 as codes, and the segments of a sequence.

use bytes::Bytes;

use super::{text, ByteOrder, Input, TrcError, WaveDesc, NAME, NAME_SEARCH};

/// Bytes of one TRIGTIME entry: TRIGGER_TIME f64, TRIGGER_OFFSET f64.
const TRIGTIME_ENTRY: u64 = 16;
/// Bytes of one RIS_TIME entry: RIS_OFFSET f64.
const RIS_ENTRY: u64 = 8;

/// One entry of the TRIGTIME array, as LeCroy stores it.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct SegmentTime {
    /// Seconds from the first segment's trigger to this segment's trigger (TRIGGER_TIME).
    pub trigger_time_s: f64,
    /// Seconds from this segment's trigger to its first sample (TRIGGER_OFFSET).
    pub trigger_offset_s: f64,
}

/// One channel of one acquisition: the decoded descriptor, the samples as codes, and the raw
/// block they came from (for saving as `.trc`).
#[derive(Debug, Clone)]
pub struct Trace {
    /// 1-based channel number (C1 = 1); 0 when a file does not say (WAVE_SOURCE 9, unknown).
    pub channel: u8,
    pub desc: WaveDesc,
    /// The samples as the scope's signed codes (16-bit in WORD format, 8-bit in BYTE format), all
    /// segments one after the other.
    pub codes: Vec<i16>,
    /// The USER_TEXT block (NUL padding removed).
    pub user_text: String,
    /// The TRIGTIME array: one entry per segment of a sequence (usually empty otherwise).
    pub trigger_times: Vec<SegmentTime>,
    /// The RIS_TIME array: RIS_OFFSET of each RIS sweep, seconds (empty unless RIS).
    pub ris_offsets: Vec<f64>,
    /// How many segments `codes` holds (1 unless a sequence).
    segments: usize,
    /// The block payload: WAVEDESC and its arrays, exactly as received.
    block: Bytes,
}

/// One segment of a trace (the whole record when it is not a sequence).
#[derive(Debug, Clone, Copy)]
pub struct Segment<'a> {
    /// 0-based position in the record.
    pub index: usize,
    /// The segment's codes.
    pub codes: &'a [i16],
    /// Seconds from the first segment's trigger to this one's (TRIGGER_TIME); None when the block
    /// has no TRIGTIME array and this is not the first segment.
    pub trigger_time_s: Option<f64>,
    /// Seconds from this segment's trigger to its first sample: TRIGGER_OFFSET, or HORIZ_OFFSET
    /// when the block has no TRIGTIME array.
    pub trigger_offset_s: f64,
    gain: f64,
    offset: f64,
    interval: f64,
}

impl Segment<'_> {
    /// The samples in volts: `VERTICAL_GAIN * code - VERTICAL_OFFSET`.
    pub fn volts(&self) -> Vec<f64> {
        self.codes.iter().map(|c| self.volt(*c)).collect()
    }

    /// One code in volts.
    pub fn volt(&self, code: i16) -> f64 {
        self.gain * f64::from(code) - self.offset
    }

    /// Sample times relative to this segment's trigger: `i * HORIZ_INTERVAL + trigger offset`.
    pub fn times(&self) -> Vec<f64> {
        (0..self.codes.len()).map(|i| self.time(i)).collect()
    }

    /// The time of sample `i` relative to this segment's trigger.
    pub fn time(&self, i: usize) -> f64 {
        i as f64 * self.interval + self.trigger_offset_s
    }
}

/// `start + len`, or the error naming `field` when it runs past `have`.
pub(super) fn end_of(
    field: &'static str,
    start: u64,
    len: u64,
    have: u64,
) -> Result<u64, TrcError> {
    let end = start.checked_add(len).ok_or(TrcError::BadField {
        field,
        value: len.to_string(),
        reason: "length overflows",
    })?;
    if end > have {
        return Err(TrcError::Truncated {
            field,
            needed: end,
            have,
            input: Input::Block,
        });
    }
    Ok(end)
}

fn f64_at(raw: &[u8], order: ByteOrder) -> f64 {
    let mut b = [0u8; 8];
    b.copy_from_slice(&raw[..8]);
    match order {
        ByteOrder::LoFirst => f64::from_le_bytes(b),
        ByteOrder::HiFirst => f64::from_be_bytes(b),
    }
}

/// How many segments the record holds, checked against the TRIGTIME array and the point count.
///
/// A scope sends one TRIGTIME entry per transmitted segment, so the entry count decides when
/// there is one (a single segment read with `WFSU SN,k` still says the acquired SUBARRAY_COUNT);
/// without TRIGTIME, SUBARRAY_COUNT does.
fn segment_count(desc: &WaveDesc) -> Result<usize, TrcError> {
    let trigtime = u64::from(desc.trigtime_array);
    if trigtime % TRIGTIME_ENTRY != 0 {
        return Err(TrcError::Inconsistent {
            field: "TRIGTIME_ARRAY",
            value: trigtime.to_string(),
            reason: format!(
                "must be a multiple of {TRIGTIME_ENTRY} bytes (two doubles per segment)"
            ),
        });
    }
    let entries = trigtime / TRIGTIME_ENTRY;
    let subarrays = u64::try_from(desc.subarray_count.max(1)).unwrap_or(1);
    if entries > subarrays.max(1) {
        return Err(TrcError::Inconsistent {
            field: "TRIGTIME_ARRAY",
            value: trigtime.to_string(),
            reason: format!(
                "it holds {entries} segment times but SUBARRAY_COUNT says {} segments",
                desc.subarray_count
            ),
        });
    }
    let count = u64::from(desc.wave_array_count);
    // No TRIGTIME and no points: nothing to split (and no reason to make empty segments).
    let segments = match (entries, count) {
        (0, 0) => 1,
        (0, _) => subarrays,
        _ => entries,
    };
    if count % segments != 0 {
        return Err(TrcError::Inconsistent {
            field: "SUBARRAY_COUNT",
            value: desc.subarray_count.to_string(),
            reason: format!(
                "WAVE_ARRAY_COUNT {count} points do not split into {segments} equal segments"
            ),
        });
    }
    // segments <= WAVE_ARRAY_COUNT or TRIGTIME entries, both bounded by the block's size.
    Ok(segments as usize)
}

impl Trace {
    /// Decodes a block payload (what follows `#9<len>`): WAVEDESC within its first 64 bytes, then
    /// the arrays its lengths announce.
    pub fn decode(channel: u8, block: Bytes) -> Result<Trace, TrcError> {
        let start = block
            .windows(NAME.len())
            .take(NAME_SEARCH)
            .position(|w| w == NAME)
            .ok_or(TrcError::NoDescriptor)?;
        let body = &block[start..];
        let desc = WaveDesc::decode(body)?;
        let have = body.len() as u64;
        let desc_end = end_of("WAVE_DESCRIPTOR", 0, u64::from(desc.wave_descriptor), have)?;
        let text_end = end_of("USER_TEXT", desc_end, u64::from(desc.user_text), have)?;
        let trig_end = end_of(
            "TRIGTIME_ARRAY",
            text_end,
            u64::from(desc.trigtime_array),
            have,
        )?;
        let ris_end = end_of(
            "RIS_TIME_ARRAY",
            trig_end,
            u64::from(desc.ris_time_array),
            have,
        )?;
        let at = end_of("RES_ARRAY1", ris_end, u64::from(desc.res_array1), have)?;
        let width = desc.sample_width();
        let data_bytes = u64::from(desc.wave_array_1);
        let data_end = end_of("WAVE_ARRAY_1", at, data_bytes, have)?;
        end_of("WAVE_ARRAY_2", data_end, u64::from(desc.wave_array_2), have)?;
        let count = u64::from(desc.wave_array_count);
        if data_bytes % width != 0 || data_bytes / width != count {
            return Err(TrcError::CountMismatch {
                count,
                bytes: data_bytes,
                width,
            });
        }
        if u64::from(desc.ris_time_array) % RIS_ENTRY != 0 {
            return Err(TrcError::Inconsistent {
                field: "RIS_TIME_ARRAY",
                value: desc.ris_time_array.to_string(),
                reason: format!("must be a multiple of {RIS_ENTRY} bytes (one double per sweep)"),
            });
        }
        let segments = segment_count(&desc)?;
        // Every range below was checked against `have` by end_of.
        let range = |a: u64, b: u64| &body[a as usize..b as usize];
        let user_text = text(range(desc_end, text_end));
        let trigger_times = range(text_end, trig_end)
            .chunks_exact(TRIGTIME_ENTRY as usize)
            .map(|e| SegmentTime {
                trigger_time_s: f64_at(&e[..8], desc.order),
                trigger_offset_s: f64_at(&e[8..], desc.order),
            })
            .collect();
        let ris_offsets = range(trig_end, ris_end)
            .chunks_exact(RIS_ENTRY as usize)
            .map(|e| f64_at(e, desc.order))
            .collect();
        let data = range(at, data_end);
        let codes = match (width, desc.order) {
            (2, ByteOrder::LoFirst) => data
                .chunks_exact(2)
                .map(|c| i16::from_le_bytes([c[0], c[1]]))
                .collect(),
            (2, ByteOrder::HiFirst) => data
                .chunks_exact(2)
                .map(|c| i16::from_be_bytes([c[0], c[1]]))
                .collect(),
            _ => data.iter().map(|b| i16::from(*b as i8)).collect(),
        };
        Ok(Trace {
            channel,
            desc,
            codes,
            user_text,
            trigger_times,
            ris_offsets,
            segments,
            block: block.slice(start..),
        })
    }

    /// Reads a `.trc` file's bytes: `#9<len>` (or no file header) + WAVEDESC + arrays. See
    /// `Trace::from_file_bytes`, which this calls; `channel` is kept as given.
    pub fn from_trc_bytes(channel: u8, file: Bytes) -> Result<Trace, TrcError> {
        let mut trace = Trace::from_file_bytes(file)?;
        trace.channel = channel;
        Ok(trace)
    }

    /// The samples in volts: `VERTICAL_GAIN * code - VERTICAL_OFFSET` (all segments).
    pub fn volts(&self) -> Vec<f64> {
        let gain = f64::from(self.desc.vertical_gain);
        let offset = f64::from(self.desc.vertical_offset);
        self.codes
            .iter()
            .map(|c| gain * f64::from(*c) - offset)
            .collect()
    }

    /// Seconds between samples (HORIZ_INTERVAL).
    pub fn sample_interval_s(&self) -> f64 {
        f64::from(self.desc.horiz_interval)
    }

    /// Time of the first sample relative to the trigger (HORIZ_OFFSET), seconds.
    pub fn first_sample_s(&self) -> f64 {
        self.desc.horiz_offset
    }

    /// The time of every sample relative to the trigger: `i * HORIZ_INTERVAL + HORIZ_OFFSET`.
    /// For a sequence this runs on across the segments; use [`Trace::segments`] there.
    pub fn times(&self) -> Vec<f64> {
        let dt = self.sample_interval_s();
        let t0 = self.first_sample_s();
        (0..self.codes.len()).map(|i| i as f64 * dt + t0).collect()
    }

    /// How many segments the record holds: 1, or the sequence's segment count.
    pub fn segment_count(&self) -> usize {
        self.segments
    }

    /// Whether this is a sequence-mode record of more than one segment.
    pub fn is_sequence(&self) -> bool {
        self.segments > 1
    }

    /// Segment `index` (0-based), or None past the last one.
    pub fn segment(&self, index: usize) -> Option<Segment<'_>> {
        if index >= self.segments {
            return None;
        }
        let len = self.codes.len() / self.segments;
        let timing = self.trigger_times.get(index);
        Some(Segment {
            index,
            codes: &self.codes[index * len..(index + 1) * len],
            trigger_time_s: timing
                .map(|t| t.trigger_time_s)
                .or((index == 0).then_some(0.0)),
            trigger_offset_s: timing.map_or(self.desc.horiz_offset, |t| t.trigger_offset_s),
            gain: f64::from(self.desc.vertical_gain),
            offset: f64::from(self.desc.vertical_offset),
            interval: self.sample_interval_s(),
        })
    }

    /// Every segment in order (one for a record that is not a sequence).
    pub fn segments(&self) -> impl Iterator<Item = Segment<'_>> + '_ {
        (0..self.segments).filter_map(|k| self.segment(k))
    }

    /// The block payload as received (WAVEDESC and arrays).
    pub fn block(&self) -> &Bytes {
        &self.block
    }

    /// The `.trc` file content: `#9` + nine length digits + the block payload.
    pub fn trc_bytes(&self) -> Vec<u8> {
        let mut out = Vec::with_capacity(self.block.len() + 11);
        out.extend_from_slice(format!("#9{:09}", self.block.len()).as_bytes());
        out.extend_from_slice(&self.block);
        out
    }
}

#[cfg(test)]
mod tests {
    use super::super::BlockBuilder;
    use super::*;

    #[test]
    fn word_block_decodes_to_volts_and_times() {
        let b = BlockBuilder {
            gain: 0.001,
            offset: 0.5,
            user_text: b"note".to_vec(),
            ..BlockBuilder::default()
        };
        let trace = Trace::decode(1, Bytes::from(b.build(&[0, 1000, -1000]))).unwrap();
        assert_eq!(trace.codes, vec![0, 1000, -1000]);
        let v = trace.volts();
        assert!(
            (v[0] + 0.5).abs() < 1e-6 && (v[1] - 0.5).abs() < 1e-6 && (v[2] + 1.5).abs() < 1e-6
        );
        let t = trace.times();
        assert_eq!(t[0], -1.0e-9);
        assert!((t[2] - (-1.0e-9 + 2.0 * f64::from(12.5e-12f32))).abs() < 1e-18);
        assert_eq!(trace.desc.template_name, "LECROY_2_3");
        assert_eq!(trace.user_text, "note");
        assert_eq!(trace.segment_count(), 1);
        let only = trace.segment(0).unwrap();
        assert_eq!(only.volts(), v);
        assert_eq!(only.times(), t);
        assert_eq!(only.trigger_time_s, Some(0.0));
        assert!(trace.segment(1).is_none());
    }

    #[test]
    fn big_endian_and_byte_formats_decode() {
        for (order, word) in [
            (ByteOrder::HiFirst, true),
            (ByteOrder::LoFirst, false),
            (ByteOrder::HiFirst, false),
        ] {
            let b = BlockBuilder {
                order,
                word,
                ..BlockBuilder::default()
            };
            let trace = Trace::decode(2, Bytes::from(b.build(&[-5, 7, 100]))).unwrap();
            assert_eq!(trace.codes, vec![-5, 7, 100], "{order:?} word={word}");
            assert_eq!(trace.desc.order, order);
        }
    }

    #[test]
    fn sequence_segments_carry_their_own_trigger_time_and_offset() {
        for (order, word) in [
            (ByteOrder::LoFirst, true),
            (ByteOrder::HiFirst, true),
            (ByteOrder::HiFirst, false),
        ] {
            let times = vec![(0.0, -2.0e-9), (7.5e-3, -1.9e-9), (1.5e-2, -2.1e-9)];
            let b = BlockBuilder {
                order,
                word,
                segments: times.clone(),
                ris_offsets: vec![1e-12, 2e-12],
                user_text: b"seq\0\0".to_vec(),
                gain: 0.5,
                offset: 1.0,
                interval: 1e-9,
                horiz_offset: -2.0e-9,
                ..BlockBuilder::default()
            };
            let codes: Vec<i16> = (0..12).map(|i| i * 3 - 10).collect();
            let trace = Trace::decode(1, Bytes::from(b.build(&codes))).unwrap();
            assert_eq!(trace.segment_count(), 3);
            assert!(trace.is_sequence());
            assert_eq!(trace.ris_offsets, vec![1e-12, 2e-12]);
            assert_eq!(trace.user_text, "seq");
            let segs: Vec<Segment<'_>> = trace.segments().collect();
            assert_eq!(segs.len(), 3);
            for (k, s) in segs.iter().enumerate() {
                assert_eq!(s.codes, &codes[4 * k..4 * k + 4], "{order:?}");
                assert_eq!(s.trigger_time_s, Some(times[k].0));
                assert_eq!(s.trigger_offset_s, times[k].1);
                assert_eq!(s.volts()[1], 0.5 * f64::from(codes[4 * k + 1]) - 1.0);
                assert_eq!(s.times()[2], 2.0 * f64::from(1e-9f32) + times[k].1);
            }
        }
    }

    #[test]
    fn a_sequence_without_trigtime_uses_horiz_offset() {
        let mut block = BlockBuilder::default().build(&[1, 2, 3, 4]);
        block[144..148].copy_from_slice(&2i32.to_le_bytes());
        let trace = Trace::decode(1, Bytes::from(block)).unwrap();
        assert_eq!(trace.segment_count(), 2);
        let second = trace.segment(1).unwrap();
        assert_eq!(second.codes, &[3, 4]);
        assert_eq!(second.trigger_time_s, None);
        assert_eq!(second.trigger_offset_s, trace.desc.horiz_offset);
    }

    #[test]
    fn segment_fields_that_disagree_are_named() {
        // 5 points in 2 segments.
        let mut block = BlockBuilder::default().build(&[1, 2, 3, 4, 5]);
        block[144..148].copy_from_slice(&2i32.to_le_bytes());
        let e = Trace::decode(1, Bytes::from(block)).unwrap_err();
        assert!(e.to_string().contains("SUBARRAY_COUNT"), "{e}");
        // TRIGTIME of 3 entries with SUBARRAY_COUNT 2.
        let mut block = BlockBuilder {
            segments: vec![(0.0, 0.0); 3],
            ..BlockBuilder::default()
        }
        .build(&[1, 2, 3, 4, 5, 6]);
        block[144..148].copy_from_slice(&2i32.to_le_bytes());
        let e = Trace::decode(1, Bytes::from(block)).unwrap_err();
        assert!(e.to_string().contains("TRIGTIME_ARRAY"), "{e}");
        // TRIGTIME not a multiple of 16 bytes (the arrays still fit: the text shrinks).
        let mut block = BlockBuilder {
            segments: vec![(0.0, 0.0); 2],
            user_text: vec![b'x'; 8],
            ..BlockBuilder::default()
        }
        .build(&[1, 2, 3, 4]);
        block[40..44].copy_from_slice(&0i32.to_le_bytes());
        block[48..52].copy_from_slice(&40i32.to_le_bytes());
        let e = Trace::decode(1, Bytes::from(block)).unwrap_err();
        assert!(e.to_string().contains("multiple of 16"), "{e}");
    }

    #[test]
    fn every_truncation_is_an_error_not_a_panic() {
        let block = BlockBuilder {
            user_text: vec![b'x'; 10],
            segments: vec![(0.0, -1e-9), (1e-3, -1e-9)],
            ris_offsets: vec![0.5e-12],
            ..BlockBuilder::default()
        }
        .build(&[1, 2, 3, 4, 5, 6]);
        for cut in 0..block.len() {
            let r = Trace::decode(1, Bytes::copy_from_slice(&block[..cut]));
            assert!(r.is_err(), "cut at {cut} decoded");
        }
        assert!(Trace::decode(1, Bytes::from(block)).is_ok());
    }

    #[test]
    fn inconsistent_fields_are_named() {
        let mut block = BlockBuilder::default().build(&[1, 2, 3]);
        block[116] = 9; // WAVE_ARRAY_COUNT = 9 with 6 bytes of data
        let e = Trace::decode(1, Bytes::from(block.clone())).unwrap_err();
        assert!(matches!(e, TrcError::CountMismatch { count: 9, .. }), "{e}");
        block[116] = 3;
        block[60..64].copy_from_slice(&(-4i32).to_le_bytes());
        let e = Trace::decode(1, Bytes::from(block.clone())).unwrap_err();
        assert!(e.to_string().contains("WAVE_ARRAY_1"), "{e}");
        block[60..64].copy_from_slice(&(1_000_000i32).to_le_bytes());
        let e = Trace::decode(1, Bytes::from(block.clone())).unwrap_err();
        assert!(
            matches!(
                e,
                TrcError::Truncated {
                    field: "WAVE_ARRAY_1",
                    ..
                }
            ),
            "{e}"
        );
        block[60..64].copy_from_slice(&(6i32).to_le_bytes());
        block[52..56].copy_from_slice(&(1_000_000i32).to_le_bytes());
        let e = Trace::decode(1, Bytes::from(block.clone())).unwrap_err();
        assert!(e.to_string().contains("RIS_TIME_ARRAY"), "{e}");
        block[52..56].copy_from_slice(&(0i32).to_le_bytes());
        block[34] = 7;
        assert!(Trace::decode(1, Bytes::from(block))
            .unwrap_err()
            .to_string()
            .contains("COMM_ORDER"));
    }

    #[test]
    fn arbitrary_bytes_never_panic() {
        let mut rng = crate::rng::SplitMix64::new(7);
        let base = BlockBuilder {
            segments: vec![(0.0, 0.0); 4],
            ..BlockBuilder::default()
        }
        .build(&[10; 16]);
        for _ in 0..4000 {
            let mut b = base.clone();
            for _ in 0..4 {
                let at = (rng.next_u64() % b.len() as u64) as usize;
                b[at] = rng.next_u64() as u8;
            }
            if let Ok(t) = Trace::decode(1, Bytes::from(b)) {
                for s in t.segments() {
                    let _ = (s.volts(), s.times());
                }
            }
        }
    }
}
