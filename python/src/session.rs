//! `radbench._radbench.Session`: the warm bench session behind `radbench.Bench`
//! (`radbench::in_memory::BenchSession`). Every call runs on the session's runtime; this thread
//! waits for it in short slices with the GIL released and checks Python's signals between them,
//! so that Ctrl-C (or a notebook's interrupt) stops the call as it stops the command: the bench
//! is put in its safe state before the KeyboardInterrupt reaches the user.

use crate::{processed_dict, to_py, waveform_kind};
use pyo3::prelude::*;
use pyo3::types::PyDict;
use radbench::in_memory::{
    BenchSession, Call, CampaignEvents, CampaignSpec, CaptureOptions, ResponseOptions,
    SessionSource,
};
use radbench::measure::BuiltIn;
use std::path::PathBuf;
use std::sync::mpsc;
use std::time::Duration;

/// How long this thread waits for a call before it looks at Python's signals again.
const POLL: Duration = Duration::from_millis(50);
/// Longest wait, after a stop, for the call to put the bench in its safe state and end.
const STOP_TIMEOUT: Duration = Duration::from_secs(60);

/// Waits for `call` with the GIL released; a Python signal's exception stops it first.
fn wait_for<T: Send>(py: Python<'_>, call: Call<T>) -> PyResult<T> {
    wait_with_events(py, call, None)
}

/// A campaign's events and the callable that takes them (JSON text), each step acknowledged
/// once it ran, so that the run waits for it.
struct Events<'a, 'py> {
    events: mpsc::Receiver<serde_json::Value>,
    acks: mpsc::Sender<()>,
    callback: &'a Bound<'py, PyAny>,
}

impl Events<'_, '_> {
    fn deliver(&self) -> PyResult<()> {
        while let Ok(event) = self.events.try_recv() {
            let step = event.get("event").is_none();
            self.callback.call1((event.to_string(),))?;
            if step {
                let _ = self.acks.send(());
            }
        }
        Ok(())
    }
}

/// [`wait_for`], handing each event to its callable as it comes; an exception raised there
/// stops the call as Ctrl-C does (before the run's next step), then is raised.
fn wait_with_events<T: Send>(
    py: Python<'_>,
    mut call: Call<T>,
    events: Option<&Events<'_, '_>>,
) -> PyResult<T> {
    let deliver = || events.map_or(Ok(()), Events::deliver);
    loop {
        let (back, ended) = py.detach(move || {
            let ended = call.wait(POLL);
            (call, ended)
        });
        call = back;
        if let Some(result) = ended {
            // A Ctrl-C that came while the call was ending is still the user's: raised, as
            // Python would at its next instruction (the call's guard left the bench safe).
            py.check_signals()?;
            deliver()?;
            return result.map_err(to_py);
        }
        if let Err(raised) = py.check_signals().and_then(|()| deliver()) {
            call.stop();
            // The call's own guard makes the bench safe before it ends; the user's exception
            // (KeyboardInterrupt, or the callback's) is what they see.
            let _ = py.detach(move || call.wait(STOP_TIMEOUT));
            return Err(raised);
        }
    }
}

/// The channels of a campaign's events, and what Python keeps of them.
fn campaign_events<'a, 'py>(callback: &'a Bound<'py, PyAny>) -> (CampaignEvents, Events<'a, 'py>) {
    let (events_tx, events) = mpsc::channel();
    let (acks, acks_rx) = mpsc::channel();
    (
        CampaignEvents {
            events: events_tx,
            acks: Some(acks_rx),
        },
        Events {
            events,
            acks,
            callback,
        },
    )
}

#[pyclass(module = "radbench._radbench")]
pub(crate) struct Session {
    open: Option<BenchSession>,
}

impl Session {
    fn session(&self) -> PyResult<&BenchSession> {
        self.open
            .as_ref()
            .ok_or_else(|| to_py(radbench::exit::bad_input("the bench session is closed")))
    }
}

#[pymethods]
impl Session {
    /// `bench`: a bench file, or `None` for the built-in mock lab (`scene_toml` with its
    /// `origin`, or `scene_json`; `scope_model`).
    #[new]
    #[pyo3(signature = (bench=None, scene_toml=None, scene_json=None, origin="<scene>", allow_rf=false, scope_model=None, trace_io=None, manual_front_ends_confirmed=false))]
    #[allow(clippy::too_many_arguments)]
    fn new(
        py: Python<'_>,
        bench: Option<PathBuf>,
        scene_toml: Option<String>,
        scene_json: Option<String>,
        origin: &str,
        allow_rf: bool,
        scope_model: Option<String>,
        trace_io: Option<PathBuf>,
        manual_front_ends_confirmed: bool,
    ) -> PyResult<Self> {
        use mock_lab::scene::Scene;
        let bad = |m: String| to_py(radbench::exit::bad_input(m));
        let scene = match (scene_toml, scene_json) {
            (Some(t), _) => Some(Scene::from_toml(&t, origin).map_err(|e| bad(e.to_string()))?),
            (None, Some(j)) => {
                Some(serde_json::from_str::<Scene>(&j).map_err(|e| bad(format!("scene: {e}")))?)
            }
            (None, None) => None,
        };
        let scope_model = scope_model
            .map(|m| {
                m.parse()
                    .map_err(|e: String| bad(format!("scope_model: {e}")))
            })
            .transpose()?;
        // The built-in lab's choices, when any was made (refused beside a bench file).
        let built_in = (scene.is_some() || scope_model.is_some()).then(|| BuiltIn {
            scene: scene.unwrap_or_default(),
            scope_model: scope_model.unwrap_or_default(),
            ..BuiltIn::default()
        });
        let source = SessionSource {
            bench,
            built_in,
            allow_rf,
            manual_front_ends_confirmed,
            trace_io,
        };
        // Opening is bounded by the connections' own timeouts.
        let open = py
            .detach(move || BenchSession::open(source))
            .map_err(to_py)?;
        Ok(Session { open: Some(open) })
    }

    /// Which bench this is.
    fn describe(&self) -> PyResult<String> {
        Ok(self.session()?.describe().to_string())
    }

    /// One capture: `keywords` a JSON object of the processing choices and `radbench capture`'s
    /// own options; `out` the folder to write, or `None`.
    #[pyo3(signature = (waveform, keywords, repetitions=1, out=None))]
    fn capture<'py>(
        &self,
        py: Python<'py>,
        waveform: &str,
        keywords: &str,
        repetitions: usize,
        out: Option<PathBuf>,
    ) -> PyResult<Bound<'py, PyDict>> {
        let kind = waveform_kind(waveform)?;
        let options =
            CaptureOptions::from_keywords(kind, keywords, repetitions, out).map_err(to_py)?;
        let done = wait_for(py, self.session()?.capture(options))?;
        processed_dict(py, done)
    }

    /// `radbench calibrate --json`'s object, as JSON text.
    fn calibrate(&self, py: Python<'_>, reference_range: f64, search: f64) -> PyResult<String> {
        let found = wait_for(py, self.session()?.calibrate(reference_range, search))?;
        Ok(found.to_string())
    }

    /// `radbench calibrate response --json`'s object, as JSON text: `keywords` a JSON object
    /// of the waveform's options.
    #[pyo3(signature = (reference_range, waveform, keywords, repetitions, gate_ns=None, reflector=None, out=None, force=false))]
    #[allow(clippy::too_many_arguments)]
    fn calibrate_response(
        &self,
        py: Python<'_>,
        reference_range: f64,
        waveform: &str,
        keywords: &str,
        repetitions: usize,
        gate_ns: Option<f64>,
        reflector: Option<f64>,
        out: Option<PathBuf>,
        force: bool,
    ) -> PyResult<String> {
        let kind = waveform_kind(waveform)?;
        let options = ResponseOptions::from_keywords(
            kind,
            keywords,
            reference_range,
            repetitions,
            gate_ns,
            reflector,
            out,
            force,
        )
        .map_err(to_py)?;
        let found = wait_for(py, self.session()?.calibrate_response(options))?;
        Ok(found.to_string())
    }

    /// `radbench doctor --json`'s report, as JSON text.
    fn doctor(&self, py: Python<'_>) -> PyResult<String> {
        let report = wait_for(py, self.session()?.doctor())?;
        Ok(report.to_string())
    }

    /// `radbench campaign run`: `spec` a spec file, or `spec_json` the spec as a JSON object;
    /// `on_event` gets `{"event": "start", "dir"}` then each finished step (JSON text). The run
    /// folder.
    #[pyo3(signature = (on_event, spec=None, spec_json=None, out=None, retries=None))]
    fn campaign_run(
        &self,
        py: Python<'_>,
        on_event: Bound<'_, PyAny>,
        spec: Option<PathBuf>,
        spec_json: Option<String>,
        out: Option<PathBuf>,
        retries: Option<usize>,
    ) -> PyResult<PathBuf> {
        let spec = match (spec, spec_json) {
            (Some(p), _) => CampaignSpec::File(p),
            (None, Some(j)) => CampaignSpec::Json(j),
            (None, None) => {
                return Err(to_py(radbench::exit::bad_input(
                    "spec: give a campaign spec file or a dict",
                )))
            }
        };
        let (to, events) = campaign_events(&on_event);
        let call = self.session()?.campaign_run(spec, out, retries, to);
        wait_with_events(py, call, Some(&events))
    }

    /// `radbench campaign resume DIR`, with the events of [`Session::campaign_run`].
    fn campaign_resume(
        &self,
        py: Python<'_>,
        on_event: Bound<'_, PyAny>,
        dir: PathBuf,
    ) -> PyResult<PathBuf> {
        let (to, events) = campaign_events(&on_event);
        let call = self.session()?.campaign_resume(dir, to);
        wait_with_events(py, call, Some(&events))
    }

    /// Puts the bench in its safe state and ends the session (its report); again: nothing.
    fn close(&mut self, py: Python<'_>) -> PyResult<Option<String>> {
        let Some(open) = self.open.take() else {
            return Ok(None);
        };
        let report = wait_for(py, open.close());
        // Dropping the session stops its runtime (and a built-in lab), off the GIL.
        py.detach(move || drop(open));
        match report {
            Ok(r) => Ok(Some(r)),
            Err(e) => Err(e),
        }
    }

    fn is_open(&self) -> bool {
        self.open.is_some()
    }
}
