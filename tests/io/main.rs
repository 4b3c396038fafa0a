//! Transports, sessions and drivers against mock_lab's servers and emulators on 127.0.0.1.
//!
//! One test binary for many suites: each file below was its own binary, linked separately.

#[path = "../support/driver/mod.rs"]
mod driver_support;
#[macro_use]
#[path = "../support/io/mod.rs"]
mod io_support;

mod driver_emulator;
mod driver_faults;
mod driver_io;
mod driver_keysight_uxr;
mod driver_scripted;
mod driver_second_scope;
mod io_faults_proxy;
mod io_hislip;
#[cfg(unix)]
mod io_serial;
mod io_socket;
mod io_vicp;
mod io_vxi11;
