//! Incremental decoders: the [`Decode`] trait every codec implements and the header-plus-payload
//! frames of HiSLIP and VICP.

use super::buffers::reserve_announced;
use crate::transport::error::CodecError;
use bytes::{Buf, Bytes, BytesMut};

/// Every item `decoder` gives for `chunks` arriving one after the other, or its first error (the
/// codecs' unit tests; the conformance harness is tests/io_fuzz.rs).
#[cfg(test)]
pub(crate) fn decode_chunks<D: Decode>(
    mut decoder: D,
    chunks: &[&[u8]],
) -> Result<Vec<D::Item>, CodecError> {
    let mut buf = BytesMut::new();
    let mut out = Vec::new();
    for chunk in chunks {
        buf.extend_from_slice(chunk);
        while let Some(item) = decoder.decode(&mut buf)? {
            out.push(item);
        }
    }
    Ok(out)
}

/// An incremental decoder: consumes whole frames from the front of `src`, leaves partial ones.
pub trait Decode {
    type Item;
    /// Returns a frame when `src` holds a whole one. May reserve space in `src` for a frame whose
    /// length it has read (after checking the length against its limit).
    fn decode(&mut self, src: &mut BytesMut) -> Result<Option<Self::Item>, CodecError>;
    /// The total size of the frame being decoded, once its header announced it (0 if unknown).
    fn announced(&self) -> u64 {
        0
    }
}

/// A fixed-size header that announces the length of the payload after it (HiSLIP, VICP).
pub trait FrameHeader: Copy {
    /// The header's size on the wire.
    const LEN: usize;
    /// The protocol's name, for errors.
    const FORMAT: &'static str;
    /// Reads a header from exactly [`LEN`](Self::LEN) bytes.
    fn parse(bytes: &[u8]) -> Result<Self, CodecError>;
    /// The payload length it announces.
    fn payload_len(&self) -> u64;
}

/// A header and its payload.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Framed<H> {
    pub header: H,
    pub payload: Bytes,
}

/// Incremental decoder of header-plus-payload frames with a payload limit: a header is parsed
/// (and its length checked) as soon as its bytes are there, the payload once it is complete.
#[derive(Debug, Clone)]
pub struct FramedDecoder<H> {
    limit: u64,
    pending: Option<H>,
}

impl<H> FramedDecoder<H> {
    pub fn new(limit: u64) -> Self {
        Self {
            limit,
            pending: None,
        }
    }
}

impl<H: FrameHeader> Decode for FramedDecoder<H> {
    type Item = Framed<H>;

    fn decode(&mut self, src: &mut BytesMut) -> Result<Option<Framed<H>>, CodecError> {
        let header = match self.pending {
            Some(h) => h,
            None => {
                if src.len() < H::LEN {
                    return Ok(None);
                }
                let h = H::parse(&src[..H::LEN])?;
                if h.payload_len() > self.limit {
                    return Err(CodecError::TooLarge {
                        format: H::FORMAT,
                        announced: h.payload_len(),
                        limit: self.limit,
                    });
                }
                src.advance(H::LEN);
                self.pending = Some(h);
                h
            }
        };
        let len = header.payload_len() as usize;
        if src.len() < len {
            reserve_announced(src, len - src.len(), self.limit);
            return Ok(None);
        }
        self.pending = None;
        let payload = src.split_to(len).freeze();
        Ok(Some(Framed { header, payload }))
    }

    fn announced(&self) -> u64 {
        self.pending.map_or(0, |h| h.payload_len() + H::LEN as u64)
    }
}
