//! The radbench binary: parse the command line, set up logging, run, map errors to exit codes.
//!
//! Standard output closed by its reader (`radbench ... | head`) ends the run quietly with exit
//! code 0, as if the output had been read: the reader took what it wanted. Commands that print
//! through [`radbench::cli::terminal::out`] see it as an error and stop (or, `scpi`, finish
//! the commands without printing); a `println!` elsewhere panics on it, and that panic is caught
//! here and silenced. Error text is printed with control characters escaped: it may quote what
//! an instrument sent.

use clap::Parser;
use radbench::cli::{classify, terminal};
use radbench::exit::ExitClass;
use std::io::Write;

fn main() {
    let cli = match radbench::cli::Cli::try_parse() {
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
    let outcome =
        std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| radbench::cli::run(cli)));
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
