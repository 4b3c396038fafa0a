//! The command line: one module per subcommand, each a clap struct and a `run()`.
//!
//! Doc comments on the clap structs are `--help` text, not rustdoc: brackets and angle brackets
//! in them are literal.
#![allow(rustdoc::broken_intra_doc_links, rustdoc::invalid_html_tags)]

use clap::{Parser, Subcommand};
use global::Global;
use std::path::PathBuf;

pub(crate) mod align;
pub(crate) mod args;
pub(crate) mod benchmarks;
pub(crate) mod benchmarks_io;
pub(crate) mod bounded;
pub(crate) mod calibrate;
pub(crate) mod calibrate_response;
pub(crate) mod campaign;
pub(crate) mod capture;
mod capture_run;
pub(crate) mod doctor;
pub(crate) mod export;
mod global;
pub(crate) mod idn;
pub(crate) mod live;
pub(crate) mod manual_front;
pub(crate) mod mock_lab;
pub(crate) mod process;
pub(crate) mod process_catalog;
pub(crate) mod progress;
pub(crate) mod recording;
pub(crate) mod repeat;
pub(crate) mod runs;
pub(crate) mod scope_model;
pub(crate) mod scpi;
pub(crate) mod simulate;
pub mod terminal;
pub(crate) mod trc;
pub(crate) mod verify_catalog;
pub(crate) mod waveform;

/// radbench: the 80 GHz radar-communication bench and its signal processing.
#[derive(Debug, Parser)]
#[command(name = "radbench", version, about, long_about = None)]
pub struct Cli {
    /// Write every instrument exchange to this file as JSON Lines (see docs/io-journal.md).
    #[arg(long, global = true, value_name = "FILE")]
    pub trace_io: Option<PathBuf>,
    /// More log output on stderr (-v info, -vv debug, -vvv trace).
    #[arg(short, long, global = true, action = clap::ArgAction::Count)]
    pub verbose: u8,
    #[command(subcommand)]
    pub command: Command,
}

#[derive(Debug, Subcommand)]
pub enum Command {
    /// Simulate the signal chain: the thesis' scenarios, free-form runs and BER curves.
    Simulate(simulate::Args),
    /// Time the DSP kernels on thesis-sized inputs.
    Bench(benchmarks::Args),
    /// Ask an instrument who it is (`*IDN?`).
    Idn(idn::Args),
    /// One measurement: waveform out, marker-triggered capture, range profile, targets, payload.
    Capture(Box<capture::Args>),
    /// Measurement campaigns: run a spec into a run folder, resume, new, report, thesis-lab.
    Campaign(campaign::Args),
    /// Place a target: capture again and again, print the strongest target's range, its level
    /// and its distance to --target-range (RF on only while capturing).
    Align(Box<align::Args>),
    /// Process saved captures again: capture folders, SigMF recordings or .trc pairs, with the
    /// options they were captured with or any others, in parallel.
    Process(Box<process::Args>),
    /// Write a capture's or a run's arrays to one .npz or HDF5 file for a notebook: decimated
    /// I/Q in volts, complex range profiles and range axis, detections, transmitted reference
    /// and bits, options (docs/export.md).
    Export(export::Args),
    /// Check a bench without radiating: every instrument reachable and identified, the scope's
    /// remote interface, the Gotmic lines, the marker at the scope's trigger (Tx off), the
    /// timebases and the calibrations; a checklist with what to fix. Exit 0 only when all hold.
    Doctor(doctor::Args),
    /// Measure the bench's fixed system delay on a reference target and store it.
    Calibrate(calibrate::Args),
    /// The simulated bench (mock_lab) on 127.0.0.1.
    #[command(name = "mock-lab")]
    MockLab(mock_lab::Args),
    /// Send SCPI commands to an instrument, one-shot or at an interactive prompt.
    Scpi(scpi::Args),
    /// Show the header and a summary of LeCroy .trc files (every segment of a sequence).
    Trc(trc::Args),
    /// Waveform analysis: the delay-Doppler ambiguity function as uploaded, a capture's
    /// cross-ambiguity.
    Waveform(waveform::Args),
    /// Show a SigMF recording: datatype, rate, samples, statistics, radbench's metadata.
    Recording(recording::Args),
    /// The run catalog (one SQLite file): index run and capture folders, list, show, query,
    /// captures, a metric's trend (docs/catalog.md).
    Runs(runs::Args),
}

pub fn run(cli: Cli) -> anyhow::Result<()> {
    let global = Global {
        trace_io: cli.trace_io,
    };
    match cli.command {
        Command::Simulate(args) => simulate::run(args, &global),
        Command::Bench(args) => benchmarks::run(args, &global),
        Command::Idn(args) => idn::run(args, &global),
        Command::Capture(args) => capture_run::run(*args, &global),
        Command::Campaign(args) => campaign::run(args, &global),
        Command::Align(args) => align::run(*args, &global),
        Command::Calibrate(args) => calibrate::run(args, &global),
        Command::Doctor(args) => doctor::run(args, &global),
        Command::Process(args) => process::run(*args, &global),
        Command::Export(args) => export::run(args, &global),
        Command::MockLab(args) => mock_lab::run(args, &global),
        Command::Scpi(args) => scpi::run(args, &global),
        Command::Trc(args) => trc::run(args, &global),
        Command::Recording(args) => recording::run(args, &global),
        Command::Waveform(args) => waveform::run(args, &global),
        Command::Runs(args) => runs::run(args),
    }
}
