//! The protocol servers and the mock-lab binary, with independent clients on 127.0.0.1.
//!
//! One test binary for many suites: each file below was its own binary, linked separately.

#[path = "../common/mod.rs"]
mod common;
// The same helpers as radbench's tests (test plumbing, not protocol code: independence is kept).
#[path = "../../../tests/support/process/mod.rs"]
mod process_support;

mod cli;
mod hislip;
mod raw_socket;
mod serial;
mod vicp;
mod vxi11;
