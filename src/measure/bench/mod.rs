//! The bench in use and its instruments: the bench file, the built-in mock lab or the instruments
//! it names, the station that plans, uploads, switches RF on, captures and leaves everything safe,
//! the simulated bench's scene, manual front ends, stop signals.
//!
//! | module | what it holds |
//! |---|---|
//! | `bench_file` | the bench file: instruments, resources, calibration |
//! | `in_use` | the bench in use: a bench file, or the built-in mock lab started in-process |
//! | `station` | the connected instruments: plan, upload, RF on, capture, safe state |
//! | `scene_capture` | the built-in mock lab's capture of a scene, in-process, without instruments or sockets |
//! | `scene_control` | the simulated bench's scene, typed: set it, reseed its noise, read it back |
//! | `interrupt` | SIGINT, SIGTERM and SIGHUP as a measurement's stop request |
//! | `manual` | front ends with `driver = "manual"`: the operator's instructions, confirmation and exit note |
//! | `verify_catalog` | `doctor --verify-catalog`: the catalog's inferred values asked of the instruments; override files |
//! | `blocking` | heavy synchronous work (DSP, file writing) run off the async runtime's workers |

pub(crate) mod bench_file;
pub(crate) mod blocking;
pub(crate) mod in_use;
pub(crate) mod interrupt;
pub(crate) mod manual;
pub(crate) mod scene_capture;
pub(crate) mod scene_control;
pub(crate) mod station;
pub(crate) mod verify_catalog;
