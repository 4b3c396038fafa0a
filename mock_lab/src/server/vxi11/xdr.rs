//! XDR (RFC 4506) reading and writing for the VXI-11 messages: big-endian 32-bit items,
//! opaque data and strings padded to 4 bytes. Pure code.

use thiserror::Error;

/// An XDR body that cannot be decoded.
#[derive(Debug, Error, PartialEq, Eq)]
pub(crate) enum XdrError {
    /// The body ended before the item.
    #[error("XDR data ends early: needed {needed} more bytes at offset {offset}")]
    Truncated {
        /// Offset of the item.
        offset: usize,
        /// Bytes missing.
        needed: usize,
    },
    /// An opaque or string length above what the field allows.
    #[error("XDR opaque of {len} bytes at offset {offset} exceeds the limit of {max} bytes")]
    TooLong {
        /// Offset of the length field.
        offset: usize,
        /// Announced length.
        len: u32,
        /// Limit for this field.
        max: usize,
    },
}

/// Reads XDR items from a byte slice.
#[derive(Debug)]
pub(crate) struct XdrReader<'a> {
    buf: &'a [u8],
    pos: usize,
}

impl<'a> XdrReader<'a> {
    /// A reader at the start of `buf`.
    pub(crate) fn new(buf: &'a [u8]) -> Self {
        XdrReader { buf, pos: 0 }
    }

    /// Bytes not read yet.
    pub(crate) fn remaining(&self) -> usize {
        self.buf.len() - self.pos
    }

    fn take(&mut self, n: usize) -> Result<&'a [u8], XdrError> {
        if self.remaining() < n {
            return Err(XdrError::Truncated {
                offset: self.pos,
                needed: n - self.remaining(),
            });
        }
        let out = &self.buf[self.pos..self.pos + n];
        self.pos += n;
        Ok(out)
    }

    /// An unsigned 32-bit integer.
    pub(crate) fn u32(&mut self) -> Result<u32, XdrError> {
        let b = self.take(4)?;
        Ok(u32::from_be_bytes([b[0], b[1], b[2], b[3]]))
    }

    /// A signed 32-bit integer.
    pub(crate) fn i32(&mut self) -> Result<i32, XdrError> {
        Ok(self.u32()? as i32)
    }

    /// A boolean (any non-zero value is true).
    pub(crate) fn bool(&mut self) -> Result<bool, XdrError> {
        Ok(self.u32()? != 0)
    }

    /// Variable-length opaque data of at most `max` bytes (padding skipped).
    pub(crate) fn opaque(&mut self, max: usize) -> Result<&'a [u8], XdrError> {
        let offset = self.pos;
        let len = self.u32()?;
        if len as usize > max {
            return Err(XdrError::TooLong { offset, len, max });
        }
        let data = self.take(len as usize)?;
        self.take(pad(len as usize))?;
        Ok(data)
    }
}

/// Padding after `len` bytes of opaque data.
pub(crate) fn pad(len: usize) -> usize {
    (4 - len % 4) % 4
}

/// Builds an XDR body.
#[derive(Debug, Default)]
pub(crate) struct XdrWriter {
    /// The encoded bytes.
    pub buf: Vec<u8>,
}

impl XdrWriter {
    /// An empty body.
    pub(crate) fn new() -> Self {
        XdrWriter::default()
    }

    /// Appends an unsigned 32-bit integer.
    pub(crate) fn u32(&mut self, v: u32) -> &mut Self {
        self.buf.extend_from_slice(&v.to_be_bytes());
        self
    }

    /// Appends a signed 32-bit integer.
    pub(crate) fn i32(&mut self, v: i32) -> &mut Self {
        self.u32(v as u32)
    }

    /// Appends opaque data with its length and padding.
    pub(crate) fn opaque(&mut self, data: &[u8]) -> &mut Self {
        self.u32(data.len() as u32);
        self.buf.extend_from_slice(data);
        self.buf.extend(std::iter::repeat_n(0u8, pad(data.len())));
        self
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn golden_opaque_is_padded() {
        let mut w = XdrWriter::new();
        w.i32(-1).opaque(b"inst0");
        assert_eq!(w.buf, b"\xff\xff\xff\xff\x00\x00\x00\x05inst0\x00\x00\x00");
        let mut r = XdrReader::new(&w.buf);
        assert_eq!(r.i32(), Ok(-1));
        assert_eq!(r.opaque(16), Ok(&b"inst0"[..]));
        assert_eq!(r.remaining(), 0);
    }

    #[test]
    fn limits_are_checked_before_reading() {
        let mut r = XdrReader::new(b"\x7f\xff\xff\xff");
        assert!(matches!(r.opaque(100), Err(XdrError::TooLong { .. })));
        let mut r = XdrReader::new(b"\x00\x00");
        assert!(matches!(r.u32(), Err(XdrError::Truncated { .. })));
    }
}
