//! Recycled large buffers. An instrument that replaces a stored 64 MB block hands the old buffer
//! back here, and the next large upload is read straight into it: memory that is already mapped,
//! instead of 16 000 fresh pages faulted in and zeroed by the kernel on every upload (which cost
//! as much as the socket copy itself).
//!
//! Buffers are only ever reused through their spare capacity: the bytes a new message lands on
//! are written before they are read, so nothing of an old block can leak into a new message.

use std::sync::Mutex;

use bytes::Bytes;

/// Smaller buffers are not worth keeping: the allocator reuses them on its own.
pub(crate) const MIN_RECYCLED: usize = 1 << 20;
/// Buffers kept at most (a stored block plus one upload in flight, per instrument in use).
const MAX_KEPT: usize = 4;
/// Largest reservation made from a length field alone; a message announced larger grows as its
/// bytes actually arrive, so a peer's claim cannot make us reserve more than this up front.
pub(crate) const PRESIZE_LIMIT: usize = 128 << 20;

static POOL: Mutex<Vec<Vec<u8>>> = Mutex::new(Vec::new());

fn pool() -> std::sync::MutexGuard<'static, Vec<Vec<u8>>> {
    POOL.lock().unwrap_or_else(|poisoned| poisoned.into_inner())
}

/// Gives the buffer behind `bytes` back when nothing else shares it and it is large; otherwise
/// simply drops it (a reply still being sent keeps its own reference).
pub(crate) fn recycle(bytes: Bytes) {
    let Ok(mut whole) = bytes.try_into_mut() else {
        return;
    };
    // Empty first: turning an empty BytesMut into a Vec moves no bytes.
    whole.clear();
    let buf: Vec<u8> = whole.into();
    if buf.capacity() < MIN_RECYCLED {
        return;
    }
    let mut kept = pool();
    if kept.len() < MAX_KEPT {
        kept.push(buf);
    }
}

/// An empty buffer with room for at least `capacity` bytes, if the pool has one (the smallest
/// that fits).
pub(crate) fn take(capacity: usize) -> Option<Vec<u8>> {
    let mut kept = pool();
    let best = kept
        .iter()
        .enumerate()
        .filter(|(_, b)| b.capacity() >= capacity)
        .min_by_key(|(_, b)| b.capacity())
        .map(|(i, _)| i)?;
    Some(kept.swap_remove(best))
}

/// Makes room for `additional` more bytes in `buf` (an announced length, already checked against
/// the maximum message size). At most [`PRESIZE_LIMIT`] is reserved; large reservations come
/// from the pool when it has a buffer, the few bytes already in `buf` (a message header) moving
/// over. A buffer already holding much grows in place instead (no copy of what it holds).
pub(crate) fn reserve(buf: &mut Vec<u8>, additional: usize) {
    let additional = additional.min(PRESIZE_LIMIT);
    if buf.capacity() - buf.len() >= additional {
        return;
    }
    if additional >= MIN_RECYCLED && buf.len() < MIN_RECYCLED {
        if let Some(mut recycled) = take(buf.len() + additional) {
            recycled.extend_from_slice(buf);
            *buf = recycled;
            return;
        }
    }
    buf.reserve(additional);
    if additional >= HUGE_PAGE {
        let spare = buf.spare_capacity_mut();
        advise_huge_pages(spare.as_mut_ptr().cast(), spare.len());
    }
}

const HUGE_PAGE: usize = 2 << 20;

/// Asks the kernel for transparent huge pages on the whole 2 MiB pages inside `ptr..ptr+len`
/// (fresh memory this process owns): a 64 MB buffer then costs 32 page faults instead of
/// 16 384, and the kernel's copies into and out of it fewer TLB misses. Advisory only: contents
/// are unchanged and failure is harmless.
fn advise_huge_pages(ptr: *mut u8, len: usize) {
    let start = (ptr as usize).next_multiple_of(HUGE_PAGE);
    let end = (ptr as usize + len) / HUGE_PAGE * HUGE_PAGE;
    if end > start {
        // SAFETY: the range lies inside an allocation we own; MADV_HUGEPAGE changes neither the
        // mapping nor its contents, only how the kernel backs it.
        unsafe {
            libc::madvise(start as *mut libc::c_void, end - start, libc::MADV_HUGEPAGE);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn shared_buffers_are_not_recycled_and_reserve_keeps_the_prefix() {
        let big = Bytes::from(vec![7u8; MIN_RECYCLED]);
        let other = big.clone();
        recycle(big);
        assert_eq!(other.len(), MIN_RECYCLED, "a shared buffer stays intact");
        // The pool is process-wide (other tests may fill or drain it): only check behaviour
        // that holds either way.
        let mut buf = b"DATA #8".to_vec();
        reserve(&mut buf, 2 * MIN_RECYCLED);
        assert_eq!(buf, b"DATA #8");
        assert!(buf.capacity() >= 2 * MIN_RECYCLED + 7);
        let mut small = Vec::new();
        reserve(&mut small, usize::MAX);
        assert!(small.capacity() >= PRESIZE_LIMIT);
    }

    #[test]
    fn a_recycled_buffer_comes_back_empty() {
        recycle(Bytes::from(vec![1u8; 3 * MIN_RECYCLED + 5]).slice(10..20));
        if let Some(buf) = take(3 * MIN_RECYCLED) {
            assert!(buf.is_empty());
            assert!(buf.capacity() >= 3 * MIN_RECYCLED);
        }
    }
}
