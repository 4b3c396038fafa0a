//! The radbench binary end to end: capture, campaigns, process, readers, exit paths, against the built-in mock lab.
//!
//! One test binary for many suites: each file below was its own binary, linked separately.

#[macro_use]
#[path = "../support/io/mod.rs"]
mod io_support;
#[path = "../support/process/mod.rs"]
mod process_support;

mod ambiguity;
mod bad_input;
mod bounded_commands;
mod calibrate_repeat;
mod calibrate_response;
mod calibration_reach;
mod campaign;
mod campaign_correction;
mod campaign_notify;
mod campaign_report;
mod campaign_summary;
mod campaign_sweeps;
mod capture_e2e;
mod cli_safety;
mod clipping_capture;
mod detect_capture;
mod detect_corrected;
mod doctor;
mod exit_paths;
mod export;
mod fault_matrix;
mod guide;
mod guide_links;
mod guide_markdown;
mod io_cli;
mod keysight_uxr;
mod link_quality;
mod live_exit_paths;
mod manual_front;
mod metrology;
mod other_protocol;
mod pointing_errors;
mod process_catalog;
mod process_cli;
mod readers_cli;
mod runs_catalog;
mod scenes;
mod sequence_capture;
mod simulate_cli;
mod simulate_scene;
mod support;
mod unattended;
mod verify_catalog;
