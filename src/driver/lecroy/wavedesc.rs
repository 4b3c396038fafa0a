//! Decoding a `WF? ALL` block: the `LECROY_2_3` WAVEDESC (offsets of instruments.md 2.6, byte order
//! from COMM_ORDER) and the data array, to volts and a time axis that includes HORIZ_OFFSET.
//! Pure: no I/O. Every length is checked against the bytes present before it is used.

/// Smallest descriptor this decoder reads.
pub const WAVEDESC_MIN_LEN: usize = 346;

/// Why a waveform block could not be decoded.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("LeCroy waveform: {0}")]
pub struct WaveformError(pub String);

/// The descriptor fields radbench uses.
#[derive(Debug, Clone, PartialEq)]
pub struct WaveDesc {
    pub template: String,
    pub instrument_name: String,
    /// 16-bit samples (COMM_TYPE word) rather than 8-bit.
    pub word: bool,
    /// Little endian (COMM_ORDER LOFIRST).
    pub little_endian: bool,
    pub descriptor_len: usize,
    pub user_text_len: usize,
    pub trigtime_len: usize,
    pub ris_time_len: usize,
    pub array1_len: usize,
    pub points: usize,
    pub first_point: u32,
    pub sparsing: u32,
    pub vertical_gain: f32,
    pub vertical_offset: f32,
    pub nominal_bits: i16,
    /// Sample interval in seconds.
    pub horiz_interval: f32,
    /// Time of the first point relative to the trigger, in seconds.
    pub horiz_offset: f64,
    /// 0..=3 for C1..C4.
    pub wave_source: i16,
}

/// One decoded channel: the raw block (for `.trc` files), the descriptor and the sample codes.
#[derive(Debug, Clone, PartialEq)]
pub struct Trace {
    pub desc: WaveDesc,
    /// Samples as transmitted (WORD values, or BYTE values widened).
    pub codes: Vec<i16>,
    /// `#9<len>` + WAVEDESC + arrays: exactly a `.trc` file.
    pub trc: Vec<u8>,
}

impl Trace {
    /// Volts per sample: `VERTICAL_GAIN x code - VERTICAL_OFFSET`.
    pub fn volts(&self) -> Vec<f64> {
        let gain = f64::from(self.desc.vertical_gain);
        let offset = f64::from(self.desc.vertical_offset);
        self.codes
            .iter()
            .map(|c| gain * f64::from(*c) - offset)
            .collect()
    }

    /// Time of sample `i` relative to the trigger: `i x HORIZ_INTERVAL + HORIZ_OFFSET`.
    pub fn time(&self, i: usize) -> f64 {
        i as f64 * f64::from(self.desc.horiz_interval) + self.desc.horiz_offset
    }

    pub fn times(&self) -> Vec<f64> {
        (0..self.codes.len()).map(|i| self.time(i)).collect()
    }

    /// Sample rate from HORIZ_INTERVAL.
    pub fn sample_rate(&self) -> f64 {
        1.0 / f64::from(self.desc.horiz_interval)
    }
}

struct Reader<'a> {
    d: &'a [u8],
    little: bool,
}

impl Reader<'_> {
    fn array<const N: usize>(&self, off: usize) -> [u8; N] {
        let mut out = [0u8; N];
        out.copy_from_slice(&self.d[off..off + N]);
        out
    }
    fn i16(&self, off: usize) -> i16 {
        let b = self.array::<2>(off);
        if self.little {
            i16::from_le_bytes(b)
        } else {
            i16::from_be_bytes(b)
        }
    }
    fn i32(&self, off: usize) -> i32 {
        let b = self.array::<4>(off);
        if self.little {
            i32::from_le_bytes(b)
        } else {
            i32::from_be_bytes(b)
        }
    }
    fn len(&self, off: usize, field: &str) -> Result<usize, WaveformError> {
        usize::try_from(self.i32(off))
            .map_err(|_| WaveformError(format!("{field} at offset {off} is negative")))
    }
    fn f32(&self, off: usize) -> f32 {
        let b = self.array::<4>(off);
        if self.little {
            f32::from_le_bytes(b)
        } else {
            f32::from_be_bytes(b)
        }
    }
    fn f64(&self, off: usize) -> f64 {
        let b = self.array::<8>(off);
        if self.little {
            f64::from_le_bytes(b)
        } else {
            f64::from_be_bytes(b)
        }
    }
    fn string(&self, off: usize, len: usize) -> String {
        let raw = &self.d[off..off + len];
        let end = raw.iter().position(|b| *b == 0).unwrap_or(len);
        String::from_utf8_lossy(&raw[..end]).into_owned()
    }
}

/// Decodes the payload of a `WF? ALL` block (starting at `WAVEDESC`).
pub fn decode(payload: &[u8]) -> Result<Trace, WaveformError> {
    if payload.len() < WAVEDESC_MIN_LEN {
        return Err(WaveformError(format!(
            "the block has {} bytes, less than a {WAVEDESC_MIN_LEN}-byte WAVEDESC",
            payload.len()
        )));
    }
    if &payload[..8] != b"WAVEDESC" {
        return Err(WaveformError(
            "the block does not start with WAVEDESC".into(),
        ));
    }
    // COMM_ORDER is 0 or 1: its low byte is non-zero only in little-endian order.
    let little = payload[34] == 1 && payload[35] == 0;
    let r = Reader { d: payload, little };
    let template = r.string(16, 16);
    if !template.starts_with("LECROY_2") {
        return Err(WaveformError(format!(
            "unknown descriptor template {template:?}"
        )));
    }
    let word = match r.i16(32) {
        0 => false,
        1 => true,
        other => {
            return Err(WaveformError(format!(
                "COMM_TYPE {other} is neither byte (0) nor word (1)"
            )))
        }
    };
    let descriptor_len = r.len(36, "WAVE_DESCRIPTOR")?;
    let user_text_len = r.len(40, "USER_TEXT")?;
    let trigtime_len = r.len(48, "TRIGTIME_ARRAY")?;
    let ris_time_len = r.len(52, "RIS_TIME_ARRAY")?;
    let array1_len = r.len(60, "WAVE_ARRAY_1")?;
    let points = r.len(116, "WAVE_ARRAY_COUNT")?;
    if descriptor_len < WAVEDESC_MIN_LEN {
        return Err(WaveformError(format!(
            "WAVE_DESCRIPTOR {descriptor_len} is below {WAVEDESC_MIN_LEN}"
        )));
    }
    let start = descriptor_len
        .checked_add(user_text_len)
        .and_then(|v| v.checked_add(trigtime_len))
        .and_then(|v| v.checked_add(ris_time_len))
        .ok_or_else(|| WaveformError("block lengths overflow".into()))?;
    let end = start
        .checked_add(array1_len)
        .ok_or_else(|| WaveformError("block lengths overflow".into()))?;
    if end > payload.len() {
        return Err(WaveformError(format!(
            "the descriptor announces {end} bytes, the block has {}",
            payload.len()
        )));
    }
    let width = if word { 2 } else { 1 };
    if points.checked_mul(width) != Some(array1_len) {
        return Err(WaveformError(format!(
            "WAVE_ARRAY_COUNT {points} x {width} bytes does not match WAVE_ARRAY_1 {array1_len}"
        )));
    }
    let data = &payload[start..end];
    let codes: Vec<i16> = if word {
        data.chunks_exact(2)
            .map(|c| {
                if little {
                    i16::from_le_bytes([c[0], c[1]])
                } else {
                    i16::from_be_bytes([c[0], c[1]])
                }
            })
            .collect()
    } else {
        data.iter().map(|b| i16::from(*b as i8)).collect()
    };
    let desc = WaveDesc {
        template,
        instrument_name: r.string(76, 16),
        word,
        little_endian: little,
        descriptor_len,
        user_text_len,
        trigtime_len,
        ris_time_len,
        array1_len,
        points,
        first_point: r.i32(132) as u32,
        sparsing: r.i32(136) as u32,
        vertical_gain: r.f32(156),
        vertical_offset: r.f32(160),
        nominal_bits: r.i16(172),
        horiz_interval: r.f32(176),
        horiz_offset: r.f64(180),
        wave_source: r.i16(344),
    };
    if !(desc.horiz_interval.is_finite() && desc.horiz_interval > 0.0) {
        return Err(WaveformError(format!(
            "HORIZ_INTERVAL {} is not a positive time",
            desc.horiz_interval
        )));
    }
    let mut trc = format!("#9{:09}", payload.len()).into_bytes();
    trc.extend_from_slice(payload);
    Ok(Trace { desc, codes, trc })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn short_or_foreign_blocks_are_errors_not_panics() {
        assert!(decode(b"WAVEDESC").is_err());
        let mut block = vec![0u8; 400];
        assert!(decode(&block).is_err());
        block[..8].copy_from_slice(b"WAVEDESC");
        block[16..26].copy_from_slice(b"LECROY_2_3");
        block[36..40].copy_from_slice(&346i32.to_be_bytes());
        block[60..64].copy_from_slice(&1000i32.to_be_bytes());
        let err = decode(&block).unwrap_err();
        assert!(err.0.contains("announces"), "{err}");
        block[60..64].copy_from_slice(&(-4i32).to_be_bytes());
        assert!(decode(&block).unwrap_err().0.contains("negative"));
    }
}
