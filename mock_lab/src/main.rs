//! The `mock-lab` binary: runs the simulated bench until stopped.
//!
//! `mock-lab serve` starts every instrument of the bench (AWG, scope, Gotmic Tx/Rx) and the
//! generic loopback test instrument on 127.0.0.1, prints where each endpoint is (a table that is
//! also a ready-to-use radbench bench file, or with `--json` one JSON line), then serves until
//! SIGINT (Ctrl-C), SIGTERM or SIGHUP, or until its standard input reaches end of file (so a
//! parent process that dies takes it along; `--ignore-stdin` for detached runs).
//!
//! Exit codes: 0 stopped as asked, 2 bad input (options, scene file), 3 the lab cannot serve
//! (a port taken, no pseudo-terminal), 1 a bug. Messages are printed with control characters
//! escaped: they may quote a scene file.

use std::process::ExitCode;

use clap::{Parser, Subcommand};
use mock_lab::emulator::lecroy::RemoteInterface;
use mock_lab::lab::{self, Announce, LabOptions, ScopeModel};
use mock_lab::scene::Scene;
use mock_lab::server::DEFAULT_MAX_MESSAGE_SIZE;

#[derive(Debug, Parser)]
#[command(
    name = "mock-lab",
    version,
    about = "A simulated radar bench speaking the real instrument protocols"
)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Debug, Subcommand)]
enum Command {
    /// Serve the instruments on 127.0.0.1 until Ctrl-C or end of standard input.
    Serve(ServeArgs),
}

#[derive(Debug, clap::Args)]
struct ServeArgs {
    /// Scene file (TOML): targets, clutter, leakage, SNR, system delay (see examples/scene.toml).
    #[arg(long, value_name = "FILE")]
    scene: Option<std::path::PathBuf>,
    /// Print the endpoints as one JSON line (for scripts) instead of a table.
    #[arg(long)]
    json: bool,
    /// Use consecutive ports from this one (5 per instrument: raw, VXI-11 core, VXI-11 abort,
    /// HiSLIP, VICP) instead of ports chosen by the OS.
    #[arg(long, value_name = "PORT")]
    port_base: Option<u16>,
    /// Port of the scope's VICP endpoint. pyvisa's VICP resource only reaches port 1861.
    #[arg(long, value_name = "PORT")]
    vicp_port: Option<u16>,
    /// Port of the loopback test instrument's VICP endpoint.
    #[arg(long, value_name = "PORT")]
    loopback_vicp_port: Option<u16>,
    /// Also run a VXI-11 portmapper on this port (111 is the standard one and needs root).
    #[arg(long, value_name = "PORT")]
    portmapper_port: Option<u16>,
    /// The scope's remote interface: only this protocol answers, as on the real scope.
    #[arg(long, value_enum, default_value = "vicp")]
    scope_remote: ScopeRemote,
    /// The scope served as `scope` (the lab's table of scopes, listed below).
    #[arg(long, value_parser = scope_models(), default_value = "lecroy")]
    scope_model: ScopeModel,
    /// Keep serving when standard input closes (for running detached, `< /dev/null`); stop
    /// with Ctrl-C / SIGINT or SIGTERM only.
    #[arg(long)]
    ignore_stdin: bool,
    /// Stop when standard input closes: the default, accepted for the same command line as
    /// `radbench mock-lab serve`.
    #[arg(long, conflicts_with = "ignore_stdin")]
    until_stdin_closes: bool,
    /// Largest message accepted from a client, in bytes.
    #[arg(long, value_name = "BYTES", default_value_t = DEFAULT_MAX_MESSAGE_SIZE)]
    max_message_size: usize,
    /// Serve the Tx module from this catalog file (its `[protocol]`, `[serial]` line terminator
    /// and registers) instead of the built-in model: a lab's own protocol description, tried
    /// with radbench before the module is on the bench.
    #[arg(long, value_name = "FILE")]
    tx_model: Option<std::path::PathBuf>,
    /// The same for the Rx module.
    #[arg(long, value_name = "FILE")]
    rx_model: Option<std::path::PathBuf>,
}

/// clap's parser of `--scope-model`: the names of the lab's table, each with its line of help.
fn scope_models() -> impl clap::builder::TypedValueParser<Value = ScopeModel> {
    use clap::builder::{PossibleValue, PossibleValuesParser, TypedValueParser};
    PossibleValuesParser::new(
        ScopeModel::ALL
            .iter()
            .map(|m| PossibleValue::new(m.name()).help(m.about())),
    )
    .map(|s| s.parse::<ScopeModel>().unwrap_or_default())
}

#[derive(Debug, Clone, Copy, clap::ValueEnum)]
enum ScopeRemote {
    Vicp,
    Vxi11,
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    tracing_subscriber::fmt()
        .with_writer(std::io::stderr)
        .with_env_filter(
            tracing_subscriber::EnvFilter::try_from_default_env()
                .unwrap_or_else(|_| tracing_subscriber::EnvFilter::new("warn")),
        )
        .init();
    let Command::Serve(args) = cli.command;
    if args.max_message_size < 1024 {
        return fail(
            2,
            &format!(
                "--max-message-size must be at least 1024 bytes, got {}",
                args.max_message_size
            ),
        );
    }
    let scene = match &args.scene {
        None => Scene::default(),
        Some(path) => {
            let loaded = std::fs::read_to_string(path)
                .map_err(|e| format!("cannot read scene file {}: {e}", path.display()))
                .and_then(|text| {
                    Scene::from_toml(&text, &path.display().to_string()).map_err(|e| e.to_string())
                });
            match loaded {
                Ok(s) => s,
                Err(e) => return fail(2, &e),
            }
        }
    };
    let options = LabOptions {
        scene,
        port_base: args.port_base,
        vicp_port: args.vicp_port,
        portmapper_port: args.portmapper_port,
        max_message_size: args.max_message_size,
        scope_remote: match args.scope_remote {
            ScopeRemote::Vicp => RemoteInterface::Vicp,
            ScopeRemote::Vxi11 => RemoteInterface::Vxi11,
        },
        with_loopback: true,
        loopback_vicp_port: args.loopback_vicp_port,
        scope_model: args.scope_model,
        front_ends: match mock_lab::catalog::front_ends_from_files(
            args.tx_model.as_deref(),
            args.rx_model.as_deref(),
        ) {
            Ok(models) => models,
            Err(e) => return fail(2, &e),
        },
    };
    if let Err(err) = options.validate() {
        return fail(err.exit_code(), &err.to_string());
    }
    let runtime = match tokio::runtime::Runtime::new() {
        Ok(rt) => rt,
        Err(err) => return fail(3, &format!("cannot start the async runtime: {err}")),
    };
    let announce = if args.json {
        Announce::Json
    } else {
        Announce::Human
    };
    let result = runtime.block_on(lab::serve_until_stopped(
        options,
        announce,
        !args.ignore_stdin,
    ));
    runtime.shutdown_background();
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(err) => fail(err.exit_code(), &err.to_string()),
    }
}

/// Prints `message` on stderr, control characters escaped, and returns `code`.
fn fail(code: u8, message: &str) -> ExitCode {
    use std::io::Write;
    // A closed stderr leaves nothing to tell.
    let _ = writeln!(std::io::stderr(), "mock-lab: {}", escape_controls(message));
    ExitCode::from(code)
}

/// `text` with control characters other than LF and tab shown as `\xNN` / `\u{NNNN}`, so a
/// scene file quoted in a message cannot drive the terminal.
fn escape_controls(text: &str) -> String {
    let mut out = String::with_capacity(text.len());
    for c in text.chars() {
        let invisible = matches!(c, '\u{200b}'..='\u{200f}' | '\u{202a}'..='\u{202e}' | '\u{2066}'..='\u{2069}');
        if (c.is_control() && c != '\n' && c != '\t') || invisible {
            if (c as u32) < 0x100 {
                out.push_str(&format!("\\x{:02x}", c as u32));
            } else {
                out.push_str(&format!("\\u{{{:04x}}}", c as u32));
            }
        } else {
            out.push(c);
        }
    }
    out
}
