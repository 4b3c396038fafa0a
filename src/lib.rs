//! radbench: drives an 80 GHz joint radar-communication bench and does its signal processing.
//!
//! # Layer map
//!
//! Imports only point down (`tests/house/layers.rs` checks it). Pure layers (`waveform`, `dsp`) do no
//! I/O and never touch tokio or the file system; everything that talks to an instrument goes
//! through `driver -> session -> transport`; `measure` talks to instruments only through `driver`.
//!
//! ```text
//! cli (binary) -> campaign (spec, plan, run folder, resume) -> measure, storage
//!  |
//!  +---> simulate ----------------------+
//!  |                                    v
//!  +---> measure (bench, processing, calibration, records) -> waveform, dsp (pure; waveform -> dsp)
//!  |        |       |        +-> storage (atomic files, SigMF, npy/npz/HDF5/CSV, plots, the prepared-piece cache)
//!  |        |       +-> catalog
//!  |        +-> driver -> session -> transport -> (tokio::net, serialport)
//!  +---> storage
//! leaves every layer may use: exit (exit classes), physics (c0), rng, time; trc (pure codec)
//! radbench -> mock_lab (the built-in bench); mock_lab -> nothing of radbench
//! ```
//!
//! # What is public
//!
//! Each layer is a public module and the only public path to what it offers: its submodules are
//! `pub(crate)` and the layer re-exports their `pub` items by name (`pub use sub::{A, b}`; no
//! glob: the layer's `mod.rs` is the list of what it offers), so a user writes
//! `radbench::<layer>::<Item>` (`radbench::simulate::RunSpec`, `radbench::measure::ProcessOptions`,
//! `radbench::waveform::WaveformKind`), never the file an item lives in. Where two submodules of
//! a layer define the same name, the layer says which one it offers (`measure` re-exports the
//! capture's `measure` and the re-processing's `Repetition`) or the name was made
//! unique (`measure::BenchCalibration`, the bench file's `[calibration]`, beside the response's
//! `measure::Calibration`; `campaign::MANIFEST_FILE`). Rooms whose names say little outside them
//! keep their namespace: the transport's protocols, whose codecs share names
//! (`transport::hislip::Header`, `transport::vicp::Header`, `transport::vxi11::VERSION`), and the
//! bench doctor (`measure::doctor::examine`, its `Report`, `Check`, `Status` and `stopped`); such
//! a room's `mod.rs` names what it offers in the same way. A new submodule is
//! `pub(crate) mod x;`, with `pub use x::{...};` beside it naming its public items (and
//! `pub(crate) use` for what the crate's other layers reach through the layer).
//!
//! `#![warn(unreachable_pub)]` keeps every `pub` item reachable, so a `pub` that is not part of
//! the API shows as a warning (an error in CI); `tests/house/public_api.rs` fails on a `pub` item
//! that nothing outside the crate names (the binary with its `cli` and `live`, tests,
//! benchmarks, examples, the Python package, doc examples) or reaches through a used signature.
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
//! | [`driver`] | 3 | capability traits (AWG, digitizer, RF front end), the drivers (M8195A, LeCroy MAUI, Keysight Infiniium, Gotmic), opened from a catalog entry's `driver` family (the closed `DriverFamily` table in `driver::family`, opened by `driver::open`), the scope drivers' shared checks and segments (`driver::scope_core`), permit, safe state; test doubles behind the `testing` feature |
//! | [`waveform`] | pure | waveform specs, MSK-LFM and OFDM generators, DAC quantisation, receivers; uses `dsp` for the OFDM numerology it shares with the radar (checked once there) |
//! | [`trc`] | pure | LeCroy waveform blocks and `.trc` files (WAVEDESC, segments): decode and build |
//! | [`dsp`] | pure | decimation, correlation, OFDM range processing, MUSIC, windows, metrics, detection (CLEAN, CFAR; CLEAN's floor follows a calibration's residual profile), the chain's response estimate (least squares over the gate's lags, a Toeplitz solve), its residual per window and its receive equaliser, the two ends' I/Q errors told apart in the image and undone |
//! | [`storage`] | out | atomic files, SigMF (write and read), npy (write and read)/CSV, npz and HDF5 exports, plots, the cache of prepared pieces (filter taps, point spreads) keyed by their inputs and the build |
//! | [`measure`] | 4 | in four rooms (`bench`, `processing`, `calibration`, `records`) and the capture that takes, processes and writes through them: the bench in use, each waveform family's room (`processing::family`: overrides, transmission, payload decoder, algorithms; one `match` in `processing::family::of`), the capture plan, capture under the safe-state guard, the one processing [`measure::Pipeline`] (with the receive correction), the chain's response calibration (measure, store, pre-distort; loaded once per command, `measure::calibration::correction`), phase ranging and each range's uncertainty (`measure::processing::ranging`), a capture's files, the bench doctor, the simulated bench's scene behind a typed seam (`set_scene`, `reseed`, `scene`) |
//! | [`campaign`] | app | measurement campaigns: spec (TOML) -> plan -> run folder (manifest, steps, `results.json`, report; its identity checked before every write), the kinds (one table, `kind.rs`; their report figures keyed by the same enum in `report/run_figures.rs`), the runner and its step jobs, positioners (commands in their own process group), resume, the thesis' lab chapter |
//! | [`simulate`] | app | the thesis' chapter-4 scenarios, free-form simulations and mock-lab scenes in-process, on the same pipeline |
//! | [`in_memory`] | app | the commands' results in memory (the Python package's entry): `radbench process`'s own options parsed by the command line's clap definitions ([`in_memory::ProcessArgs`], [`in_memory::WaveformArgs`]) and the processing choices deserialized into [`measure::ProcessingChoices`] (the type the command line and campaigns use), captures processed and read back, the transmission; the warm bench session ([`in_memory::BenchSession`]: `radbench.Bench`, captures and campaigns through `measure`'s rig and `campaign`'s runner, one session per bench) |
//! | [`runs_db`] | app | the run catalog: one SQLite file indexing run and capture folders (runs, steps, captures, targets, calibrations, instruments, files with SHA-256), filled by `radbench runs index` and, off the measurement's path, by the commands that write the folders; queries, trends |
//! | [`archive`] | app | archive processing driven by the run catalog: the captures a query selects, each processed into a folder addressed by content (input SHA-256, options hash, version), written under a temporary name and renamed when complete; what `radbench process --from-catalog` and the Python package's Dask path run |
//! | [`classify()`] | app | an error chain's exit class (the binary's exit code, the Python package's exception) |
//!
//! The binary (`src/bin/radbench/main.rs`) holds what only the command line needs: `cli` (one module per
//! subcommand: parse, call, print; in `src/bin/radbench/cli/`) and `live` (the live view: a loopback HTTP
//! server of one self-contained page and its event stream, fed through a bounded queue that drops
//! frames, never waited for; in `src/bin/radbench/live/`). They use the library as any user does, through
//! `radbench::...`.
//!
//! # Examples
//!
//! Resource strings parse as pyvisa and instrument manuals write them, and print back unchanged:
//!
//! ```
//! use radbench::address::Resource;
//!
//! let awg: Resource = "TCPIP0::192.168.1.20::hislip0::INSTR".parse()?;
//! assert_eq!(awg.to_string(), "TCPIP0::192.168.1.20::hislip0::INSTR");
//! let err = "GPIB0::7::INSTR".parse::<Resource>().unwrap_err();
//! assert!(err.to_string().contains("accepted forms"));
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```
//!
//! Two pillars simulated at 80 GSa/s (30 dB SNR), decimated, correlated and detected by the one
//! pipeline every command uses; both are found within a millimetre:
//!
//! ```
//! use radbench::simulate::simulate;
//! use radbench::simulate::Target;
//! use radbench::simulate::{RunSpec, WaveformSpec};
//!
//! let mut spec = RunSpec::new(
//!     "two pillars",
//!     WaveformSpec::msk_lfm_default(),
//!     vec![Target::at(1.0), Target { amplitude: 0.5, ..Target::at(1.8) }],
//! );
//! spec.snr_db = Some(30.0);
//! spec.capture_rate_hz = Some(80e9);
//! let outcome = simulate(&spec)?;
//! let found = &outcome.result.detected_m;
//! assert_eq!(found.len(), 2);
//! assert!((found[0] - 1.0).abs() < 1e-3 && (found[1] - 1.8).abs() < 1e-3);
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```
//!
//! Your own samples through the same pipeline: the thesis' MSK-LFM, an echo 2 m away (its
//! round trip delays it), processed as one aligned repetition:
//!
//! ```
//! use num_complex::Complex64;
//! use radbench::measure::{Dac, Pipeline, ProcessOptions, RawIq, RecordGeometry, Transmission};
//! use radbench::physics::C0;
//! use radbench::waveform::WaveformKind;
//! use std::sync::Arc;
//!
//! let kind = WaveformKind::MskLfm;
//! let tx = Arc::new(Transmission::new(&kind.thesis_default(), None, 1, Dac::Ideal)?);
//! let (period, fs) = (tx.len(), tx.sample_rate_hz());
//! let geometry = RecordGeometry { period, correlation_lags: period };
//! let mut pipeline = Pipeline::new(tx.clone(), ProcessOptions::for_waveform(kind), geometry)?;
//!
//! let delay = (2.0 * 2.0 / C0 * fs).round() as usize;
//! let samples: Vec<Complex64> =
//!     (0..period).map(|n| 0.1 * tx.reference[(n + period - delay) % period]).collect();
//! let aligned = pipeline.align(&RawIq { samples, sample_rate_hz: fs, first_point_s: 0.0 })?;
//! let processed = pipeline.process(aligned, None)?;
//! let range = processed.targets[0].range_m;
//! assert!((range - 2.0).abs() < 0.01, "{range} m");
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```
//!
//! A LeCroy trace (a `WF?` reply's block, or a saved `.trc` file) gives volts and times per
//! segment:
//!
//! ```
//! use radbench::trc::BlockBuilder;
//! use radbench::trc::Trace;
//!
//! let block = BlockBuilder { gain: 1.0 / 64.0, interval: 12.5e-12, ..BlockBuilder::default() }
//!     .build(&[0, 64, -64]);
//! let trace = Trace::decode(1, block.clone().into())?;
//! assert_eq!(trace.volts(), vec![0.0, 1.0, -1.0]);
//! assert!((trace.sample_interval_s() - 12.5e-12).abs() < 1e-18);
//!
//! let path = std::env::temp_dir().join(format!("radbench-doc-{}.trc", std::process::id()));
//! std::fs::write(&path, &block)?;
//! let saved = Trace::from_trc_bytes(1, std::fs::read(&path)?.into())?;
//! std::fs::remove_file(&path)?;
//! assert_eq!(saved.volts(), trace.volts());
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```
//!
//! A session with any instrument (needs one on the network, so not run here):
//!
//! ```no_run
//! use radbench::session::{Session, SessionOptions};
//!
//! # async fn identify() -> Result<(), Box<dyn std::error::Error>> {
//! let resource = "TCPIP0::192.168.1.30::inst0::INSTR".parse()?;
//! let mut scope = Session::open(resource, SessionOptions::default(), None, "scope").await?;
//! println!("{}", scope.idn().await?);
//! let vdiv = scope.query_f64("C1:VDIV?").await?;
//! println!("C1 at {vdiv} V/div");
//! # Ok(())
//! # }
//! ```

#![warn(unreachable_pub)]

/// The rest of an enum named on the command line and in files, from its strum derives
/// (`VariantArray`, `IntoStaticStr`, `EnumMessage`; `measure::Listed` has the recipe): its
/// `name()` (the one spelling, `IntoStaticStr`'s), `FromStr` over its `VARIANTS` by that name (the
/// error names what was given and lists every allowed value: `unknown window `x`: allowed: rect,
/// hann, ...`) and `Display` as that name. A macro of the crate root, not of `measure` (where
/// `Listed` is): `waveform`, below `measure`, has one of these enums.
macro_rules! named_enum {
    ($t:ty, $what:literal) => {
        impl $t {
            /// As the command line and the files spell it.
            pub fn name(self) -> &'static str {
                self.into()
            }
        }

        impl std::str::FromStr for $t {
            type Err = String;

            /// As `name` spells it; the error lists what is allowed.
            fn from_str(s: &str) -> Result<Self, String> {
                let all = <Self as strum::VariantArray>::VARIANTS;
                all.iter().copied().find(|v| v.name() == s).ok_or_else(|| {
                    let names: Vec<&str> = all.iter().map(|v| v.name()).collect();
                    format!(
                        concat!("unknown ", $what, " `{}`: allowed: {}{}"),
                        s,
                        names.join(", "),
                        $crate::exit::did_you_mean(s, names.iter().copied())
                    )
                })
            }
        }

        impl std::fmt::Display for $t {
            fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
                f.write_str(self.name())
            }
        }
    };
}

pub mod address;
pub mod archive;
pub mod campaign;
pub mod catalog;
mod classify;
pub mod driver;
pub mod dsp;
pub mod exit;
pub mod in_memory;
pub mod measure;
pub mod physics;
pub mod rng;
pub mod runs_db;
pub mod session;
pub mod simulate;
pub mod storage;
pub mod time;
pub mod transport;
pub mod trc;
pub mod waveform;

pub use classify::classify;
