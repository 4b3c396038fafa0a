//! The `mock-lab` binary: runs the simulated bench until stopped.
//!
//! `mock-lab serve` starts every instrument on every transport on 127.0.0.1, prints where each
//! endpoint is (a table, or with `--json` one JSON line), then serves until Ctrl-C or until its
//! standard input reaches end of file (so a parent process that dies takes it along).

use std::io::Read;
use std::process::ExitCode;
use std::sync::Arc;

use anyhow::{bail, Context};
use clap::{Parser, Subcommand};
use mock_lab::emulator::loopback::Loopback;
use mock_lab::server::launch::{self, Endpoint, Ports, Running, Transport};
use mock_lab::server::{Handler, ServerOptions, DEFAULT_MAX_MESSAGE_SIZE};

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
    /// Print the endpoints as one JSON line (for scripts) instead of a table.
    #[arg(long)]
    json: bool,
    /// Use consecutive ports from this one (per instrument: raw, VXI-11 core, VXI-11 abort,
    /// HiSLIP, VICP) instead of ports chosen by the OS.
    #[arg(long, value_name = "PORT")]
    port_base: Option<u16>,
    /// Port for the (first) VICP endpoint. pyvisa's VICP resource only reaches port 1861.
    #[arg(long, value_name = "PORT")]
    vicp_port: Option<u16>,
    /// Also run a VXI-11 portmapper on this port (111 is the standard one and needs root).
    #[arg(long, value_name = "PORT")]
    portmapper_port: Option<u16>,
    /// Keep serving when standard input closes (for running detached, `< /dev/null`); stop
    /// with Ctrl-C / SIGINT only.
    #[arg(long)]
    ignore_stdin: bool,
    /// Largest message accepted from a client, in bytes.
    #[arg(long, value_name = "BYTES", default_value_t = DEFAULT_MAX_MESSAGE_SIZE)]
    max_message_size: usize,
}

/// Ports used per instrument with `--port-base`.
const PORTS_PER_INSTRUMENT: u16 = 5;

fn main() -> ExitCode {
    let cli = Cli::parse();
    tracing_subscriber::fmt()
        .with_writer(std::io::stderr)
        .with_env_filter(
            tracing_subscriber::EnvFilter::try_from_default_env()
                .unwrap_or_else(|_| tracing_subscriber::EnvFilter::new("warn")),
        )
        .init();
    let runtime = match tokio::runtime::Runtime::new() {
        Ok(rt) => rt,
        Err(err) => {
            eprintln!("mock-lab: cannot start the async runtime: {err}");
            return ExitCode::from(3);
        }
    };
    let Command::Serve(args) = cli.command;
    let result = runtime.block_on(serve(args));
    // Do not wait for the thread blocked on stdin.
    runtime.shutdown_background();
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(err) => {
            eprintln!("mock-lab: {err:#}");
            ExitCode::from(3)
        }
    }
}

/// The instruments the bench offers, each on every network transport.
fn instruments() -> Vec<(&'static str, Arc<dyn Handler>)> {
    vec![("loopback", Arc::new(Loopback::new()) as Arc<dyn Handler>)]
}

fn ports_for(args: &ServeArgs, index: u16, transport: Transport) -> anyhow::Result<Ports> {
    let mut ports = Ports::default();
    if let Some(base) = args.port_base {
        let first = u32::from(base) + u32::from(index * PORTS_PER_INSTRUMENT);
        let port = |offset: u32| -> anyhow::Result<u16> {
            u16::try_from(first + offset)
                .context("--port-base is too high: ports would exceed 65535; choose a lower base")
        };
        ports.main = match transport {
            Transport::Raw => port(0)?,
            Transport::Vxi11 => port(1)?,
            Transport::Hislip => port(3)?,
            Transport::Vicp => port(4)?,
            Transport::Serial => 0,
        };
        if transport == Transport::Vxi11 {
            ports.abort = port(2)?;
        }
    }
    if transport == Transport::Vicp && index == 0 {
        if let Some(p) = args.vicp_port {
            ports.main = p;
        }
    }
    if transport == Transport::Vxi11 && index == 0 {
        ports.portmapper = args.portmapper_port;
    }
    Ok(ports)
}

async fn serve(args: ServeArgs) -> anyhow::Result<()> {
    if args.max_message_size < 1024 {
        bail!(
            "--max-message-size must be at least 1024 bytes, got {}",
            args.max_message_size
        );
    }
    let mut running: Vec<Running> = Vec::new();
    let mut endpoints: Vec<Endpoint> = Vec::new();
    for (index, (name, handler)) in instruments().into_iter().enumerate() {
        let index = u16::try_from(index).context("too many instruments")?;
        for transport in Transport::NETWORK.into_iter().chain([Transport::Serial]) {
            let options = ServerOptions {
                max_message_size: args.max_message_size,
                ..ServerOptions::default()
            };
            let ports = ports_for(&args, index, transport)?;
            let (server, endpoint) =
                launch::start(name, Arc::clone(&handler), transport, ports, options)
                    .await
                    .with_context(|| format!("cannot start {name} on {}", transport.name()))?;
            running.push(server);
            endpoints.push(endpoint);
        }
    }
    if args.json {
        let line = serde_json::json!({ "endpoints": endpoints });
        println!("{line}");
    } else {
        println!(
            "{:<10} {:<7} {:<22} resource",
            "instrument", "proto", "address"
        );
        for e in &endpoints {
            println!(
                "{:<10} {:<7} {:<22} {}",
                e.instrument,
                e.transport.name(),
                e.address,
                e.resource
            );
        }
        if args.ignore_stdin {
            println!("serving until Ctrl-C");
        } else {
            println!("serving until Ctrl-C or end of standard input");
        }
    }
    use std::io::Write;
    std::io::stdout()
        .flush()
        .context("cannot write the endpoint list to standard output")?;
    let ignore_stdin = args.ignore_stdin;
    let stdin_closed = async move {
        if ignore_stdin {
            std::future::pending::<()>().await;
        }
        let _ = tokio::task::spawn_blocking(|| {
            let mut sink = [0u8; 4096];
            let mut stdin = std::io::stdin();
            while matches!(stdin.read(&mut sink), Ok(n) if n > 0) {}
        })
        .await;
    };
    tokio::select! {
        signal = tokio::signal::ctrl_c() => signal.context("cannot listen for Ctrl-C")?,
        _ = stdin_closed => {}
    }
    drop(running);
    Ok(())
}
