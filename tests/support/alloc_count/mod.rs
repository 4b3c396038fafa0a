//! A global allocator that counts the bytes alive and their peak, so a test can show what an
//! operation allocated: process-wide ([`start`], [`peak_above`]; the tests that use these hold a
//! lock while they measure) and per thread ([`thread_start`], [`thread_peak_above`]; for work
//! done on the calling thread, such as decoding). Register it in the test binary with
//! `#[global_allocator] static A: io_alloc_count::Counting = io_alloc_count::Counting;`.
#![allow(dead_code)]

use std::alloc::{GlobalAlloc, Layout, System};
use std::cell::Cell;
use std::sync::atomic::{AtomicUsize, Ordering};

static LIVE: AtomicUsize = AtomicUsize::new(0);
static PEAK: AtomicUsize = AtomicUsize::new(0);

thread_local! {
    /// Bytes allocated minus bytes freed by this thread (frees of memory other threads
    /// allocated make it go down too, hence signed), and its peak.
    static THREAD_LIVE: Cell<isize> = const { Cell::new(0) };
    static THREAD_PEAK: Cell<isize> = const { Cell::new(0) };
}

pub struct Counting;

fn grew(n: usize) {
    let now = LIVE.fetch_add(n, Ordering::Relaxed) + n;
    PEAK.fetch_max(now, Ordering::Relaxed);
    let _ = THREAD_LIVE.try_with(|live| {
        let now = live.get() + n as isize;
        live.set(now);
        let _ = THREAD_PEAK.try_with(|peak| peak.set(peak.get().max(now)));
    });
}

fn shrank(n: usize) {
    LIVE.fetch_sub(n, Ordering::Relaxed);
    let _ = THREAD_LIVE.try_with(|live| live.set(live.get() - n as isize));
}

// SAFETY: every call is forwarded unchanged to the system allocator; the counters have no effect
// on the memory handed out.
unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        // SAFETY: the caller's contract, passed on to the system allocator unchanged.
        let p = unsafe { System.alloc(layout) };
        if !p.is_null() {
            grew(layout.size());
        }
        p
    }
    unsafe fn alloc_zeroed(&self, layout: Layout) -> *mut u8 {
        // SAFETY: the caller's contract, passed on to the system allocator unchanged.
        let p = unsafe { System.alloc_zeroed(layout) };
        if !p.is_null() {
            grew(layout.size());
        }
        p
    }
    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, size: usize) -> *mut u8 {
        // SAFETY: the caller's contract, passed on to the system allocator unchanged.
        let p = unsafe { System.realloc(ptr, layout, size) };
        if !p.is_null() {
            if size > layout.size() {
                grew(size - layout.size());
            } else {
                shrank(layout.size() - size);
            }
        }
        p
    }
    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        // SAFETY: the caller's contract, passed on to the system allocator unchanged.
        unsafe { System.dealloc(ptr, layout) };
        shrank(layout.size());
    }
}

/// Starts a measurement: returns the bytes alive now, and resets the peak to it.
pub fn start() -> usize {
    let base = LIVE.load(Ordering::Relaxed);
    PEAK.store(base, Ordering::Relaxed);
    base
}

/// The most bytes alive since [`start`], above its baseline.
pub fn peak_above(base: usize) -> usize {
    PEAK.load(Ordering::Relaxed).saturating_sub(base)
}

/// Starts a measurement of this thread's allocations.
pub fn thread_start() -> isize {
    let base = THREAD_LIVE.with(Cell::get);
    THREAD_PEAK.with(|p| p.set(base));
    base
}

/// The most bytes this thread had allocated (net) since [`thread_start`], above its baseline.
pub fn thread_peak_above(base: isize) -> usize {
    (THREAD_PEAK.with(Cell::get) - base).max(0) as usize
}
