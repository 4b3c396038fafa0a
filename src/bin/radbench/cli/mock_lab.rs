//! `radbench mock-lab serve`: the simulated bench on 127.0.0.1 (the same as the `mock-lab` binary).
//! It serves until SIGINT (Ctrl-C), SIGTERM or SIGHUP, and with `--until-stdin-closes` also until
//! standard input closes; a stop asked for that way is a success (exit code 0).

use mock_lab::emulator::lecroy::RemoteInterface;
use mock_lab::lab::{self, Announce, LabError, LabOptions, ScopeModel};
use mock_lab::scene::Scene;
use radbench::exit::{bad_input, Classified, ExitClass};
use std::path::PathBuf;

#[derive(Debug, clap::Args)]
pub struct Args {
    #[command(subcommand)]
    pub command: MockLabCommand,
}

#[derive(Debug, clap::Subcommand)]
pub enum MockLabCommand {
    /// Start the simulated bench on 127.0.0.1, print its endpoints and a bench file, serve until
    /// Ctrl-C (SIGINT), SIGTERM or SIGHUP.
    Serve(ServeArgs),
}

#[derive(Debug, clap::Args)]
pub struct ServeArgs {
    /// Scene file (TOML): targets, clutter, leakage, SNR, system delay, impairments
    /// (see examples/scene.toml). Default: one target at 1 m.
    #[arg(long, value_name = "FILE")]
    pub scene: Option<PathBuf>,
    /// Print one JSON line naming every endpoint and the control channel instead of a table.
    #[arg(long)]
    pub json: bool,
    /// Use consecutive ports from this one (5 per instrument) instead of OS-assigned ones.
    #[arg(long, value_name = "PORT")]
    pub port_base: Option<u16>,
    /// Port of the scope's VICP endpoint (pyvisa's VICP resource reaches only 1861).
    #[arg(long, value_name = "PORT")]
    pub vicp_port: Option<u16>,
    /// Also run a VXI-11 portmapper on this port (111 is standard and needs root).
    #[arg(long, value_name = "PORT")]
    pub portmapper_port: Option<u16>,
    /// The scope's remote interface: only this protocol answers, as on the real scope.
    #[arg(long, value_enum, default_value = "vicp")]
    pub scope_remote: ScopeRemote,
    /// The scope served as `scope` (the lab's table of scopes, listed below).
    #[arg(long, value_parser = super::args::scope_models(), value_name = "MODEL")]
    pub scope_model: Option<ScopeModel>,
    /// Also serve the generic loopback test instrument on every transport.
    #[arg(long)]
    pub with_loopback: bool,
    /// Also stop when standard input reaches end of file (for parent processes); SIGINT and
    /// SIGTERM stop it as well.
    #[arg(long)]
    pub until_stdin_closes: bool,
    /// Serve the Tx module from this catalog file (its `[protocol]`, `[serial]` line terminator
    /// and registers) instead of the built-in model: a lab's own protocol description, tried
    /// with radbench before the module is on the bench.
    #[arg(long, value_name = "FILE")]
    pub tx_model: Option<PathBuf>,
    /// The same for the Rx module.
    #[arg(long, value_name = "FILE")]
    pub rx_model: Option<PathBuf>,
}

#[derive(Debug, Clone, Copy, clap::ValueEnum)]
pub enum ScopeRemote {
    Vicp,
    Vxi11,
}

/// Reads and validates a scene file; errors name the file and the field (exit code 2).
pub(crate) fn load_scene(path: &std::path::Path) -> anyhow::Result<Scene> {
    let text = std::fs::read_to_string(path)
        .map_err(|e| bad_input(format!("cannot read scene file {}: {e}", path.display())))?;
    Scene::from_toml(&text, &path.display().to_string())
        .map_err(|e| bad_input(radbench::exit::with_key_hint(&e.to_string())))
}

pub(crate) fn run(args: Args, _global: &super::global::Global) -> anyhow::Result<()> {
    let MockLabCommand::Serve(a) = args.command;
    let scene = match &a.scene {
        Some(path) => load_scene(path)?,
        None => Scene::default(),
    };
    let options = LabOptions {
        scene,
        port_base: a.port_base,
        vicp_port: a.vicp_port,
        portmapper_port: a.portmapper_port,
        scope_remote: match a.scope_remote {
            ScopeRemote::Vicp => RemoteInterface::Vicp,
            ScopeRemote::Vxi11 => RemoteInterface::Vxi11,
        },
        with_loopback: a.with_loopback,
        scope_model: a.scope_model.unwrap_or_default(),
        front_ends: mock_lab::catalog::front_ends_from_files(
            a.tx_model.as_deref(),
            a.rx_model.as_deref(),
        )
        .map_err(bad_input)?,
        ..LabOptions::default()
    };
    options.validate().map_err(classified)?;
    let announce = if a.json {
        Announce::Json
    } else {
        Announce::Human
    };
    let runtime = super::global::runtime()?;
    let result = runtime.block_on(lab::serve_until_stopped(
        options,
        announce,
        a.until_stdin_closes,
    ));
    // Nothing of the lab may outlive this call, and nothing may hold up the exit.
    runtime.shutdown_background();
    result.map_err(classified)
}

/// The lab's error with the exit class it calls for (2 bad input, 3 cannot serve, 1 bug).
fn classified(err: LabError) -> anyhow::Error {
    let class = match err.exit_code() {
        2 => ExitClass::BadInput,
        3 => ExitClass::Instrument,
        _ => ExitClass::Internal,
    };
    anyhow::Error::new(Classified {
        class,
        message: err.to_string(),
    })
}
