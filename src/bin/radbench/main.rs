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
#[cfg(all(target_os = "linux", target_env = "gnu"))]
mod huge_pages;
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

/// Buffers of 1 MiB or more on transparent huge pages (see [`huge_pages`]).
#[cfg(all(target_os = "linux", target_env = "gnu"))]
#[global_allocator]
static ALLOCATOR: huge_pages::HugePages = huge_pages::HugePages { by_default: true };

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
