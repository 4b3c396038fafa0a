//! LeCroy waveform blocks: the WAVEDESC descriptor (template `LECROY_2_3`, 346 bytes,
//! instruments.md section 2.6) decoded to volts and a time axis, and the raw block kept so it can be
//! saved as a `.trc` file (`#9<len>` + WAVEDESC + arrays) that LeCroy's tools and lecroyparser read.
//!
//! Pure: no I/O. Every length field is checked against the block size before it is used; a
//! truncated or inconsistent block gives a [`TrcError`] naming the field, never a panic.
//!
//! Scaling: `volts = VERTICAL_GAIN * code - VERTICAL_OFFSET`, `t_i = i * HORIZ_INTERVAL +
//! HORIZ_OFFSET` (HORIZ_OFFSET is the time from the trigger to the first sample, negative when
//! the record starts before the trigger).

use bytes::Bytes;

/// Bytes of the descriptor in template `LECROY_2_3`.
pub const WAVEDESC_LEN: usize = 346;
const NAME: &[u8] = b"WAVEDESC";
/// How far into a block the descriptor name may start (some firmware puts a short prefix first).
const NAME_SEARCH: usize = 64;

/// Why a waveform block or `.trc` file cannot be decoded.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum TrcError {
    #[error("the waveform block has no WAVEDESC descriptor in its first {NAME_SEARCH} bytes; it is not a LeCroy waveform")]
    NoDescriptor,
    #[error("the waveform block is truncated: {field} needs bytes up to {needed}, the block holds {have}; read the waveform again (raise the read timeout if the link is slow)")]
    Truncated {
        field: &'static str,
        needed: u64,
        have: u64,
    },
    #[error("WAVEDESC field {field} = {value} is not valid: {reason}")]
    BadField {
        field: &'static str,
        value: String,
        reason: &'static str,
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

/// The fields of WAVEDESC radbench uses (and reports in its manifest).
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
    pub instrument_name: String,
    pub instrument_number: i32,
    pub trace_label: String,
    pub wave_array_count: u32,
    pub first_valid_pnt: i32,
    pub last_valid_pnt: i32,
    pub first_point: i32,
    pub sparsing_factor: i32,
    pub segment_index: i32,
    pub subarray_count: i32,
    pub vertical_gain: f32,
    pub vertical_offset: f32,
    pub nominal_bits: i16,
    pub horiz_interval: f32,
    pub horiz_offset: f64,
    pub vertunit: String,
    pub horunit: String,
    pub acq_duration: f32,
    pub record_type: i16,
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
        let raw = &self.desc[offset..offset + len];
        let end = raw.iter().position(|b| *b == 0).unwrap_or(len);
        String::from_utf8_lossy(&raw[..end]).trim().to_string()
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

impl WaveDesc {
    /// Decodes the descriptor at the start of `desc` (at least [`WAVEDESC_LEN`] bytes).
    pub fn decode(desc: &[u8]) -> Result<WaveDesc, TrcError> {
        if desc.len() < WAVEDESC_LEN {
            return Err(TrcError::Truncated {
                field: "WAVEDESC",
                needed: WAVEDESC_LEN as u64,
                have: desc.len() as u64,
            });
        }
        let order = match (desc[34], desc[35]) {
            (1, 0) => ByteOrder::LoFirst,
            (0, 0) => ByteOrder::HiFirst,
            (a, b) => {
                return Err(TrcError::BadField {
                    field: "COMM_ORDER",
                    value: format!("bytes {a:#04x} {b:#04x}"),
                    reason: "must be 0 (HIFIRST) or 1 (LOFIRST)",
                })
            }
        };
        let r = Reader { desc, order };
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
        let d = WaveDesc {
            template_name: r.text(16, 16),
            comm_type,
            order,
            wave_descriptor,
            user_text: r.length("USER_TEXT", 40)?,
            res_desc1: r.length("RES_DESC1", 44)?,
            trigtime_array: r.length("TRIGTIME_ARRAY", 48)?,
            ris_time_array: r.length("RIS_TIME_ARRAY", 52)?,
            res_array1: r.length("RES_ARRAY1", 56)?,
            wave_array_1: r.length("WAVE_ARRAY_1", 60)?,
            wave_array_2: r.length("WAVE_ARRAY_2", 64)?,
            instrument_name: r.text(76, 16),
            instrument_number: r.i32(92),
            trace_label: r.text(96, 16),
            wave_array_count: r.length("WAVE_ARRAY_COUNT", 116)?,
            first_valid_pnt: r.i32(124),
            last_valid_pnt: r.i32(128),
            first_point: r.i32(132),
            sparsing_factor: r.i32(136),
            segment_index: r.i32(140),
            subarray_count: r.i32(144),
            vertical_gain: r.f32(156),
            vertical_offset: r.f32(160),
            nominal_bits: r.i16(172),
            horiz_interval: r.f32(176),
            horiz_offset: r.f64(180),
            vertunit: r.text(196, 48),
            horunit: r.text(244, 48),
            acq_duration: r.f32(312),
            record_type: r.i16(316),
            wave_source: r.i16(344),
        };
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
        finite("VERTICAL_GAIN", f64::from(d.vertical_gain))?;
        finite("VERTICAL_OFFSET", f64::from(d.vertical_offset))?;
        finite("HORIZ_OFFSET", d.horiz_offset)?;
        if !(d.horiz_interval.is_finite() && d.horiz_interval > 0.0) {
            return Err(TrcError::BadField {
                field: "HORIZ_INTERVAL",
                value: d.horiz_interval.to_string(),
                reason: "the sample interval must be a positive number",
            });
        }
        Ok(d)
    }

    /// Bytes per sample of the data arrays.
    pub fn sample_width(&self) -> u64 {
        if self.comm_type == 1 {
            2
        } else {
            1
        }
    }
}

/// One channel of one acquisition: the decoded descriptor, the samples as codes, and the raw
/// block they came from (for saving as `.trc`).
#[derive(Debug, Clone)]
pub struct Trace {
    /// 1-based channel number (C1 = 1).
    pub channel: u8,
    pub desc: WaveDesc,
    /// The samples as the scope's signed codes (16-bit in WORD format, 8-bit in BYTE format).
    pub codes: Vec<i16>,
    /// The block payload: WAVEDESC and its arrays, exactly as received.
    block: Bytes,
}

fn end_of(field: &'static str, start: u64, len: u64, have: u64) -> Result<u64, TrcError> {
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
        });
    }
    Ok(end)
}

impl Trace {
    /// Decodes a block payload (what follows `#9<len>`).
    pub fn decode(channel: u8, block: Bytes) -> Result<Trace, TrcError> {
        let start = block
            .windows(NAME.len())
            .take(NAME_SEARCH)
            .position(|w| w == NAME)
            .ok_or(TrcError::NoDescriptor)?;
        let body = &block[start..];
        let desc = WaveDesc::decode(body)?;
        let have = body.len() as u64;
        let mut at = end_of("WAVE_DESCRIPTOR", 0, u64::from(desc.wave_descriptor), have)?;
        for (field, len) in [
            ("USER_TEXT", desc.user_text),
            ("RES_DESC1", desc.res_desc1),
            ("TRIGTIME_ARRAY", desc.trigtime_array),
            ("RIS_TIME_ARRAY", desc.ris_time_array),
            ("RES_ARRAY1", desc.res_array1),
        ] {
            at = end_of(field, at, u64::from(len), have)?;
        }
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
        let data = &body[at as usize..data_end as usize];
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
            block: block.slice(start..),
        })
    }

    /// Reads a `.trc` file's bytes (`#9<len>` + WAVEDESC + arrays).
    pub fn from_trc_bytes(channel: u8, file: Bytes) -> Result<Trace, TrcError> {
        let header_ok = file.len() >= 11
            && file.starts_with(b"#9")
            && file[2..11].iter().all(u8::is_ascii_digit);
        if !header_ok {
            return Err(TrcError::BadFileHeader {
                start: String::from_utf8_lossy(&file[..file.len().min(11)]).into_owned(),
            });
        }
        let len: u64 = std::str::from_utf8(&file[2..11])
            .ok()
            .and_then(|s| s.parse().ok())
            .ok_or(TrcError::BadFileHeader {
                start: String::from_utf8_lossy(&file[..11]).into_owned(),
            })?;
        let end = end_of("file length", 11, len, file.len() as u64)?;
        Trace::decode(channel, file.slice(11..end as usize))
    }

    /// The samples in volts: `VERTICAL_GAIN * code - VERTICAL_OFFSET`.
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
    pub fn times(&self) -> Vec<f64> {
        let dt = self.sample_interval_s();
        let t0 = self.first_sample_s();
        (0..self.codes.len()).map(|i| i as f64 * dt + t0).collect()
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

/// Builds a WAVEDESC block (tests, and the golden files the interop check reads).
#[derive(Debug, Clone)]
pub struct BlockBuilder {
    pub order: ByteOrder,
    pub word: bool,
    pub gain: f32,
    pub offset: f32,
    pub interval: f32,
    pub horiz_offset: f64,
    pub user_text: Vec<u8>,
    pub source: i16,
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
        }
    }
}

impl BlockBuilder {
    /// The block payload (WAVEDESC, user text, one data array) for these codes.
    pub fn build(&self, codes: &[i16]) -> Vec<u8> {
        let width = if self.word { 2 } else { 1 };
        let mut d = vec![0u8; WAVEDESC_LEN];
        let put = |d: &mut Vec<u8>, at: usize, le: &[u8]| {
            let mut b = le.to_vec();
            if self.order == ByteOrder::HiFirst {
                b.reverse();
            }
            d[at..at + b.len()].copy_from_slice(&b);
        };
        d[..8].copy_from_slice(NAME);
        d[16..26].copy_from_slice(b"LECROY_2_3");
        put(&mut d, 32, &i16::from(self.word).to_le_bytes());
        put(
            &mut d,
            34,
            &i16::from(self.order == ByteOrder::LoFirst).to_le_bytes(),
        );
        put(&mut d, 36, &(WAVEDESC_LEN as i32).to_le_bytes());
        put(&mut d, 40, &(self.user_text.len() as i32).to_le_bytes());
        put(&mut d, 60, &((codes.len() * width) as i32).to_le_bytes());
        d[76..83].copy_from_slice(b"RADBNCH");
        put(&mut d, 116, &(codes.len() as i32).to_le_bytes());
        put(&mut d, 120, &(codes.len() as i32).to_le_bytes());
        put(&mut d, 128, &(codes.len() as i32 - 1).to_le_bytes());
        put(&mut d, 144, &1i32.to_le_bytes());
        put(&mut d, 148, &1i32.to_le_bytes());
        put(&mut d, 156, &self.gain.to_le_bytes());
        put(&mut d, 160, &self.offset.to_le_bytes());
        put(&mut d, 172, &8i16.to_le_bytes());
        put(&mut d, 176, &self.interval.to_le_bytes());
        put(&mut d, 180, &self.horiz_offset.to_le_bytes());
        d[196..197].copy_from_slice(b"V");
        d[244..245].copy_from_slice(b"S");
        put(&mut d, 344, &self.source.to_le_bytes());
        d.extend_from_slice(&self.user_text);
        for c in codes {
            if self.word {
                match self.order {
                    ByteOrder::LoFirst => d.extend_from_slice(&c.to_le_bytes()),
                    ByteOrder::HiFirst => d.extend_from_slice(&c.to_be_bytes()),
                }
            } else {
                d.push(*c as i8 as u8);
            }
        }
        d
    }
}

#[cfg(test)]
mod tests {
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
    fn trc_file_round_trips() {
        let block = BlockBuilder::default().build(&[1, 2, 3, 4]);
        let trace = Trace::decode(1, Bytes::from(block.clone())).unwrap();
        let file = trace.trc_bytes();
        assert!(file.starts_with(format!("#9{:09}", block.len()).as_bytes()));
        let back = Trace::from_trc_bytes(1, Bytes::from(file)).unwrap();
        assert_eq!(back.codes, trace.codes);
        assert!(Trace::from_trc_bytes(1, Bytes::from_static(b"WAVEDESC")).is_err());
    }

    #[test]
    fn every_truncation_is_an_error_not_a_panic() {
        let block = BlockBuilder {
            user_text: vec![b'x'; 10],
            ..BlockBuilder::default()
        }
        .build(&[1, 2, 3, 4, 5]);
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
        block[34] = 7;
        assert!(Trace::decode(1, Bytes::from(block))
            .unwrap_err()
            .to_string()
            .contains("COMM_ORDER"));
    }

    #[test]
    fn arbitrary_bytes_never_panic() {
        let mut rng = crate::rng::SplitMix64::new(7);
        let base = BlockBuilder::default().build(&[10; 16]);
        for _ in 0..2000 {
            let mut b = base.clone();
            for _ in 0..4 {
                let at = (rng.next_u64() % b.len() as u64) as usize;
                b[at] = rng.next_u64() as u8;
            }
            let _ = Trace::decode(1, Bytes::from(b));
        }
    }
}
