//! `radbench._radbench`: the extension module behind radbench's Python package. Thin: every
//! call goes to radbench's library (`radbench::in_memory`, the same code as the command
//! line) or to mock_lab's in-process lab; the Python layer (`radbench/__init__.py`) gives it its
//! documented API. Long calls release the GIL; arrays are handed over as numpy arrays that own
//! radbench's vectors (no copy).

use numpy::{Complex64, IntoPyArray, PyArray1, PyReadonlyArray1};
use pyo3::exceptions::PyRuntimeError;
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyList};
use radbench::archive;
use radbench::in_memory::{self, InMemory, ProcessRequest};
use radbench::measure::RawIq;
use radbench::waveform::WaveformKind;
use std::path::PathBuf;
use std::time::Duration;

// The command line's allocator for buffers of 1 MiB or more (the same file), off unless
// RADBENCH_HUGE_PAGES=on: radbench.dask's workers turn it on (docs/catalog.md measures it).
#[cfg(all(target_os = "linux", target_env = "gnu"))]
#[path = "../../src/bin/radbench/huge_pages.rs"]
mod huge_pages;
mod session;

#[cfg(all(target_os = "linux", target_env = "gnu"))]
#[global_allocator]
static ALLOCATOR: huge_pages::HugePages = huge_pages::HugePages { by_default: false };

/// radbench's error as the Python exception of its exit class (`radbench.errors`), carrying
/// radbench's message and its exit code.
pub(crate) fn to_py(err: anyhow::Error) -> PyErr {
    let code = radbench::classify(&err).code();
    py_error(code, radbench::exit::render(&err))
}

/// The exception of `radbench.errors` for exit code `code`.
fn py_error(code: i32, message: String) -> PyErr {
    Python::attach(|py| {
        let name = match code {
            2 => "InputError",
            3 => "InstrumentError",
            4 => "ProcessingError",
            _ => "RadbenchError",
        };
        let made = py
            .import("radbench.errors")
            .and_then(|m| m.getattr(name))
            .and_then(|t| t.call1((message, code)));
        match made {
            Ok(e) => PyErr::from_value(e),
            Err(e) => e,
        }
    })
}

fn json_text(v: &serde_json::Value) -> String {
    v.to_string()
}

fn f64s<'py>(py: Python<'py>, v: Vec<f64>) -> Bound<'py, PyArray1<f64>> {
    v.into_pyarray(py)
}

fn complex<'py>(py: Python<'py>, v: Vec<Complex64>) -> Bound<'py, PyArray1<Complex64>> {
    v.into_pyarray(py)
}

/// The arrays and JSON of one processing, as a dict for the Python layer.
pub(crate) fn processed_dict<'py>(py: Python<'py>, done: InMemory) -> PyResult<Bound<'py, PyDict>> {
    let d = PyDict::new(py);
    d.set_item("summary_json", json_text(&done.summary))?;
    d.set_item(
        "options_json",
        serde_json::to_string(&done.options).map_err(|e| PyRuntimeError::new_err(e.to_string()))?,
    )?;
    let p = done.processed;
    let profiles = PyList::empty(py);
    for profile in p.profiles {
        let item = PyDict::new(py);
        item.set_item("range_m", f64s(py, profile.ranges()))?;
        item.set_item("label", profile.label)?;
        item.set_item("amplitude", f64s(py, profile.amplitude))?;
        profiles.append(item)?;
    }
    d.set_item("profiles", profiles)?;
    d.set_item("complex_profile", p.complex_profile.map(|z| complex(py, z)))?;
    d.set_item("threshold", f64s(py, p.detection.threshold))?;
    d.set_item("residual", f64s(py, p.detection.residual))?;
    d.set_item("noise_db", p.detection.noise_db)?;
    d.set_item("aligned", complex(py, p.aligned))?;
    Ok(d)
}

/// One capture processed as `radbench process FILES OPTIONS` processes it (nothing written);
/// `keywords`: the options as a JSON object of Python keywords.
#[pyfunction]
fn process_capture<'py>(
    py: Python<'py>,
    files: Vec<PathBuf>,
    keywords: &str,
) -> PyResult<Bound<'py, PyDict>> {
    let done = py
        .detach(|| ProcessRequest::from_keywords(keywords).and_then(|r| r.capture(&files)))
        .map_err(to_py)?;
    processed_dict(py, done)
}

/// A record of samples (volts) processed as a capture radbench did not make.
#[pyfunction]
fn process_samples<'py>(
    py: Python<'py>,
    samples: PyReadonlyArray1<'py, Complex64>,
    sample_rate_hz: f64,
    first_point_s: f64,
    keywords: &str,
) -> PyResult<Bound<'py, PyDict>> {
    let raw = RawIq {
        samples: samples.as_array().to_vec(),
        sample_rate_hz,
        first_point_s,
    };
    let done = py
        .detach(|| ProcessRequest::from_keywords(keywords).and_then(|r| r.samples(raw)))
        .map_err(to_py)?;
    processed_dict(py, done)
}

/// The captures `radbench process INPUTS` would process: `[(folder name, [files])]`.
#[pyfunction]
fn captures(py: Python<'_>, inputs: Vec<PathBuf>) -> PyResult<Vec<(String, Vec<PathBuf>)>> {
    let found = py.detach(|| in_memory::captures(&inputs)).map_err(to_py)?;
    Ok(found.into_iter().map(|c| (c.name, c.files)).collect())
}

/// The captures `query` selects in `catalog` (or the capture folders `dirs`, when given), as
/// archive units: `[(input_dir, input_sha256)]`.
#[pyfunction]
#[pyo3(signature = (catalog, query, dirs=None))]
fn archive_units(
    py: Python<'_>,
    catalog: PathBuf,
    query: &str,
    dirs: Option<Vec<PathBuf>>,
) -> PyResult<Vec<(PathBuf, String)>> {
    let units = py
        .detach(|| match &dirs {
            Some(d) => archive::units_of(&catalog, d),
            None => archive::units(&catalog, query),
        })
        .map_err(to_py)?;
    Ok(units
        .into_iter()
        .map(|u| (u.input_dir, u.input_sha256))
        .collect())
}

/// One archive unit processed into `out/<address>` unless done: `(status, out_dir)`, status
/// `written` or `skipped`. `markers`: a folder where each computation started leaves a file.
#[pyfunction]
#[pyo3(signature = (input_dir, input_sha256, out, keywords, markers=None))]
fn archive_process_unit(
    py: Python<'_>,
    input_dir: PathBuf,
    input_sha256: String,
    out: PathBuf,
    keywords: &str,
    markers: Option<PathBuf>,
) -> PyResult<(String, PathBuf)> {
    let unit = archive::Unit {
        input_dir,
        input_sha256,
    };
    let done = py
        .detach(|| {
            let settings = archive::ArchiveSettings::from_keywords(keywords)?;
            std::fs::create_dir_all(&out)?;
            archive::process_unit(&unit, &out, &settings, markers.as_deref())
        })
        .map_err(to_py)?;
    let status = match done.status {
        archive::UnitStatus::Written => "written",
        archive::UnitStatus::Skipped => "skipped",
    };
    Ok((status.to_string(), done.out_dir))
}

/// Registers done units `[(input_dir, input_sha256, out_dir)]` in the catalog's `processed`
/// table and removes the temporary folders of done units in `out`; how many were removed.
#[pyfunction]
fn archive_register(
    py: Python<'_>,
    catalog: PathBuf,
    out: PathBuf,
    keywords: &str,
    done: Vec<(PathBuf, String, PathBuf)>,
) -> PyResult<usize> {
    py.detach(|| -> anyhow::Result<usize> {
        let settings = archive::ArchiveSettings::from_keywords(keywords)?;
        let rows: Vec<_> = done
            .into_iter()
            .map(|(input_dir, input_sha256, out_dir)| {
                archive::UnitDone {
                    unit: archive::Unit {
                        input_dir,
                        input_sha256,
                    },
                    out_dir,
                    status: archive::UnitStatus::Written,
                }
                .row(&settings)
            })
            .collect();
        radbench::runs_db::record_processed(&catalog, &rows)?;
        Ok(archive::sweep_partials(&out))
    })
    .map_err(to_py)
}

/// A saved capture: every repetition raw (volts, capture rate) and decimated, its metadata.
#[pyfunction]
fn read_capture<'py>(py: Python<'py>, files: Vec<PathBuf>) -> PyResult<Bound<'py, PyDict>> {
    let c = py
        .detach(|| in_memory::read_capture(&files))
        .map_err(to_py)?;
    let d = PyDict::new(py);
    d.set_item("files", c.files)?;
    let raw = PyList::empty(py);
    let mut rate = None;
    let mut t0 = Vec::new();
    for r in c.raw {
        rate = Some(r.sample_rate_hz);
        t0.push(r.first_point_s);
        raw.append(complex(py, r.samples))?;
    }
    d.set_item("raw", raw)?;
    d.set_item("capture_rate_hz", rate)?;
    d.set_item("raw_t0_s", f64s(py, t0))?;
    let decimated = PyList::empty(py);
    let mut residual = Vec::new();
    for a in c.decimated {
        residual.push(a.residual_s);
        decimated.append(complex(py, a.samples))?;
    }
    d.set_item("decimated", decimated)?;
    d.set_item("decimated_t0_s", f64s(py, residual))?;
    d.set_item("processing_rate_hz", c.processing_rate_hz)?;
    d.set_item("not_decimated", c.not_decimated)?;
    d.set_item(
        "radbench_json",
        json_text(&serde_json::Value::Object(c.radbench)),
    )?;
    d.set_item("scene_json", c.scene.map(|s| json_text(&s)))?;
    Ok(d)
}

/// A waveform kind by its command-line name.
pub(crate) fn waveform_kind(kind: &str) -> PyResult<WaveformKind> {
    match kind {
        "msk-lfm" => Ok(WaveformKind::MskLfm),
        "ofdm" => Ok(WaveformKind::Ofdm),
        other => Err(to_py(radbench::exit::bad_input(format!(
            "waveform: {other:?}; msk-lfm or ofdm"
        )))),
    }
}

/// The waveform `radbench capture --waveform KIND OPTIONS` transmits, with its AWG codes.
#[pyfunction]
fn transmission<'py>(
    py: Python<'py>,
    kind: &str,
    options: Vec<String>,
) -> PyResult<Bound<'py, PyDict>> {
    let kind = waveform_kind(kind)?;
    let tx = py
        .detach(|| in_memory::transmission(kind, &options))
        .map_err(to_py)?;
    let d = PyDict::new(py);
    d.set_item("description_json", json_text(&tx.describe()))?;
    d.set_item("sample_rate_hz", tx.sample_rate_hz())?;
    d.set_item("bandwidth_hz", tx.bandwidth_hz())?;
    d.set_item("samples", complex(py, tx.reference))?;
    d.set_item("i", tx.iq.i.into_pyarray(py))?;
    d.set_item("q", tx.iq.q.into_pyarray(py))?;
    d.set_item("marker_high_samples", tx.iq.marker_high_samples)?;
    d.set_item("bits", tx.bits.into_pyarray(py))?;
    d.set_item("payload", tx.payload)?;
    d.set_item("seed", tx.seed)?;
    Ok(d)
}

/// Longest wait for the lab to start listening.
const START_TIMEOUT: Duration = Duration::from_secs(30);
/// Longest wait for the lab's tasks and threads to end when it stops.
const STOP_TIMEOUT: Duration = Duration::from_secs(10);

/// mock_lab's simulated bench, running in-process on 127.0.0.1 on a runtime of its own.
#[pyclass(module = "radbench._radbench")]
struct Lab {
    running: Option<(tokio::runtime::Runtime, mock_lab::lab::Lab)>,
}

fn stop(running: Option<(tokio::runtime::Runtime, mock_lab::lab::Lab)>) {
    if let Some((runtime, lab)) = running {
        {
            let _inside = runtime.enter();
            drop(lab);
        }
        runtime.shutdown_timeout(STOP_TIMEOUT);
    }
}

impl Lab {
    fn lab(&self) -> PyResult<&mock_lab::lab::Lab> {
        self.running
            .as_ref()
            .map(|(_, lab)| lab)
            .ok_or_else(|| PyRuntimeError::new_err("the mock lab is stopped"))
    }
}

#[pymethods]
impl Lab {
    /// `scene_toml` (a scene file's text, named `origin`) or `scene_json`; neither: the default
    /// scene. `scope_remote`: "vxi11" or "vicp".
    #[new]
    #[pyo3(signature = (scene_toml=None, scene_json=None, origin="<scene>", scope_remote="vxi11"))]
    fn new(
        py: Python<'_>,
        scene_toml: Option<String>,
        scene_json: Option<String>,
        origin: &str,
        scope_remote: &str,
    ) -> PyResult<Self> {
        use mock_lab::emulator::lecroy::RemoteInterface;
        use mock_lab::scene::Scene;
        let bad = |m: String| to_py(radbench::exit::bad_input(m));
        let scene = match (scene_toml, scene_json) {
            (Some(t), _) => Scene::from_toml(&t, origin).map_err(|e| bad(e.to_string()))?,
            (None, Some(j)) => {
                serde_json::from_str::<Scene>(&j).map_err(|e| bad(format!("scene: {e}")))?
            }
            (None, None) => Scene::default(),
        };
        let remote = match scope_remote {
            "vxi11" => RemoteInterface::Vxi11,
            "vicp" => RemoteInterface::Vicp,
            other => return Err(bad(format!("scope_remote: {other:?}; vxi11 or vicp"))),
        };
        let options = mock_lab::lab::LabOptions {
            scene,
            scope_remote: remote,
            ..mock_lab::lab::LabOptions::default()
        };
        let started = py.detach(move || {
            let runtime = tokio::runtime::Builder::new_multi_thread()
                .worker_threads(2)
                .thread_name("radbench-mock-lab")
                .enable_io()
                .enable_time()
                .build()
                .map_err(|e| format!("cannot start the mock lab's runtime: {e}"))?;
            let lab = runtime.block_on(async {
                tokio::time::timeout(START_TIMEOUT, mock_lab::lab::start(options)).await
            });
            match lab {
                Ok(Ok(lab)) => Ok((runtime, lab)),
                Ok(Err(e)) => {
                    runtime.shutdown_timeout(STOP_TIMEOUT);
                    Err(e.to_string())
                }
                Err(_) => {
                    runtime.shutdown_timeout(STOP_TIMEOUT);
                    Err(format!(
                        "the mock lab did not start within {} s",
                        START_TIMEOUT.as_secs()
                    ))
                }
            }
        });
        match started {
            Ok(running) => Ok(Lab {
                running: Some(running),
            }),
            Err(m) => Err(py_error(3, m)),
        }
    }

    /// Every endpoint as JSON: `[{"instrument", "transport", "address", "resource", ...}]`.
    fn endpoints_json(&self) -> PyResult<String> {
        serde_json::to_string(&self.lab()?.endpoints())
            .map_err(|e| PyRuntimeError::new_err(e.to_string()))
    }

    /// The scene control channel's `host:port`.
    fn control_address(&self) -> PyResult<String> {
        Ok(self.lab()?.control.to_string())
    }

    /// One request on the scene control channel (a JSON object), its JSON reply.
    fn control(&self, request_json: &str) -> PyResult<String> {
        Ok(self.lab()?.bench.scene.apply(request_json).to_string())
    }

    /// A radbench bench file for this lab (AWG over HiSLIP; the scope over its remote interface).
    fn bench_toml(&self, scope_transport: &str) -> PyResult<String> {
        use mock_lab::server::launch::Transport;
        let scope = if scope_transport == "vicp" {
            Transport::Vicp
        } else {
            Transport::Vxi11
        };
        Ok(self.lab()?.bench_toml(Transport::Hislip, scope))
    }

    /// Stops every server and the runtime's threads (waits for them, at most 10 s).
    fn close(&mut self, py: Python<'_>) {
        let running = self.running.take();
        py.detach(move || stop(running));
    }

    fn is_running(&self) -> bool {
        self.running.is_some()
    }
}

impl Drop for Lab {
    fn drop(&mut self) {
        stop(self.running.take());
    }
}

#[pymodule]
fn _radbench(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_function(wrap_pyfunction!(process_capture, m)?)?;
    m.add_function(wrap_pyfunction!(process_samples, m)?)?;
    m.add_function(wrap_pyfunction!(captures, m)?)?;
    m.add_function(wrap_pyfunction!(read_capture, m)?)?;
    m.add_function(wrap_pyfunction!(transmission, m)?)?;
    m.add_function(wrap_pyfunction!(archive_units, m)?)?;
    m.add_function(wrap_pyfunction!(archive_process_unit, m)?)?;
    m.add_function(wrap_pyfunction!(archive_register, m)?)?;
    m.add_class::<Lab>()?;
    m.add_class::<session::Session>()?;
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    Ok(())
}
