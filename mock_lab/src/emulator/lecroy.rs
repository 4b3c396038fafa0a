//! Teledyne LeCroy LabMaster 10 Zi-A emulator (legacy 488.2 commands + the VBS automation
//! statements a driver uses), fixed 80 GSa/s, `Cn:WF? ALL` with a `LECROY_2_3` WAVEDESC.
//!
//! An acquisition completes only when the pluggable [`TriggerSource`] reports a marker edge (or the
//! trigger is forced); in sequence mode (`SampleMode = "Sequence"`, `NumSegments`) it records one
//! segment per edge and `WF? ALL` returns them all with a TRIGTIME array. The emulator never holds its lock while it waits for an edge, so a client can
//! poll `INR?` on another connection while one connection is blocked in `WAIT`.
//!
//! Errors follow the legacy LeCroy registers \[I\]: command errors set `CMR?` (1 unknown header,
//! 2 illegal header path, 3 illegal number, 5 unknown keyword, 11 bad block) and ESR bit 5;
//! execution errors set `EXR?` (22 environment, 25 parameter, 26 not implemented, 27 parameter
//! missing) and ESR bit 4. Out-of-range values are adapted to the nearest allowed value and flag
//! STB bit 2 (VAB), as the scope does.

mod commands;
mod params;
mod settings;
mod state;
pub(crate) use state::{Recording, NO_TRIGGER_TIME};
pub(crate) mod trigger;
mod vbs;
pub(crate) mod wavedesc;

use std::sync::atomic::Ordering;
use std::sync::{Arc, Mutex, MutexGuard};
use std::time::{Duration, Instant};

pub use state::{
    Acquisition, ChannelSettings, HeaderMode, RecordedChannel, RemoteInterface, SampleMode,
    ScopeState, TransferWindow, TriggerMode, EMULATOR_MAX_POINTS, SEQUENCE_REARM_S,
};
pub use trigger::{AcquisitionRequest, Capture, Slope, TestSignal, TriggerSetup, TriggerSource};

use super::received_log::ReceivedLog;
use super::scpi::message::{parse_unit, split_units};
use crate::catalog::{self, CatalogError, DigitizerModel};
use crate::server::Handler;

const LOG_CAPACITY: usize = 1000;
/// The longest a `WAIT` for a trigger edge goes without looking whether it was abandoned.
const WAIT_SLICE: Duration = Duration::from_millis(20);

/// Name written into WAVEDESC INSTRUMENT_NAME (honest: this is an emulator).
pub(crate) const WAVEDESC_INSTRUMENT_NAME: &str = "MOCK_LAB EMU";

/// A failure while running one command, mapped to the CMR/EXR registers.
#[derive(Debug, Clone, PartialEq, Eq)]
pub(crate) enum Fault {
    /// Command error: CMR code; abandons the rest of the message.
    Command(u8, String),
    /// Execution error: EXR code.
    Execution(u8, String),
}

/// The emulated scope.
pub struct Lecroy {
    /// Bumped by a device clear and by [`Lecroy::abandon_waits`]: a `WAIT` under way gives up.
    abandoned: std::sync::atomic::AtomicU64,
    model: DigitizerModel,
    inner: Mutex<ScopeState>,
    source: Arc<dyn TriggerSource>,
    log: ReceivedLog,
    wait_cap: Mutex<Duration>,
    /// Tells the lab when the remote interface changes, so it opens and closes the endpoints.
    remote_changes: tokio::sync::watch::Sender<RemoteInterface>,
}

impl Lecroy {
    /// A scope with `model`'s limits whose inputs see `source`, remote interface set to VICP.
    /// Refuses a model the emulator cannot work with (no sample rate, zero divisions).
    pub fn new(
        model: DigitizerModel,
        source: Arc<dyn TriggerSource>,
    ) -> Result<Lecroy, CatalogError> {
        catalog::check_digitizer(&model)?;
        let state = ScopeState::reset(&model, RemoteInterface::Vicp);
        Ok(Lecroy {
            abandoned: Default::default(),
            inner: Mutex::new(state),
            source,
            log: ReceivedLog::new("lecroy", LOG_CAPACITY),
            wait_cap: Mutex::new(Duration::from_secs(10)),
            remote_changes: tokio::sync::watch::Sender::new(RemoteInterface::Vicp),
            model,
        })
    }

    /// The built-in LabMaster 10 Zi-A model with a [`TestSignal`] (marker present, 1 GHz tone).
    pub fn embedded() -> Result<Lecroy, CatalogError> {
        Lecroy::new(catalog::lecroy()?, Arc::new(TestSignal::default()))
    }

    /// The built-in model with the given input source.
    pub fn embedded_with(source: Arc<dyn TriggerSource>) -> Result<Lecroy, CatalogError> {
        Lecroy::new(catalog::lecroy()?, source)
    }

    pub fn model(&self) -> &DigitizerModel {
        &self.model
    }

    pub fn log(&self) -> &ReceivedLog {
        &self.log
    }

    /// A copy of the settings and the last acquisition.
    pub fn state(&self) -> ScopeState {
        self.lock().clone()
    }

    /// Longest time `WAIT` without an argument blocks (the real scope waits forever).
    pub fn set_wait_cap(&self, cap: Duration) {
        *self.wait_cap.lock().unwrap_or_else(|e| e.into_inner()) = cap;
    }

    /// Chooses the remote-control protocol, as in Utilities > Remote on the scope.
    pub fn set_remote_interface(&self, remote: RemoteInterface) {
        self.lock().remote = remote;
        self.remote_changes.send_if_modified(|current| {
            let changed = *current != remote;
            *current = remote;
            changed
        });
    }

    /// Follows the remote interface: the receiver sees every change made by
    /// [`Lecroy::set_remote_interface`].
    pub(crate) fn watch_remote_interface(&self) -> tokio::sync::watch::Receiver<RemoteInterface> {
        self.remote_changes.subscribe()
    }

    pub fn remote_interface(&self) -> RemoteInterface {
        self.lock().remote
    }

    /// Whether a client on `via` is served. Servers call this when a link opens and refuse the link
    /// with this message (the scope has no listener for the disabled protocol).
    pub fn accepts(&self, via: RemoteInterface) -> Result<(), String> {
        let enabled = self.remote_interface();
        if enabled == via {
            Ok(())
        } else {
            Err(format!(
                "the scope's remote interface is set to {}, not {}: change Utilities > Utilities Setup > Remote",
                enabled.label(),
                via.label()
            ))
        }
    }

    /// A [`Handler`] for clients arriving over `via`; it serves nothing while the scope's remote
    /// interface is set to the other protocol.
    pub fn port(self: &Arc<Self>, via: RemoteInterface) -> LecroyPort {
        LecroyPort {
            scope: Arc::clone(self),
            via,
        }
    }

    /// The `.trc` file content of channel `n` (1-based) from the last acquisition: the `#9` block of
    /// `WF? ALL` in the current COMM_FORMAT/COMM_ORDER, exactly as the scope saves it.
    pub fn trc_bytes(&self, n: u8) -> Option<Vec<u8>> {
        let st = self.lock();
        let index = usize::from(n).checked_sub(1)?;
        if index >= st.channels.len() {
            return None;
        }
        Some(st.waveform(&self.model, index, WAVEDESC_INSTRUMENT_NAME))
    }

    fn lock(&self) -> MutexGuard<'_, ScopeState> {
        self.inner.lock().unwrap_or_else(|e| e.into_inner())
    }

    /// Completes a pending acquisition if the source delivers its edges (one per segment in
    /// sequence mode) before `deadline` (a past deadline polls). The lock is released while
    /// waiting.
    fn settle(&self, deadline: Instant) {
        let (request, arm_id, mode, segments, recording) = {
            let st = self.lock();
            if !st.armed {
                return;
            }
            let request = st.request(&self.model);
            let segments = st.segments_per_acquisition();
            let recording = st.recording(&self.model, &request, segments);
            (request, st.arm_id, st.trigger_mode, segments, recording)
        };
        let result = match mode {
            TriggerMode::Auto => {
                let (mut recording, ok) =
                    self.segments(&request, segments, Instant::now(), arm_id, recording);
                if ok {
                    Some((recording, false))
                } else {
                    // No edge: the scope forces the acquisition, starting the record again.
                    recording = self.lock().recording(&self.model, &request, segments);
                    self.forced_segments(&request, segments, &mut recording);
                    Some((recording, true))
                }
            }
            _ => {
                let (recording, ok) =
                    self.segments(&request, segments, deadline, arm_id, recording);
                ok.then_some((recording, false))
            }
        };
        if let Some((recording, forced)) = result {
            let times = segment_times(&request, &recording);
            let mut st = self.lock();
            if st.armed && st.arm_id == arm_id {
                st.complete(&request, recording, times, forced);
                tracing::debug!(
                    instrument = "lecroy",
                    forced,
                    segments,
                    "acquisition complete"
                );
            }
        }
    }

    /// One capture per segment, each at its own edge; None when an edge did not come by
    /// `deadline` (the acquisition stays incomplete, as on the scope), or when the wait was
    /// abandoned meanwhile: acquisition `arm_id` stopped or armed again (`STOP`, `ARM`), a
    /// device clear, or the lab shutting down. The edges are waited for in short slices so that
    /// an abandoned wait ends at once, and the segments still to come are not synthesised (a
    /// client gone after an interrupted capture kept a lab's shutdown waiting up to 10 s).
    fn segments(
        &self,
        request: &AcquisitionRequest,
        segments: u32,
        deadline: Instant,
        arm_id: u64,
        mut recording: Recording,
    ) -> (Recording, bool) {
        let generation = self.abandoned.load(Ordering::SeqCst);
        let current = || {
            let st = self.lock();
            st.armed && st.arm_id == arm_id && self.abandoned.load(Ordering::SeqCst) == generation
        };
        for _ in 0..segments {
            let capture = loop {
                if !current() {
                    return (recording, false);
                }
                let slice = deadline.min(Instant::now() + WAIT_SLICE);
                match self.source.acquire(request, slice) {
                    Some(capture) => break capture,
                    None if slice >= deadline => return (recording, false),
                    None => {}
                }
            };
            recording.push(capture);
        }
        (recording, true)
    }

    /// Ends every `WAIT` under way (the lab is shutting down: nobody will read its reply).
    pub fn abandon_waits(&self) {
        self.abandoned.fetch_add(1, Ordering::SeqCst);
    }

    fn forced_segments(&self, request: &AcquisitionRequest, segments: u32, into: &mut Recording) {
        for _ in 0..segments {
            into.push(self.source.force(request));
        }
    }

    /// Forces one acquisition now (FRTR): arms if needed and records without an edge.
    fn force(&self) {
        let mut st = self.lock();
        if !st.armed {
            st.arm();
        }
        let request = st.request(&self.model);
        let segments = st.segments_per_acquisition();
        let mut recording = st.recording(&self.model, &request, segments);
        self.forced_segments(&request, segments, &mut recording);
        let times = segment_times(&request, &recording);
        st.complete(&request, recording, times, true);
    }

    /// Runs one program message; returns the response bytes if it had queries.
    pub fn execute(&self, message: &[u8]) -> Option<Vec<u8>> {
        self.log.record(message);
        let units = match split_units(message) {
            Ok(units) => units,
            Err(e) => {
                self.record_fault(Fault::Command(11, e.text));
                return None;
            }
        };
        let mut responses: Vec<Vec<u8>> = Vec::new();
        for raw in units {
            let outcome = parse_unit(raw)
                .map_err(|e| Fault::Command(if e.code == -161 { 11 } else { 1 }, e.text))
                .and_then(|unit| self.run_unit(&unit));
            match outcome {
                Ok(Some(reply)) => responses.push(reply),
                Ok(None) => {}
                Err(fault) => {
                    let abort = matches!(fault, Fault::Command(..));
                    self.record_fault(fault);
                    if abort {
                        break;
                    }
                }
            }
        }
        if responses.is_empty() {
            return None;
        }
        let mut out = Vec::new();
        for (i, r) in responses.into_iter().enumerate() {
            if i > 0 {
                out.push(b';');
            }
            out.extend(r);
        }
        Some(out)
    }

    fn record_fault(&self, fault: Fault) {
        let mut st = self.lock();
        match fault {
            Fault::Command(code, text) => {
                tracing::debug!(instrument = "lecroy", code, %text, "command error");
                st.cmr = code;
                st.esr |= 0x20;
            }
            Fault::Execution(code, text) => {
                tracing::debug!(instrument = "lecroy", code, %text, "execution error");
                st.exr = code;
                st.esr |= 0x10;
            }
        }
    }

    fn wait_cap(&self) -> Duration {
        *self.wait_cap.lock().unwrap_or_else(|e| e.into_inner())
    }
}

/// Each segment's trigger time after the first's: the scope records a segment, re-arms, and
/// takes the next edge that comes after that. With repeating edges (the AWG's marker every
/// repetition) that is a whole number of periods; otherwise the next edge is taken as soon as
/// the scope is ready.
fn segment_times(request: &AcquisitionRequest, recording: &Recording) -> Vec<f64> {
    let after_trigger = (request.first_point_s + request.points as f64 / request.sample_rate)
        .max(0.0)
        + state::SEQUENCE_REARM_S;
    let spacing = match recording.edge_period_s() {
        Some(period) if period > 0.0 => (after_trigger / period).ceil().max(1.0) * period,
        _ => after_trigger,
    };
    (0..recording.segments().max(1))
        .map(|k| k as f64 * spacing)
        .collect()
}

impl Handler for Lecroy {
    fn message(&self, data: &[u8]) -> Vec<Vec<u8>> {
        self.execute(data).into_iter().collect()
    }

    fn device_clear(&self) {
        tracing::debug!(instrument = "lecroy", "device clear");
        self.abandon_waits();
    }

    fn status_byte(&self) -> u8 {
        self.lock().status_byte()
    }

    fn trigger(&self) {
        self.force();
    }
}

/// The scope as seen through one remote protocol (see [`Lecroy::port`]).
pub struct LecroyPort {
    scope: Arc<Lecroy>,
    via: RemoteInterface,
}

impl LecroyPort {
    pub fn scope(&self) -> &Arc<Lecroy> {
        &self.scope
    }
}

impl Handler for LecroyPort {
    fn message(&self, data: &[u8]) -> Vec<Vec<u8>> {
        match self.scope.accepts(self.via) {
            Ok(()) => self.scope.message(data),
            Err(reason) => {
                self.scope.log.record(data);
                tracing::warn!(instrument = "lecroy", %reason, "message refused");
                Vec::new()
            }
        }
    }

    fn device_clear(&self) {
        self.scope.device_clear();
    }

    fn status_byte(&self) -> u8 {
        self.scope.status_byte()
    }

    fn trigger(&self) {
        if self.scope.accepts(self.via).is_ok() {
            self.scope.trigger();
        }
    }
}
