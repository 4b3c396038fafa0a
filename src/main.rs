//! The radbench binary: parse the command line, set up logging, run, map errors to exit codes.
//!
//! Standard output closed by its reader (`radbench ... | head`) ends the run quietly with exit
//! code 0, as if the output had been read: the reader took what it wanted. Commands that print
//! through [`cli::terminal::out`] see it as an error and stop (or, `scpi`, finish
//! the commands without printing); a `println!` elsewhere panics on it, and that panic is caught
//! here and silenced. Error text is printed with control characters escaped: it may quote what
//! an instrument sent.

use clap::Parser;
use cli::terminal;
use radbench::classify;
use radbench::exit::ExitClass;
use std::io::Write;

mod cli;
mod live;

fn main() {
    keep_large_buffers();
    let cli = match cli::Cli::try_parse() {
        Ok(cli) => cli,
        Err(e) => {
            let code = if e.use_stderr() {
                ExitClass::BadInput.code()
            } else {
                0
            };
            // `--help | head`: a closed pipe is not an error here either.
            let _ = e.print();
            std::process::exit(code);
        }
    };
    init_tracing(cli.verbose);
    silence_closed_output_panics();
    let outcome = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| cli::run(cli)));
    let code = match outcome {
        Ok(Ok(())) => 0,
        Ok(Err(err)) if terminal::is_stdout_closed(&err) => 0,
        Ok(Err(err)) => {
            let class = classify(&err);
            let mut text = format!(
                "error: {}\n",
                terminal::printable(&radbench::exit::render(&err))
            );
            if class == ExitClass::Internal {
                text.push_str(
                    "(this is a radbench bug: please report it with the command you ran)\n",
                );
            }
            // stderr may be closed too (`2>&1 | head`): nothing more can be said then.
            let _ = std::io::stderr().write_all(text.as_bytes());
            class.code()
        }
        Err(payload) if terminal::is_closed_output_panic(payload.as_ref()) => 0,
        Err(_) => {
            // The panic hook has printed the panic (and run the safe state, during a capture).
            let _ = std::io::stderr().write_all(
                b"(this is a radbench bug: please report it with the command you ran)\n",
            );
            ExitClass::Internal.code()
        }
    };
    std::process::exit(code);
}

/// Large buffers on transparent huge pages.
///
/// A one-shot `radbench capture` touches ~70 MB (the waveform's tables, the scope's words and
/// their copies, spectra, file bytes): 14 000 page faults of 4 KiB, and as long again for the
/// kernel to free them when the process exits (5-6 ms between `exit_group` and the parent seeing
/// the exit, `strace -f -tt`). Every allocation of 1 MiB or more is aligned to 2 MiB and advised
/// `MADV_HUGEPAGE` (what glibc's `glibc.malloc.hugetlb=1` tunable does for its own mappings), so
/// the kernel backs it with 2 MiB pages where it can: ~700 faults, and the exit's teardown under
/// 1 ms. Where transparent huge pages are off the advice does nothing. Freed buffers stay in the
/// heap for reuse as before (`keep_large_buffers`).
#[cfg(all(target_os = "linux", target_env = "gnu"))]
mod huge_pages {
    use std::alloc::{GlobalAlloc, Layout, System};

    /// A transparent huge page.
    const HUGE_PAGE: usize = 2 << 20;
    /// Allocations from this size on are placed and advised for huge pages.
    const FROM: usize = 1 << 20;

    pub(crate) struct HugePages;

    /// The layout a large allocation is made with: aligned to a huge page.
    fn placed(layout: Layout) -> Option<Layout> {
        if layout.size() < FROM {
            return None;
        }
        Layout::from_size_align(layout.size(), layout.align().max(HUGE_PAGE)).ok()
    }

    /// Advises the pages of `size` bytes from `ptr` (a huge page's boundary) for huge pages.
    fn advise(ptr: *mut u8, size: usize) {
        if !ptr.is_null() {
            // SAFETY: `ptr..ptr + size` (rounded up to whole pages) was just allocated; the
            // advice changes how it is backed, never its contents. Failing (no transparent huge
            // pages) leaves it as it was.
            unsafe {
                libc::madvise(ptr.cast(), size.next_multiple_of(4096), libc::MADV_HUGEPAGE);
            }
        }
    }

    // SAFETY: every call is passed to the system allocator with a valid layout (the same size, a
    // larger power-of-two alignment for large allocations), and each block is freed with the
    // layout it was allocated with (`placed` is a function of the caller's layout).
    unsafe impl GlobalAlloc for HugePages {
        unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
            match placed(layout) {
                Some(big) => {
                    // SAFETY: `big` has a non-zero size (at least `FROM`).
                    let ptr = unsafe { System.alloc(big) };
                    advise(ptr, big.size());
                    ptr
                }
                // SAFETY: the caller's contract, passed on unchanged.
                None => unsafe { System.alloc(layout) },
            }
        }

        unsafe fn alloc_zeroed(&self, layout: Layout) -> *mut u8 {
            match placed(layout) {
                Some(big) => {
                    // SAFETY: as in `alloc`.
                    let ptr = unsafe { System.alloc_zeroed(big) };
                    advise(ptr, big.size());
                    ptr
                }
                // SAFETY: the caller's contract, passed on unchanged.
                None => unsafe { System.alloc_zeroed(layout) },
            }
        }

        unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
            // SAFETY: `ptr` came from `alloc`/`alloc_zeroed`/`realloc` with this layout, made
            // with `placed(layout)` when that is `Some`.
            unsafe { System.dealloc(ptr, placed(layout).unwrap_or(layout)) }
        }

        unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
            // SAFETY: the caller guarantees `new_size` is valid with `layout.align()`.
            let new_layout = unsafe { Layout::from_size_align_unchecked(new_size, layout.align()) };
            if placed(layout).is_none() && placed(new_layout).is_none() {
                // SAFETY: small before and after: the system allocator's own realloc.
                return unsafe { System.realloc(ptr, layout, new_size) };
            }
            // SAFETY: `new_layout` is valid (the caller's contract); the old block holds
            // `layout.size()` bytes and the new one `new_size`, distinct blocks.
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

#[cfg(all(target_os = "linux", target_env = "gnu"))]
#[global_allocator]
static ALLOCATOR: huge_pages::HugePages = huge_pages::HugePages;

/// Lets freed large buffers be reused instead of handed back to the kernel.
///
/// radbench allocates and frees records of megabytes per capture (words, samples, spectra,
/// file bytes). glibc serves each of those with a fresh `mmap` and unmaps it when freed, so every
/// capture touched its buffers' pages anew: `perf stat` of `radbench process` on 24 captures
/// counted 62 000 page faults and ~16 % of the CPU time in the kernel's page-fault path. Served
/// from the heap and kept there when freed (up to 512 MiB of free memory kept, 64 MiB of padding
/// per heap growth), the same run faults 13 000 times. A freed buffer then stays in the process
/// (its resident size stays at its peak) until it exits: radbench's peaks are a few captures'
/// records.
fn keep_large_buffers() {
    #[cfg(all(target_os = "linux", target_env = "gnu"))]
    {
        const MIB: i32 = 1 << 20;
        // SAFETY: mallopt only sets the allocator's thresholds; it is called before any thread
        // starts, as glibc's manual asks.
        unsafe {
            libc::mallopt(libc::M_MMAP_THRESHOLD, 256 * MIB);
            libc::mallopt(libc::M_TRIM_THRESHOLD, 512 * MIB);
            libc::mallopt(libc::M_TOP_PAD, 64 * MIB);
        }
    }
}

/// The default panic hook, except for the panic `println!` raises on a closed pipe: that one is
/// the reader going away, not a bug, and ends the run quietly.
fn silence_closed_output_panics() {
    let default = std::panic::take_hook();
    std::panic::set_hook(Box::new(move |info| {
        if !terminal::is_closed_output_panic(info.payload()) {
            default(info);
        }
    }));
}

fn init_tracing(verbose: u8) {
    let default = match verbose {
        0 => "warn",
        1 => "info",
        2 => "debug",
        _ => "trace",
    };
    let filter = tracing_subscriber::EnvFilter::try_from_env("RADBENCH_LOG")
        .unwrap_or_else(|_| tracing_subscriber::EnvFilter::new(default));
    // Colour only on a terminal: a log redirected to a file stays plain text. NO_COLOR is
    // honoured too (no-color.org).
    use std::io::IsTerminal;
    let colour = std::io::stderr().is_terminal() && std::env::var_os("NO_COLOR").is_none();
    tracing_subscriber::fmt()
        .with_env_filter(filter)
        .with_writer(std::io::stderr)
        .with_ansi(colour)
        .init();
}
