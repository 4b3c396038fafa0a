//! radbench: drives an 80 GHz joint radar-communication bench and does its signal processing.
//!
//! # Layer map
//!
//! Imports only point down. Pure layers (`waveform`, `dsp`) do no I/O and never touch tokio or the
//! file system; everything that talks to an instrument goes through `driver -> session -> transport`.
//!
//! ```text
//! cli -> measure -> driver -> session -> transport -> (tokio::net, serialport)
//!  |        |          +-> catalog
//!  |        +-> processing (names of the processing choices) -> dsp, waveform (pure)
//!  +-> simulate -> processing, dsp, waveform
//!  +-> storage (atomic files, SigMF, npy/CSV, plots)
//! ```
//!
//! | module | layer | what it holds |
//! |---|---|---|
//! | [`address`] | 1 | VISA-style resource strings, parsed and printed back identically |
//! | [`transport`] | 1 | whole-message transports: raw socket, VXI-11, HiSLIP, VICP, serial, journal |
//! | [`session`] | 2 | IEEE 488.2 / SCPI on a transport: queries, blocks, `*OPC?`, `SYST:ERR?` |
//! | [`catalog`] | data | schema and loader for `instruments/*.toml` |
//! | [`driver`] | 3 | capability traits (AWG, digitizer, RF front end) and the concrete drivers |
//! | [`waveform`] | pure | MSK-LFM and OFDM generators, DAC quantisation, communication receivers |
//! | [`dsp`] | pure | decimation, correlation, OFDM range processing, MUSIC, windows, metrics, detection |
//! | [`rng`] | pure | seeded SplitMix64 bits and Gaussian noise |
//! | [`processing`] | pure | the `--algorithm`, `--window` and `--fft-precision` names shared by simulate, measure and the CLI |
//! | [`measure`] | 4 | one bench measurement: configure, arm, capture, decimate, align, process |
//! | [`storage`] | out | run folders, SigMF, npy/CSV, plots |
//! | [`simulate`] | app | the thesis' chapter-4 scenarios and free-form simulations |
//! | [`time`] | pure | RFC 3339 UTC text for journals and run files |
//! | [`cli`] | app | one module per subcommand, plus the transfer progress bar |
//!
//! Exit codes are in [`exit`]: 0 success, 2 bad input, 3 instrument or link failure, 4 processing
//! failure.

pub mod address;
pub mod catalog;
pub mod cli;
pub mod driver;
pub mod dsp;
pub mod exit;
pub mod measure;
pub mod processing;
pub mod rng;
pub mod session;
pub mod simulate;
pub mod storage;
pub mod time;
pub mod transport;
pub mod waveform;
