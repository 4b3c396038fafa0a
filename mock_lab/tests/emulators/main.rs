//! The instruments' emulators driven directly: command trees, limits, errors, fuzzed input.
//!
//! One test binary for many suites: each file below was its own binary, linked separately.

mod emulator_fuzz;
mod emulator_gotmic;
mod emulator_lecroy;
mod emulator_m8195a;
