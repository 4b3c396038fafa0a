//! Where the transmitted bits come from, how a payload is framed into them, and how it comes back.
//!
//! # Bit order
//! Bits are `u8` values 0 or 1. Every byte is sent least significant bit first (the same order in
//! which [`SplitMix64::bits`] takes bits from its words), so byte `0x01` becomes bits `1,0,0,0,0,0,0,0`.
//!
//! # Payload framing
//! A payload of `n` bytes is sent as
//!
//! | field | bits | content |
//! |---|---|---|
//! | length header | 32 | `n` as an unsigned 32-bit integer, LSB first |
//! | payload | 8 n | the bytes, each LSB first |
//! | padding | to the end of the last pulse / frame | PRBS from [`SplitMix64`] seeded with `PADDING_SEED` |
//!
//! The number of pulses (MSK-LFM) or frames (OFDM) is the smallest whole number that holds header and
//! payload (and at least the number the caller asked for). Padding is pseudo-random rather than zeros
//! so a short payload does not turn the radar waveform into a periodic one (all-zero OFDM symbols
//! are identical and give a spiky, high-crest-factor signal).

use super::{DecodeError, ParamError};
use crate::rng::SplitMix64;

/// Seed of the PRBS that pads a payload to whole pulses or frames ("RADBENCH" in ASCII).
pub(crate) const PADDING_SEED: u64 = 0x5241_4442_454E_4348;

/// Bits in the payload length header.
pub(crate) const HEADER_BITS: usize = 32;

/// Where a transmission's bits come from.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum BitSource {
    /// Pseudo-random bits from [`SplitMix64`] with this seed (LSB first from successive words).
    Prbs { seed: u64 },
    /// A user payload, framed as described in the module docs.
    Payload(Vec<u8>),
}

impl BitSource {
    /// A text payload, sent as its UTF-8 bytes.
    pub fn text(text: &str) -> Self {
        BitSource::Payload(text.as_bytes().to_vec())
    }
}

/// The bits of a transmission cut into whole units (pulses or frames).
#[derive(Debug, Clone, PartialEq, Eq)]
pub(crate) struct FramedBits {
    /// All transmitted bits, `units * bits_per_unit` of them.
    pub bits: Vec<u8>,
    /// How many pulses or frames the bits fill.
    pub units: usize,
    /// Payload length in bytes when the source was a payload.
    pub payload_len: Option<usize>,
}

/// Produces the bits for `source`, filling at least `min_units` units of `bits_per_unit` bits.
///
/// A PRBS fills exactly `max(min_units, 1)` units; a payload as many as it needs (at least
/// `min_units`). Fails when `bits_per_unit` is zero or the payload is longer than the 32-bit header
/// can describe.
pub(crate) fn frame_bits(
    source: &BitSource,
    bits_per_unit: usize,
    min_units: usize,
) -> Result<FramedBits, ParamError> {
    if bits_per_unit == 0 {
        return Err(ParamError::out_of_range(
            "bits per pulse/frame",
            0,
            "must be at least 1",
        ));
    }
    let min_units = min_units.max(1);
    match source {
        BitSource::Prbs { seed } => {
            let bits = SplitMix64::new(*seed).bits(min_units * bits_per_unit);
            Ok(FramedBits {
                bits,
                units: min_units,
                payload_len: None,
            })
        }
        BitSource::Payload(bytes) => {
            let len = u32::try_from(bytes.len()).map_err(|_| {
                ParamError::out_of_range(
                    "payload length",
                    format!("{} bytes", bytes.len()),
                    "at most 4 294 967 295 bytes (32-bit length header)",
                )
            })?;
            let needed = HEADER_BITS + 8 * bytes.len();
            let units = needed.div_ceil(bits_per_unit).max(min_units);
            let mut bits = Vec::with_capacity(units * bits_per_unit);
            push_u32(&mut bits, len);
            for &b in bytes {
                push_byte(&mut bits, b);
            }
            let pad = units * bits_per_unit - bits.len();
            bits.extend(SplitMix64::new(PADDING_SEED).bits(pad));
            Ok(FramedBits {
                bits,
                units,
                payload_len: Some(bytes.len()),
            })
        }
    }
}

/// Recovers a payload framed by `frame_bits` from received hard decisions.
///
/// Fails when the length header asks for more bits than were received (a corrupted header, or a
/// transmission that was not a payload).
///
/// # Errors
///
/// [`DecodeError`] when fewer bits than the 32-bit length header arrived, or the header asks for
/// more bytes than follow it.
pub fn unframe_payload(bits: &[u8]) -> Result<Vec<u8>, DecodeError> {
    if bits.len() < HEADER_BITS {
        return Err(DecodeError {
            message: format!(
                "received {} bits, fewer than the {HEADER_BITS}-bit payload length header",
                bits.len()
            ),
        });
    }
    let len = bits[..HEADER_BITS]
        .iter()
        .enumerate()
        .fold(0u64, |acc, (k, &b)| acc | (u64::from(b & 1) << k)) as usize;
    let available = (bits.len() - HEADER_BITS) / 8;
    if len > available {
        return Err(DecodeError {
            message: format!(
                "payload length header says {len} bytes but only {available} bytes were received: \
                 the header is corrupted (too many bit errors?) or the capture was not a payload"
            ),
        });
    }
    Ok(bits_to_bytes(&bits[HEADER_BITS..HEADER_BITS + 8 * len]))
}

/// Packs bits (LSB first) into bytes; a trailing partial byte is zero-filled in its high bits.
pub(crate) fn bits_to_bytes(bits: &[u8]) -> Vec<u8> {
    bits.chunks(8)
        .map(|c| {
            c.iter()
                .enumerate()
                .fold(0u8, |acc, (k, &b)| acc | ((b & 1) << k))
        })
        .collect()
}

/// Unpacks bytes into bits, each byte LSB first.
#[cfg(test)]
pub(crate) fn bytes_to_bits(bytes: &[u8]) -> Vec<u8> {
    let mut bits = Vec::with_capacity(bytes.len() * 8);
    for &b in bytes {
        push_byte(&mut bits, b);
    }
    bits
}

/// Number of positions where `a` and `b` differ, over the shorter of the two.
pub(crate) fn count_bit_errors(a: &[u8], b: &[u8]) -> usize {
    a.iter()
        .zip(b)
        .filter(|(x, y)| (*x & 1) != (*y & 1))
        .count()
}

fn push_byte(bits: &mut Vec<u8>, byte: u8) {
    bits.extend((0..8).map(|k| (byte >> k) & 1));
}

fn push_u32(bits: &mut Vec<u8>, v: u32) {
    bits.extend((0..32).map(|k| ((v >> k) & 1) as u8));
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn byte_bit_order_is_lsb_first() {
        assert_eq!(bytes_to_bits(&[0x01]), vec![1, 0, 0, 0, 0, 0, 0, 0]);
        assert_eq!(bytes_to_bits(&[0x80]), vec![0, 0, 0, 0, 0, 0, 0, 1]);
        assert_eq!(bits_to_bytes(&bytes_to_bits(b"radbench")), b"radbench");
    }

    #[test]
    fn payload_round_trips_and_fills_whole_units() {
        let src = BitSource::text("hello, bench");
        let framed = frame_bits(&src, 128, 1).unwrap();
        // 32 + 12 * 8 = 128 bits: exactly one unit.
        assert_eq!(framed.units, 1);
        assert_eq!(framed.bits.len(), 128);
        assert_eq!(unframe_payload(&framed.bits).unwrap(), b"hello, bench");
        let framed = frame_bits(&BitSource::Payload(vec![7; 100]), 128, 3).unwrap();
        assert_eq!(framed.units, 7); // 832 bits need 7 units of 128
        assert_eq!(unframe_payload(&framed.bits).unwrap(), vec![7; 100]);
    }

    #[test]
    fn empty_payload_and_prbs() {
        let framed = frame_bits(&BitSource::Payload(vec![]), 64, 0).unwrap();
        assert_eq!(framed.units, 1);
        assert!(unframe_payload(&framed.bits).unwrap().is_empty());
        let a = frame_bits(&BitSource::Prbs { seed: 3 }, 10, 2).unwrap();
        assert_eq!(a.bits, SplitMix64::new(3).bits(20));
    }

    #[test]
    fn corrupted_header_is_an_error_not_a_panic() {
        let mut framed = frame_bits(&BitSource::text("x"), 64, 1).unwrap();
        framed.bits[31] = 1; // length now > 2^31
        let err = unframe_payload(&framed.bits).unwrap_err();
        assert!(err.message.contains("corrupted"), "{err}");
        assert!(unframe_payload(&[0; 5]).is_err());
        assert!(frame_bits(&BitSource::text("x"), 0, 1).is_err());
    }
}
