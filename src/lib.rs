//! radbench: drives an 80 GHz joint radar-communication bench and does its signal processing.
//!
//! # Layer map
//!
//! Imports only point down (`tests/dsp/layers.rs` checks it). Pure layers (`waveform`, `dsp`) do no
//! I/O and never touch tokio or the file system; everything that talks to an instrument goes
//! through `driver -> session -> transport`; `measure` talks to instruments only through `driver`.
//!
//! ```text
//! cli -> campaign (spec, plan, run folder, resume) -> measure, storage
//!  |
//!  +---> simulate ----------------------+
//!  |                                    v
//!  +---> measure (bench, station, pipeline, record) -> dsp, waveform (pure)
//!  |        |       |        +-> storage (atomic files, SigMF, npy/CSV, plots)
//!  |        |       +-> catalog
//!  |        +-> driver -> session -> transport -> (tokio::net, serialport)
//!  +---> storage
//! leaves every layer may use: exit (exit classes), physics (c0), rng, time; trc (pure codec)
//! radbench -> mock_lab (the built-in bench); mock_lab -> nothing of radbench
//! ```
//!
//! | module | layer | what it holds |
//! |---|---|---|
//! | [`exit`] | leaf | exit classes every error type maps to (0, 2, 3, 4, 129/130/143) |
//! | [`physics`] | leaf | the speed of light |
//! | [`rng`] | leaf | seeded SplitMix64 bits and Gaussian noise |
//! | [`time`] | leaf | RFC 3339 UTC text for journals and run files |
//! | [`address`] | 1 | VISA-style resource strings, parsed and printed back identically |
//! | [`transport`] | 1 | whole-message transports: raw socket, VXI-11, HiSLIP, VICP, serial, journal |
//! | [`session`] | 2 | IEEE 488.2 / SCPI on a transport: queries, blocks, `*OPC?`, `SYST:ERR?` |
//! | [`catalog`] | data | schema and loader for `instruments/*.toml` |
//! | [`driver`] | 3 | capability traits (AWG, digitizer, RF front end), the drivers, permit, safe state |
//! | [`waveform`] | pure | waveform specs, MSK-LFM and OFDM generators, DAC quantisation, receivers |
//! | [`trc`] | pure | LeCroy waveform blocks and `.trc` files (WAVEDESC, segments): decode and build |
//! | [`dsp`] | pure | decimation, correlation, OFDM range processing, MUSIC, windows, metrics, detection (CLEAN, CFAR) |
//! | [`storage`] | out | atomic files, SigMF (write and read), npy/CSV, plots |
//! | [`measure`] | 4 | the bench in use, the capture plan, capture under the safe-state guard, the one processing [`measure::Pipeline`], a capture's files |
//! | [`campaign`] | app | measurement campaigns: spec (TOML) -> plan -> run folder (manifest, steps, `results.json`, report), resume, the thesis' lab chapter |
//! | [`simulate`] | app | the thesis' chapter-4 scenarios and free-form simulations, on the same pipeline |
//! | [`cli`] | app | one module per subcommand: parse, call, print; exit codes from error chains |

pub mod address;
pub mod campaign;
pub mod catalog;
pub mod cli;
pub mod driver;
pub mod dsp;
pub mod exit;
pub mod measure;
pub mod physics;
pub mod rng;
pub mod session;
pub mod simulate;
pub mod storage;
pub mod time;
pub mod transport;
pub mod trc;
pub mod waveform;
