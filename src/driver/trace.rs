//! What a digitizer returns, in no vendor's terms: codes with their scaling and timing, one or
//! more segments (sequence mode: one segment per trigger), and optionally the instrument's own
//! file of the same record so it can be saved as the scope would. A driver converts its wire
//! format into this (the LeCroy driver from WAVEDESC); nothing above `driver` sees the format.

use bytes::Bytes;
use serde::Serialize;

/// When one segment was triggered and where its first sample sits.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct SegmentTiming {
    /// Seconds from the first segment's trigger to this segment's trigger (0 for the first);
    /// None when the instrument did not say.
    pub trigger_time_s: Option<f64>,
    /// Seconds from this segment's trigger to its first sample (negative: before the trigger).
    pub first_sample_s: f64,
}

/// The instrument's own file of a record (for LeCroy a `.trc`), kept to save beside ours: a
/// short header and the block as received, not joined (no copy of the record on the capture's
/// path).
#[derive(Debug, Clone, PartialEq)]
pub struct NativeFile {
    /// File name extension without the dot, e.g. `trc`.
    pub extension: &'static str,
    /// What the file starts with before the block (for a `.trc`, `#9` and the length).
    pub header: Vec<u8>,
    pub body: Bytes,
}

impl NativeFile {
    /// The whole file.
    pub fn to_vec(&self) -> Vec<u8> {
        [&self.header[..], &self.body[..]].concat()
    }
}

/// One channel of one acquisition.
#[derive(Debug, Clone, PartialEq)]
pub struct ChannelTrace {
    /// 1-based channel number.
    pub channel: u8,
    /// Signed codes, every segment one after the other, all segments the same length.
    pub codes: Vec<i16>,
    /// Volts = `volts_per_code * code - offset_v`.
    pub volts_per_code: f64,
    pub offset_v: f64,
    pub sample_interval_s: f64,
    /// One entry per segment (one when not in sequence mode); never empty.
    pub segments: Vec<SegmentTiming>,
    pub native: Option<NativeFile>,
}

impl ChannelTrace {
    /// Segments the record holds (at least 1).
    pub fn segment_count(&self) -> usize {
        self.segments.len().max(1)
    }

    /// Samples per segment.
    pub fn segment_len(&self) -> usize {
        self.codes.len() / self.segment_count()
    }

    /// The codes of segment `k` (empty past the last one).
    pub fn segment_codes(&self, k: usize) -> &[i16] {
        let n = self.segment_len();
        self.codes.get(k * n..(k + 1) * n).unwrap_or(&[])
    }

    /// Timing of segment `k`; the first segment's when `k` is past the last one.
    pub fn timing(&self, k: usize) -> SegmentTiming {
        self.segments
            .get(k)
            .or(self.segments.first())
            .copied()
            .unwrap_or(SegmentTiming {
                trigger_time_s: Some(0.0),
                first_sample_s: 0.0,
            })
    }

    /// Time of the first sample of the first segment relative to its trigger, seconds.
    pub fn first_sample_s(&self) -> f64 {
        self.timing(0).first_sample_s
    }

    /// The time of every sample of segment `k` relative to its trigger, seconds.
    pub fn segment_times(&self, k: usize) -> Vec<f64> {
        let t0 = self.timing(k).first_sample_s;
        (0..self.segment_codes(k).len())
            .map(|i| t0 + i as f64 * self.sample_interval_s)
            .collect()
    }

    /// Segment `k` in volts.
    pub fn segment_volts(&self, k: usize) -> Vec<f64> {
        self.segment_codes(k)
            .iter()
            .map(|&c| self.volts_per_code * f64::from(c) - self.offset_v)
            .collect()
    }
}

/// I and Q captured by the same trigger(s).
#[derive(Debug, Clone, PartialEq)]
pub struct IqCapture {
    pub i: ChannelTrace,
    pub q: ChannelTrace,
}

impl IqCapture {
    /// Segments held (repetitions of the waveform captured by this acquisition).
    pub fn segments(&self) -> usize {
        self.i.segment_count()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn trace(codes: Vec<i16>, segments: usize) -> ChannelTrace {
        ChannelTrace {
            channel: 1,
            codes,
            volts_per_code: 0.5,
            offset_v: 1.0,
            sample_interval_s: 1e-9,
            segments: (0..segments)
                .map(|k| SegmentTiming {
                    trigger_time_s: Some(k as f64 * 1e-6),
                    first_sample_s: -2e-9,
                })
                .collect(),
            native: None,
        }
    }

    #[test]
    fn segments_split_the_codes_evenly() {
        let t = trace(vec![0, 1, 2, 3, 4, 5], 3);
        assert_eq!(t.segment_count(), 3);
        assert_eq!(t.segment_codes(1), &[2, 3]);
        assert_eq!(t.segment_volts(2), vec![1.0, 1.5]);
        assert!(t.segment_codes(3).is_empty());
        assert_eq!(t.timing(2).trigger_time_s, Some(2e-6));
    }

    #[test]
    fn a_record_without_timings_is_one_segment() {
        let t = trace(vec![4, 5], 0);
        assert_eq!(t.segment_count(), 1);
        assert_eq!(t.segment_codes(0), &[4, 5]);
        assert_eq!(t.first_sample_s(), 0.0);
    }
}
