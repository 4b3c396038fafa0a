//! Large buffers on transparent huge pages.
//!
//! A one-shot `radbench capture` touches ~70 MB (the waveform's tables, the scope's words and
//! their copies, spectra, file bytes): 13 000-14 000 page faults of 4 KiB, and the kernel then
//! takes 5-6 ms to free them when the process exits (between `exit_group` and the parent seeing
//! the exit, `strace -f -tt`). Every allocation of 1 MiB or more is a mapping of its own, whole
//! 2 MiB pages aligned to 2 MiB and advised `MADV_HUGEPAGE` before it is touched, so the kernel
//! backs it with huge pages where it can: one fault per 2 MiB, and little to free at the exit.
//! Blocks are a power of two of huge pages long; freed ones are kept for reuse by a later
//! allocation of the same length (at most 64 blocks and 512 MiB, as glibc keeps smaller ones,
//! `keep_large_buffers`), so repeated captures do not fault their buffers in again. Where
//! transparent huge pages are off the advice does nothing and the blocks are ordinary pages.
//! `RADBENCH_HUGE_PAGES=off` in the environment leaves every allocation to glibc, as before;
//! `on` turns it on where it is off by default.
//!
//! Linux with glibc only. The command line installs it on by default (`main.rs`: a one-shot
//! process). The Python extension includes this file too (`python/src/lib.rs`) and installs it
//! off unless `RADBENCH_HUGE_PAGES=on`: a notebook's process lives long and its user manages its
//! memory, while a Dask worker that runs unit after unit gains what the command line gains
//! (`radbench.dask.WORKER_CONFIG` sets it for the workers).

use std::alloc::{GlobalAlloc, Layout, System};
use std::sync::Mutex;

/// A transparent huge page.
const HUGE_PAGE: usize = 2 << 20;
/// Allocations from this size on get blocks of their own.
const FROM: usize = 1 << 20;
/// Most freed blocks kept, and most bytes in them.
const KEPT_BLOCKS: usize = 64;
const KEPT_BYTES: usize = 512 << 20;

/// Freed blocks kept for reuse: (address, length), length 0 for an empty slot.
struct Kept {
    blocks: [(usize, usize); KEPT_BLOCKS],
    bytes: usize,
}

static KEPT: Mutex<Kept> = Mutex::new(Kept {
    blocks: [(0, 0); KEPT_BLOCKS],
    bytes: 0,
});

fn kept() -> std::sync::MutexGuard<'static, Kept> {
    KEPT.lock().unwrap_or_else(|p| p.into_inner())
}

pub(crate) struct HugePages {
    /// Whether large allocations get blocks of their own when `RADBENCH_HUGE_PAGES` is unset.
    pub(crate) by_default: bool,
}

/// Whether large allocations get blocks of their own: `by_default` unless the environment
/// says `RADBENCH_HUGE_PAGES=off` (a machine where huge pages are scarce and the kernel's
/// compaction stalls the faults) or `on`. Read once, at the first large allocation, and never
/// changed afterwards, so a block is always freed the way it was made.
fn enabled(by_default: bool) -> bool {
    use std::sync::atomic::{AtomicU8, Ordering};
    const UNKNOWN: u8 = 0;
    const ON: u8 = 1;
    const OFF: u8 = 2;
    static STATE: AtomicU8 = AtomicU8::new(UNKNOWN);
    let known = STATE.load(Ordering::Relaxed);
    if known != UNKNOWN {
        return known == ON;
    }
    // `getenv` allocates nothing (the allocator may not), and radbench never changes its
    // environment: every thread that gets here reads the same answer.
    // SAFETY: a NUL-terminated name; the value, when there is one, is a C string owned by
    // the environment.
    let on = unsafe {
        let value = libc::getenv(c"RADBENCH_HUGE_PAGES".as_ptr());
        match (!value.is_null()).then(|| std::ffi::CStr::from_ptr(value).to_bytes()) {
            Some(b"off") => false,
            Some(b"on") => true,
            _ => by_default,
        }
    };
    STATE.store(if on { ON } else { OFF }, Ordering::Relaxed);
    on
}

/// The block length of a large allocation, `None` for the others: a power of two of huge
/// pages, so that the few lengths there are find kept blocks again (a buffer grown piece by
/// piece, or of a slightly different size the next time, reuses one). Pages of a block that
/// are never touched cost nothing.
fn block(layout: Layout, by_default: bool) -> Option<usize> {
    if layout.size() < FROM || layout.align() > HUGE_PAGE || !enabled(by_default) {
        return None;
    }
    layout
        .size()
        .div_ceil(HUGE_PAGE)
        .checked_next_power_of_two()?
        .checked_mul(HUGE_PAGE)
}

/// A kept block of exactly `len` bytes.
fn reuse(len: usize) -> Option<*mut u8> {
    let mut k = kept();
    let slot = k.blocks.iter().position(|&(_, l)| l == len)?;
    let (addr, _) = std::mem::take(&mut k.blocks[slot]);
    k.bytes -= len;
    Some(addr as *mut u8)
}

/// A new block of `len` bytes (a multiple of `HUGE_PAGE`) aligned to `HUGE_PAGE`, advised
/// for huge pages; null when the kernel has no memory for it.
fn map(len: usize) -> *mut u8 {
    let Some(span) = len.checked_add(HUGE_PAGE) else {
        return std::ptr::null_mut();
    };
    // SAFETY: a fresh private anonymous mapping; only its own parts are unmapped or advised.
    unsafe {
        let raw = libc::mmap(
            std::ptr::null_mut(),
            span,
            libc::PROT_READ | libc::PROT_WRITE,
            libc::MAP_PRIVATE | libc::MAP_ANONYMOUS | libc::MAP_NORESERVE,
            -1,
            0,
        );
        if raw == libc::MAP_FAILED {
            return std::ptr::null_mut();
        }
        let raw = raw as usize;
        let start = raw.next_multiple_of(HUGE_PAGE);
        if start > raw {
            libc::munmap(raw as *mut libc::c_void, start - raw);
        }
        let end = start + len;
        if raw + span > end {
            libc::munmap(end as *mut libc::c_void, raw + span - end);
        }
        libc::madvise(start as *mut libc::c_void, len, libc::MADV_HUGEPAGE);
        start as *mut u8
    }
}

/// Keeps the block at `ptr` of `len` bytes for reuse, or unmaps it.
fn release(ptr: *mut u8, len: usize) {
    {
        let mut k = kept();
        if k.bytes + len <= KEPT_BYTES {
            if let Some(slot) = k.blocks.iter().position(|&(_, l)| l == 0) {
                k.blocks[slot] = (ptr as usize, len);
                k.bytes += len;
                return;
            }
        }
    }
    // SAFETY: the block is a mapping `map` made, no longer used by anyone.
    unsafe {
        libc::munmap(ptr.cast(), len);
    }
}

// SAFETY: small allocations go to the system allocator unchanged; a large one is a block
// of whole huge pages (at least its size, aligned to 2 MiB, so to any alignment up to that)
// used by nobody else until it is freed, and freed with the length it was made with (a
// function of the caller's layout).
unsafe impl GlobalAlloc for HugePages {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        match block(layout, self.by_default) {
            Some(len) => reuse(len).unwrap_or_else(|| map(len)),
            // SAFETY: the caller's contract, passed on unchanged.
            None => unsafe { System.alloc(layout) },
        }
    }

    unsafe fn alloc_zeroed(&self, layout: Layout) -> *mut u8 {
        match block(layout, self.by_default) {
            Some(len) => match reuse(len) {
                Some(ptr) => {
                    // SAFETY: a kept block holds `len >= layout.size()` bytes.
                    unsafe { std::ptr::write_bytes(ptr, 0, layout.size()) };
                    ptr
                }
                // A new anonymous mapping reads as zeros.
                None => map(len),
            },
            // SAFETY: the caller's contract, passed on unchanged.
            None => unsafe { System.alloc_zeroed(layout) },
        }
    }

    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        match block(layout, self.by_default) {
            Some(len) => release(ptr, len),
            // SAFETY: `ptr` came from the system allocator with this layout.
            None => unsafe { System.dealloc(ptr, layout) },
        }
    }

    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        // SAFETY: the caller guarantees `new_size` is valid with `layout.align()`.
        let new_layout = unsafe { Layout::from_size_align_unchecked(new_size, layout.align()) };
        match (
            block(layout, self.by_default),
            block(new_layout, self.by_default),
        ) {
            // SAFETY: small before and after: the system allocator's own realloc.
            (None, None) => unsafe { System.realloc(ptr, layout, new_size) },
            // The block already holds the new size.
            (Some(old), Some(new)) if old == new => ptr,
            _ => {
                // SAFETY: distinct blocks; the old one holds `layout.size()` bytes and the
                // new one `new_size`.
                unsafe {
                    let new = self.alloc(new_layout);
                    if !new.is_null() {
                        std::ptr::copy_nonoverlapping(ptr, new, layout.size().min(new_size));
                        self.dealloc(ptr, layout);
                    }
                    new
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    /// Large blocks hold what was written, grow and shrink keeping it, come back zeroed
    /// when asked, and are reused once freed.
    #[test]
    fn large_blocks_keep_their_contents_and_are_reused() {
        if !super::enabled(true) {
            eprintln!("RADBENCH_HUGE_PAGES=off: glibc's blocks, nothing of ours to test");
            return;
        }
        let mut v: Vec<u32> = (0..(3 << 20) / 4).collect();
        assert_eq!(
            v.as_ptr() as usize % super::HUGE_PAGE,
            0,
            "aligned to a huge page"
        );
        v.extend(0..(1 << 20));
        v.truncate(1000);
        v.shrink_to_fit();
        assert!(v.iter().enumerate().all(|(k, &x)| x as usize == k));
        // A size no other test allocates (a block of 32 huge pages), so nothing else takes
        // the block.
        let size = (40 << 20) + 1;
        let big: Vec<u8> = vec![7; size];
        let at = big.as_ptr() as usize;
        drop(big);
        let zeroed: Vec<u8> = vec![0; size];
        assert!(zeroed.iter().all(|&b| b == 0), "zeroed, also when reused");
        assert_eq!(zeroed.as_ptr() as usize, at, "the freed block was reused");
    }
}
