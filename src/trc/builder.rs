//! Writes WAVEDESC blocks at the offsets of instruments.md section 2.6 (tests and golden files).

use super::{ByteOrder, TriggerTime, NAME, WAVEDESC_LEN};

/// Builds a WAVEDESC block: descriptor, USER_TEXT, TRIGTIME, RIS_TIME, one data array.
#[derive(Debug, Clone)]
pub struct BlockBuilder {
    pub order: ByteOrder,
    /// 16-bit samples (COMM_TYPE 1) when true, 8-bit (COMM_TYPE 0) otherwise.
    pub word: bool,
    pub gain: f32,
    pub offset: f32,
    pub interval: f32,
    pub horiz_offset: f64,
    pub user_text: Vec<u8>,
    /// WAVE_SOURCE: 0..=3 for C1..C4.
    pub source: i16,
    /// A sequence: (TRIGGER_TIME, TRIGGER_OFFSET) of each segment, written as the TRIGTIME array
    /// with SUBARRAY_COUNT = its length. Empty: a single record (SUBARRAY_COUNT 1, no TRIGTIME).
    pub segments: Vec<(f64, f64)>,
    /// RIS_OFFSET of each sweep (the RIS_TIME array).
    pub ris_offsets: Vec<f64>,
    pub trigger_time: TriggerTime,
}

impl Default for BlockBuilder {
    fn default() -> Self {
        Self {
            order: ByteOrder::LoFirst,
            word: true,
            gain: 1.0 / 6400.0,
            offset: 0.0,
            interval: 12.5e-12,
            horiz_offset: -1.0e-9,
            user_text: Vec::new(),
            source: 0,
            segments: Vec::new(),
            ris_offsets: Vec::new(),
            trigger_time: TriggerTime::default(),
        }
    }
}

impl BlockBuilder {
    /// The block payload (WAVEDESC, arrays) for these codes (all segments one after the other).
    pub fn build(&self, codes: &[i16]) -> Vec<u8> {
        let width = if self.word { 2 } else { 1 };
        let le_to_order = |le: &[u8]| {
            let mut b = le.to_vec();
            if self.order == ByteOrder::HiFirst {
                b.reverse();
            }
            b
        };
        let mut d = vec![0u8; WAVEDESC_LEN];
        let put = |d: &mut Vec<u8>, at: usize, le: &[u8]| {
            let b = le_to_order(le);
            d[at..at + b.len()].copy_from_slice(&b);
        };
        let len = |n: usize| (n as i32).to_le_bytes();
        d[..8].copy_from_slice(NAME);
        d[16..26].copy_from_slice(b"LECROY_2_3");
        put(&mut d, 32, &i16::from(self.word).to_le_bytes());
        put(
            &mut d,
            34,
            &i16::from(self.order == ByteOrder::LoFirst).to_le_bytes(),
        );
        put(&mut d, 36, &len(WAVEDESC_LEN));
        put(&mut d, 40, &len(self.user_text.len()));
        put(&mut d, 48, &len(16 * self.segments.len()));
        put(&mut d, 52, &len(8 * self.ris_offsets.len()));
        put(&mut d, 60, &len(codes.len() * width));
        d[76..83].copy_from_slice(b"RADBNCH");
        put(&mut d, 116, &len(codes.len()));
        put(&mut d, 120, &len(codes.len()));
        put(&mut d, 128, &(codes.len() as i32 - 1).to_le_bytes());
        let segments = self.segments.len().max(1);
        put(&mut d, 144, &len(segments));
        put(&mut d, 148, &1i32.to_le_bytes());
        put(&mut d, 156, &self.gain.to_le_bytes());
        put(&mut d, 160, &self.offset.to_le_bytes());
        put(&mut d, 172, &8i16.to_le_bytes());
        put(&mut d, 174, &(segments as i16).to_le_bytes());
        put(&mut d, 176, &self.interval.to_le_bytes());
        put(&mut d, 180, &self.horiz_offset.to_le_bytes());
        d[196..197].copy_from_slice(b"V");
        d[244..245].copy_from_slice(b"S");
        let t = self.trigger_time;
        put(&mut d, 296, &t.seconds.to_le_bytes());
        d[304..308].copy_from_slice(&[t.minute, t.hour, t.day, t.month]);
        put(&mut d, 308, &t.year.to_le_bytes());
        put(&mut d, 344, &self.source.to_le_bytes());
        d.extend_from_slice(&self.user_text);
        for (time, offset) in &self.segments {
            d.extend_from_slice(&le_to_order(&time.to_le_bytes()));
            d.extend_from_slice(&le_to_order(&offset.to_le_bytes()));
        }
        for r in &self.ris_offsets {
            d.extend_from_slice(&le_to_order(&r.to_le_bytes()));
        }
        for c in codes {
            if self.word {
                d.extend_from_slice(&le_to_order(&c.to_le_bytes()));
            } else {
                d.push(*c as i8 as u8);
            }
        }
        d
    }
}
