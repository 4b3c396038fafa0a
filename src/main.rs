//! The radbench binary: parse the command line, set up logging, run, map errors to exit codes.

use clap::Parser;
use radbench::cli::classify;
use radbench::exit::ExitClass;

fn main() {
    let cli = match radbench::cli::Cli::try_parse() {
        Ok(cli) => cli,
        Err(e) => {
            let code = if e.use_stderr() {
                ExitClass::BadInput.code()
            } else {
                0
            };
            let _ = e.print();
            std::process::exit(code);
        }
    };
    init_tracing(cli.verbose);
    if let Err(err) = radbench::cli::run(cli) {
        let class = classify(&err);
        eprintln!("error: {}", radbench::exit::render(&err));
        if class == ExitClass::Internal {
            eprintln!("(this is a radbench bug: please report it with the command you ran)");
        }
        std::process::exit(class.code());
    }
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
    tracing_subscriber::fmt()
        .with_env_filter(filter)
        .with_writer(std::io::stderr)
        .init();
}
