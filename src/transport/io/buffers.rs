//! Receive buffers that grow with what arrives, never past the largest message, and messages put
//! together from several frames.

use crate::transport::error::{CodecError, LinkError};
use bytes::{Bytes, BytesMut};

/// Framing overhead allowed on top of the largest message in a receive buffer: headers, record
/// marks, XDR fields, and the start of the next frame read along with this one.
const FRAMING_SLACK: usize = 64 << 10;

/// The most a receive buffer holds for messages of at most `max_message` bytes.
pub fn buffer_ceiling(max_message: usize) -> usize {
    max_message
        .saturating_add(FRAMING_SLACK)
        .saturating_add(RECLAIM_SLACK)
}

/// Makes room for `additional` more bytes in `buf` without letting its capacity pass `ceiling`
/// (unless `additional` itself needs more): far below the ceiling, the usual amortised doubling;
/// near it, one exact allocation. A message that never ends therefore costs at most its limit,
/// not the 1.5x to 2x a doubling buffer overshoots by.
pub fn reserve_within(buf: &mut BytesMut, additional: usize, ceiling: usize) {
    if buf.capacity() - buf.len() >= additional || buf.try_reclaim(additional) {
        return;
    }
    let needed = buf.len().saturating_add(additional);
    let doubled = buf.capacity().saturating_mul(2).max(needed);
    if doubled <= ceiling / 2 {
        buf.reserve(additional);
    } else {
        // Through the Vec: an unshared buffer is taken without a copy and grown by realloc, which
        // for a large block remaps its pages rather than holding old and new side by side.
        let target = doubled.min(ceiling).max(needed);
        let mut bytes: Vec<u8> = std::mem::take(buf).into();
        bytes.reserve_exact(target - bytes.len());
        // Spare capacity, so Bytes keeps the Vec whole and hands it back unshared: no copy.
        *buf = BytesMut::from(bytes::Bytes::from(bytes));
    }
}

/// A reply of `total` bytes (so far) over the `limit` of the largest message.
fn reply_too_large(protocol: &'static str, total: u64, limit: usize) -> LinkError {
    LinkError::Codec {
        protocol,
        source: CodecError::TooLarge {
            format: protocol,
            announced: total,
            limit: limit as u64,
        },
    }
}

/// Appends one frame's payload to a message assembled from several frames, refusing a message
/// over `limit` bytes (a peer that never sends the last frame) before growing the buffer.
fn append_within(
    message: &mut BytesMut,
    data: &[u8],
    limit: usize,
    protocol: &'static str,
) -> Result<(), LinkError> {
    let total = message.len() as u64 + data.len() as u64;
    if total > limit as u64 {
        return Err(reply_too_large(protocol, total, limit));
    }
    reserve_within(message, data.len(), limit);
    message.extend_from_slice(data);
    Ok(())
}

/// One message put together from the frames that carry it (HiSLIP Data, VICP blocks, VXI-11
/// reads). A message of one frame is passed on as it came, a shared `Bytes` with no copy; only a
/// message of several frames is copied into one buffer, and never past the limit.
pub(crate) struct Reassembly {
    first: Option<Bytes>,
    rest: BytesMut,
    limit: usize,
    protocol: &'static str,
}

impl Reassembly {
    pub(crate) fn new(limit: usize, protocol: &'static str) -> Self {
        Reassembly {
            first: None,
            rest: BytesMut::new(),
            limit,
            protocol,
        }
    }

    /// Adds the next frame's payload; a message past the limit is an error.
    pub(crate) fn push(&mut self, payload: Bytes) -> Result<(), LinkError> {
        match &self.first {
            None if payload.len() > self.limit => Err(reply_too_large(
                self.protocol,
                payload.len() as u64,
                self.limit,
            )),
            None => {
                self.first = Some(payload);
                Ok(())
            }
            Some(head) => {
                if self.rest.is_empty() {
                    append_within(&mut self.rest, head, self.limit, self.protocol)?;
                }
                append_within(&mut self.rest, &payload, self.limit, self.protocol)
            }
        }
    }

    /// Drops what came so far (it belonged to an abandoned message); returns how many bytes.
    pub(crate) fn abandon(&mut self) -> usize {
        let dropped = self
            .first
            .take()
            .map_or(0, |f| f.len())
            .max(self.rest.len());
        self.rest.clear();
        dropped
    }

    /// The whole message.
    pub(crate) fn finish(self) -> Bytes {
        if self.rest.is_empty() {
            self.first.unwrap_or_default()
        } else {
            self.rest.freeze()
        }
    }
}

/// Largest reservation made from a length field alone (after its check against the limit): a
/// frame announced larger grows as its bytes actually arrive, so a peer's claim cannot make us
/// reserve more than this up front. Big enough for a 64 MB block in one piece.
pub(crate) const PRESIZE_LIMIT: usize = 128 << 20;

/// Makes room for `wanted` more bytes of a frame whose length a header announced (already
/// checked against the limit), at most `PRESIZE_LIMIT`: the payload is then read straight
/// into place, without regrowth copies.
pub fn reserve_announced(src: &mut BytesMut, wanted: usize, limit: u64) {
    let ceiling = buffer_ceiling(usize::try_from(limit).unwrap_or(usize::MAX));
    let wanted = wanted.min(PRESIZE_LIMIT);
    if src.capacity() - src.len() >= wanted {
        return;
    }
    // A large buffer gets room beyond this frame: once the caller has dropped the frame, the
    // buffer is reclaimed whole for the next one, and the next frame of the same size needs its
    // header (and the start of whatever follows) to fit as well, or the buffer is reallocated and
    // what was already read copied over. Measured: the repeated 64 MB read then touches no fresh
    // pages and makes no copy in user space.
    let wanted = if wanted >= HUGE_PAGE {
        (wanted + RECLAIM_SLACK).min(PRESIZE_LIMIT)
    } else {
        wanted
    };
    reserve_within(src, wanted, ceiling);
    if wanted >= HUGE_PAGE {
        let spare = src.spare_capacity_mut();
        advise_huge_pages(spare.as_mut_ptr().cast(), spare.len());
    }
}

const HUGE_PAGE: usize = 2 << 20;
/// Extra room given to large frame buffers (see [`reserve_announced`]): more than any frame
/// header plus one read's worth of what follows it.
const RECLAIM_SLACK: usize = READ_CHUNK + MIN_READ_SPACE;

/// Asks the kernel for transparent huge pages on the whole 2 MiB pages inside `ptr..ptr+len`
/// (memory this process owns and has not touched yet). A 64 MB receive buffer then costs 32 page
/// faults instead of 16 384, and the kernel's copy into it far fewer TLB misses. Advisory only:
/// contents are unchanged and failure is harmless (THP off, not Linux).
fn advise_huge_pages(ptr: *mut u8, len: usize) {
    #[cfg(target_os = "linux")]
    {
        let start = (ptr as usize).next_multiple_of(HUGE_PAGE);
        let end = (ptr as usize + len) / HUGE_PAGE * HUGE_PAGE;
        if end > start {
            // SAFETY: the range lies inside an allocation we own; MADV_HUGEPAGE changes neither
            // the mapping nor its contents, only how the kernel backs it.
            unsafe {
                libc::madvise(start as *mut libc::c_void, end - start, libc::MADV_HUGEPAGE);
            }
        }
    }
    #[cfg(not(target_os = "linux"))]
    let _ = (ptr, len);
}

pub(super) const MIN_READ_SPACE: usize = 16 << 10;
pub(super) const READ_CHUNK: usize = 256 << 10;

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn buffers_stop_growing_at_their_ceiling() {
        let ceiling = 1 << 20;
        let mut buf = BytesMut::new();
        while buf.len() < ceiling - 4096 {
            reserve_within(&mut buf, 4096, ceiling);
            assert!(buf.capacity() <= ceiling, "{}", buf.capacity());
            let n = buf.capacity() - buf.len();
            buf.extend_from_slice(&vec![0; n.min(4096)]);
        }
        // A request beyond the ceiling still gets what it needs, no more.
        reserve_within(&mut buf, ceiling, ceiling);
        assert!(buf.capacity() >= buf.len() + ceiling);
        assert!(buf.capacity() <= 2 * ceiling);
        let mut message = BytesMut::new();
        append_within(&mut message, &[1; 100], 150, "test").unwrap();
        let err = append_within(&mut message, &[1; 51], 150, "test").unwrap_err();
        assert!(err.to_string().contains("151 bytes"), "{err}");
        assert_eq!(message.len(), 100);
    }
}
