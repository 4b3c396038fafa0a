//! A warm session on a bench (the Python package's `radbench.Bench`): the bench is opened and
//! connected once, then captured from as often as asked, the connections, the uploaded waveform
//! and the pipeline kept while the waveform and the options do not change. It is the path of
//! `radbench capture --repeat` and of a campaign's steps ([`Rig`], [`Prepared`]), not a second
//! one: the same preparation, capture under the safe-state guard, processing and files.
//!
//! Each call runs on the session's own runtime and hands back a [`Call`]: the caller waits for
//! it in bounded slices (Python checks its signals between them) and can stop it as Ctrl-C stops
//! the command, the bench put in its safe state before the call returns. Closing the session
//! (or dropping it) puts the bench in its safe state and releases the instruments and the
//! bench's lock ([`BenchLock`]: a second session on the same instruments is refused).

mod campaign;

pub use campaign::{CampaignEvents, CampaignSpec};

use super::bench_lock::BenchLock;
use super::capture_call::{calibration_warnings, prepare_out, resolve_correction, CaptureOptions};
use super::processed::InMemory;
use super::response_call::ResponseOptions;
use crate::catalog::Catalog;
use crate::driver::Journal;
use crate::driver::{RfPermit, SafeStateReport};
use crate::exit::bad_input;
use crate::measure::records::record::{capture_summary, keep_all};
use crate::measure::{self, Algorithm, Bench, BenchCalibration, BenchSource, BuiltIn};
use crate::measure::{CalibrateRequest, CaptureRequest, CorrectionMode, Interrupt};
use crate::measure::{MeasureError, Prepared};
use crate::measure::{ProcessOptions, Provenance, Recorder, Rig, StopSignal};
use crate::waveform::WaveformSpec;
use serde_json::{json, Value};
use std::future::Future;
use std::path::PathBuf;
use std::sync::{mpsc, Arc};
use std::time::Duration;

/// Longest wait for the bench's safe state and the end of a call when the session closes.
const CLOSE_TIMEOUT: Duration = Duration::from_secs(60);
/// Longest wait for the runtime's threads when the session ends.
const STOP_TIMEOUT: Duration = Duration::from_secs(10);

/// Which bench a session opens, as `radbench capture` chooses it.
#[derive(Debug, Clone, Default)]
pub struct SessionSource {
    /// A bench file; `None`: the built-in mock lab, started for the session.
    pub bench: Option<PathBuf>,
    /// The built-in mock lab's scene and scope (`--scene`, `--scope-model`), when given:
    /// refused with a bench file.
    pub built_in: Option<BuiltIn>,
    /// The explicit permit to switch RF on (`--allow-rf`).
    pub allow_rf: bool,
    /// The operator set the bench file's manual front ends (`driver = "manual"`) by hand: what
    /// the command line's typed `yes` says. Without it a bench with manual front ends is refused
    /// before anything radiates.
    pub manual_front_ends_confirmed: bool,
    /// Every instrument exchange journaled here (`--trace-io`).
    pub trace_io: Option<PathBuf>,
}

impl SessionSource {
    /// The bench's source, checked as the command line checks `--bench` beside `--scene` and
    /// `--scope-model`.
    fn source(&self) -> anyhow::Result<BenchSource> {
        match (&self.bench, &self.built_in) {
            (Some(_), Some(_)) => Err(bad_input(
                "scene, scope_model: apply to the built-in mock lab only; with a bench file, the \
                 file names the instruments (change a mock lab's scene through its control \
                 channel)",
            )),
            (Some(path), None) => Ok(BenchSource::File(path.clone())),
            (None, built_in) => Ok(BenchSource::BuiltIn(Box::new(
                built_in.clone().unwrap_or_default(),
            ))),
        }
    }
}

/// A call under way on the session's runtime.
pub struct Call<T> {
    done: mpsc::Receiver<anyhow::Result<T>>,
    interrupt: Interrupt,
}

impl<T> Call<T> {
    /// Its result, when it ends within `at_most`; `None` while it runs.
    pub fn wait(&self, at_most: Duration) -> Option<anyhow::Result<T>> {
        match self.done.recv_timeout(at_most) {
            Ok(result) => Some(result),
            Err(mpsc::RecvTimeoutError::Timeout) => None,
            Err(mpsc::RecvTimeoutError::Disconnected) => Some(Err(MeasureError::Worker(
                "the session's call ended without a result (it panicked)".into(),
            )
            .into())),
        }
    }

    /// Stops the call as Ctrl-C stops the command: the bench is put in its safe state and the
    /// call ends with the interruption (wait for it).
    pub fn stop(&self) {
        self.interrupt.raise(StopSignal::Interrupt);
    }
}

/// A session on a bench (see the module's documentation).
pub struct BenchSession {
    runtime: Option<tokio::runtime::Runtime>,
    warm: Option<Arc<tokio::sync::Mutex<Warm>>>,
    describe: String,
}

/// What a session keeps between calls.
struct Warm {
    bench: Bench,
    catalog: Catalog,
    /// `None` before the first connection, after an error lost it, after `doctor` and `close`.
    rig: Option<Rig>,
    /// The last request and its preparation (pipeline, plans, transmission).
    prepared: Option<(CaptureRequest, Prepared)>,
    journal: Option<Journal>,
    allow_rf: bool,
    manual_front_ends_confirmed: bool,
    closed: bool,
    _lock: BenchLock,
}

impl BenchSession {
    /// Opens the bench (starts the built-in mock lab when no bench file is given), takes its
    /// lock and connects every instrument. Nothing radiates.
    pub fn open(source: SessionSource) -> anyhow::Result<BenchSession> {
        let bench_source = source.source()?;
        let runtime = tokio::runtime::Builder::new_multi_thread()
            .worker_threads(2)
            .thread_name("radbench-session")
            .enable_all()
            .build()?;
        let opened = runtime.block_on(async {
            let journal = match &source.trace_io {
                Some(p) => Some(Journal::create(p, false)?),
                None => None,
            };
            let bench = Bench::open(bench_source).await?;
            let lock = BenchLock::take(&bench.file)?;
            let catalog = bench.file.catalog()?;
            let rig = Rig::connect(&bench, &catalog, journal.clone()).await?;
            anyhow::Ok(Warm {
                bench,
                catalog,
                rig: Some(rig),
                prepared: None,
                journal,
                allow_rf: source.allow_rf,
                manual_front_ends_confirmed: source.manual_front_ends_confirmed,
                closed: false,
                _lock: lock,
            })
        });
        match opened {
            Ok(warm) => Ok(BenchSession {
                describe: warm.bench.describe(),
                runtime: Some(runtime),
                warm: Some(Arc::new(tokio::sync::Mutex::new(warm))),
            }),
            Err(e) => {
                runtime.shutdown_timeout(STOP_TIMEOUT);
                Err(e)
            }
        }
    }

    /// Which bench this is, for the user.
    pub fn describe(&self) -> &str {
        &self.describe
    }

    /// Runs `work` on the session's state, on its runtime.
    fn spawn<T, F, Fut>(&self, work: F) -> Call<T>
    where
        T: Send + 'static,
        F: FnOnce(tokio::sync::OwnedMutexGuard<Warm>, Interrupt) -> Fut + Send + 'static,
        Fut: Future<Output = anyhow::Result<T>> + Send,
    {
        let (tx, done) = mpsc::channel();
        let interrupt = Interrupt::never();
        let call = Call {
            done,
            interrupt: interrupt.clone(),
        };
        let (Some(runtime), Some(warm)) = (&self.runtime, &self.warm) else {
            let _ = tx.send(Err(closed()));
            return call;
        };
        let warm = warm.clone();
        runtime.spawn(async move {
            let guard = warm.lock_owned().await;
            let result = if guard.closed {
                Err(closed())
            } else {
                work(guard, interrupt).await
            };
            let _ = tx.send(result);
        });
        call
    }

    /// [`spawn`](Self::spawn) for work whose future cannot move between threads (a
    /// campaign's): driven on a thread of its own, on the session's runtime.
    fn spawn_on_thread<T, F, Fut>(&self, work: F) -> Call<T>
    where
        T: Send + 'static,
        F: FnOnce(tokio::sync::OwnedMutexGuard<Warm>, Interrupt) -> Fut + Send + 'static,
        Fut: Future<Output = anyhow::Result<T>>,
    {
        let (tx, done) = mpsc::channel();
        let interrupt = Interrupt::never();
        let call = Call {
            done,
            interrupt: interrupt.clone(),
        };
        let (Some(runtime), Some(warm)) = (&self.runtime, &self.warm) else {
            let _ = tx.send(Err(closed()));
            return call;
        };
        let (handle, warm) = (runtime.handle().clone(), warm.clone());
        let failed = tx.clone();
        let started = std::thread::Builder::new()
            .name("radbench-session-call".into())
            .spawn(move || {
                let result = handle.block_on(async move {
                    let guard = warm.lock_owned().await;
                    if guard.closed {
                        Err(closed())
                    } else {
                        work(guard, interrupt).await
                    }
                });
                let _ = tx.send(result);
            });
        if let Err(e) = started {
            let _ = failed.send(Err(e.into()));
        }
        call
    }

    /// One capture as `radbench capture` takes it: warm when the waveform and options are
    /// those of the last one. `options.out`: the folder `radbench capture --out` would write;
    /// `None` writes nothing.
    pub fn capture(&self, options: CaptureOptions) -> Call<InMemory> {
        self.spawn(
            move |mut warm, interrupt| async move { warm.capture(options, &interrupt).await },
        )
    }

    /// `radbench calibrate --reference-range R`: the system delay measured on the reference
    /// target, stored in the bench file (a bench file's session uses it from now on); the
    /// built-in lab's is only returned. JSON as `radbench calibrate --json` prints it.
    pub fn calibrate(&self, reference_range_m: f64, search_m: f64) -> Call<Value> {
        self.spawn(move |mut warm, interrupt| async move {
            warm.calibrate(reference_range_m, search_m, &interrupt)
                .await
        })
    }

    /// `radbench calibrate response`: the chain's response measured on the reference pillar,
    /// checked to help, and stored (beside the bench file, or at `options.out`), named in the
    /// bench file so this session's later captures correct with it. JSON as `radbench calibrate
    /// response --json` prints it; a response that does not help is refused unless forced.
    pub fn calibrate_response(&self, options: ResponseOptions) -> Call<Value> {
        self.spawn(move |mut warm, interrupt| async move {
            warm.calibrate_response(options, &interrupt).await
        })
    }

    /// `radbench doctor --json`'s report. The session's connections are released for it (the
    /// doctor opens its own) and made again by the next capture.
    pub fn doctor(&self) -> Call<Value> {
        self.spawn(move |mut warm, interrupt| async move {
            if let Some(mut rig) = warm.rig.take() {
                rig.engage_safe_state().await;
            }
            warm.prepared = None;
            let report =
                measure::doctor::examine(&warm.bench, warm.journal.clone(), &interrupt).await?;
            Ok(serde_json::to_value(&report)?)
        })
    }

    /// `radbench campaign run SPEC [--bench FILE] [--out DIR]` (the session's bench file, if it
    /// has one; else the built-in mock lab the spec describes), its events to `to`. The
    /// session's connections are released for the run (the campaign connects as the command
    /// does); its lock is kept, so no other session comes in between. Ends with the run
    /// folder, or the error that stopped the run (the folder is resumable).
    pub fn campaign_run(
        &self,
        spec: CampaignSpec,
        out: Option<PathBuf>,
        retries: Option<usize>,
        to: CampaignEvents,
    ) -> Call<PathBuf> {
        self.spawn_on_thread(move |mut warm, interrupt| async move {
            warm.before_campaign().await?;
            let bench_file = warm.bench.path.clone();
            let permit = warm.permit();
            campaign::run(
                spec,
                bench_file.as_deref(),
                out,
                retries,
                to,
                permit,
                interrupt,
            )
            .await
        })
    }

    /// `radbench campaign resume DIR`: only the steps not measured yet (as
    /// [`campaign_run`](Self::campaign_run)).
    pub fn campaign_resume(&self, dir: PathBuf, to: CampaignEvents) -> Call<PathBuf> {
        self.spawn_on_thread(move |mut warm, interrupt| async move {
            warm.before_campaign().await?;
            campaign::resume(&dir, to, warm.permit(), interrupt).await
        })
    }

    /// Puts the bench in its safe state and releases the instruments; later calls are refused.
    /// The safe state's report.
    pub fn close(&self) -> Call<String> {
        self.spawn(move |mut warm, _| async move { Ok(warm.close().await.to_string()) })
    }
}

impl Drop for BenchSession {
    fn drop(&mut self) {
        let Some(runtime) = self.runtime.take() else {
            return;
        };
        if let Some(warm) = self.warm.take() {
            let _inside = runtime.enter();
            // Waits for a call still running (its own guard makes the bench safe), then closes.
            let _ = runtime.block_on(tokio::time::timeout(CLOSE_TIMEOUT, async {
                warm.lock().await.close().await;
            }));
            // The built-in lab stops inside the runtime that serves it.
            drop(warm);
        }
        runtime.shutdown_timeout(STOP_TIMEOUT);
    }
}

fn closed() -> anyhow::Error {
    bad_input("the bench session is closed: open a new one")
}

impl Warm {
    async fn close(&mut self) -> SafeStateReport {
        self.prepared = None;
        self.closed = true;
        match self.rig.take() {
            Some(mut rig) => rig.engage_safe_state().await,
            // Nothing connected: the last call's guard left the bench safe, or it never radiated.
            None => SafeStateReport::default(),
        }
    }

    /// The user's permit (`allow_rf` is checked by each call), with the operator's confirmation
    /// of the manual front ends when the session was opened with it.
    fn permit(&self) -> RfPermit {
        let permit = RfPermit::granted_by_user();
        if self.manual_front_ends_confirmed {
            permit.with_manual_front_ends_confirmed()
        } else {
            permit
        }
    }

    /// The permit checked, then the safe state, the connections released and the preparation
    /// dropped: a campaign connects itself.
    async fn before_campaign(&mut self) -> anyhow::Result<()> {
        if !self.allow_rf {
            return Err(MeasureError::NoPermit {
                run: "campaign's steps",
            }
            .into());
        }
        self.prepared = None;
        if let Some(mut rig) = self.rig.take() {
            rig.engage_safe_state().await;
        }
        Ok(())
    }

    /// Connects the rig again when an error or the doctor released it.
    async fn connected(&mut self) -> Result<(), MeasureError> {
        if self.rig.is_none() {
            let rig = Rig::connect(&self.bench, &self.catalog, self.journal.clone()).await?;
            self.rig = Some(rig);
        }
        Ok(())
    }

    /// The preparation of `request`: the last one when it is the same request, else a new
    /// one (its waveform uploaded while its pipeline is built).
    async fn prepared(
        &mut self,
        request: &CaptureRequest,
        repetitions: usize,
        interrupt: &Interrupt,
    ) -> Result<Prepared, MeasureError> {
        if let Some((last, prepared)) = self.prepared.take() {
            if same_request(&last, request) {
                return Ok(prepared);
            }
        }
        self.connected().await?;
        measure::prepare_uploading(
            &self.bench,
            &self.catalog,
            request,
            &mut self.rig,
            repetitions,
            interrupt,
        )
        .await
    }

    /// One measurement on the warm rig; the preparation kept for the next one.
    async fn measure(
        &mut self,
        request: CaptureRequest,
        repetitions: usize,
        interrupt: &Interrupt,
    ) -> Result<measure::Measurement, MeasureError> {
        let mut prepared = self.prepared(&request, repetitions, interrupt).await?;
        self.connected().await?;
        let permit = self.permit();
        let rig = self.rig.as_mut().expect("connected above");
        let measured = rig
            .measure(&self.bench, &mut prepared, repetitions, &permit, interrupt)
            .await;
        if measured.is_err() {
            // What the instruments hold after a failure is unknown: connect again next time.
            self.rig = None;
        }
        self.prepared = Some((request, prepared));
        measured
    }

    async fn capture(
        &mut self,
        o: CaptureOptions,
        interrupt: &Interrupt,
    ) -> anyhow::Result<InMemory> {
        if !self.allow_rf {
            return Err(MeasureError::NoPermit { run: "capture" }.into());
        }
        let mut options = o.choices.options(o.waveform);
        self.bench.file.processing_of_this_bench(&mut options);
        let calibration = resolve_correction(
            o.choices.correction,
            o.choices.calibration.as_deref(),
            &self.bench,
        )?;
        let mode = o.choices.correction.unwrap_or(CorrectionMode::Rx);
        options.correction = calibration.as_ref().map(|c| c.used_as(mode));
        let request = CaptureRequest {
            waveform: o.waveform_args.spec(o.waveform)?,
            payload: o.payload.as_ref().map(|p| p.as_bytes().to_vec()),
            seed: o.seed,
            options,
            tx_off: o.tx_off,
            wait_s: o.wait_s,
            background: o.background.clone(),
        };
        if let Some(out) = &o.out {
            prepare_out(out, o.force)?;
        }
        let mut m = self.measure(request, o.repetitions, interrupt).await?;
        if let Some(cal) = &calibration {
            let warnings = calibration_warnings(cal, &m.taken.identities);
            m.processing.processed.warnings.extend(warnings);
        }
        let provenance = Provenance {
            bench_file: self.bench.path.clone(),
            simulated: self.bench.is_simulated(),
        };
        let summary = match &o.out {
            Some(out) => {
                Recorder::new(out, &provenance)
                    .write(&mut m, &mut [], &keep_all)?
                    .1
            }
            None => capture_summary(&m, &provenance),
        };
        if let Some(signal) = interrupt.received() {
            // Stopped while processing: the capture is complete (and written), the bench safe.
            return Err(MeasureError::Interrupted {
                signal,
                report: m.taken.safe_state.to_string(),
            }
            .into());
        }
        Ok(InMemory {
            summary,
            options: m.processing.options,
            processed: m.processing.processed,
        })
    }

    async fn calibrate(
        &mut self,
        reference_range_m: f64,
        search_m: f64,
        interrupt: &Interrupt,
    ) -> anyhow::Result<Value> {
        measure::check(reference_range_m, search_m)?;
        if !self.allow_rf {
            return Err(MeasureError::NoPermit { run: "calibration" }.into());
        }
        // As `radbench calibrate`: with the response the bench file names corrected, the delay
        // is the corrected chain's.
        let correction = resolve_correction(None, None, &self.bench)?;
        let request = CaptureRequest {
            waveform: WaveformSpec::msk_lfm_default(),
            payload: None,
            seed: 1,
            options: ProcessOptions {
                algorithm: Algorithm::Correlation,
                system_delay_s: 0.0,
                min_range_m: 0.0,
                max_range_m: reference_range_m + search_m + 150.0,
                correction: correction.as_ref().map(|c| c.used()),
                ..ProcessOptions::default()
            },
            tx_off: false,
            wait_s: 10.0,
            background: None,
        };
        let m = self.measure(request, 1, interrupt).await?;
        let estimate =
            measure::estimate_delay(&m.processing.processed, reference_range_m, search_m)?;
        let calibration = BenchCalibration {
            system_delay_s: estimate.system_delay_s,
            reference_range_m: Some(reference_range_m),
            measured_at: Some(crate::storage::utc_now_rfc3339()),
            response: self
                .bench
                .file
                .calibration
                .as_ref()
                .and_then(|c| c.response.clone()),
        };
        if let Some(path) = &self.bench.path {
            measure::store_calibration(path, &calibration)?;
            self.bench.file.calibration = Some(calibration);
        }
        Ok(json!({
            "system_delay_s": estimate.system_delay_s,
            "reference_range_m": estimate.reference_range_m,
            "measured_range_m": estimate.measured_range_m,
            "stored_in": self.bench.path.as_ref().map(|p| p.display().to_string()),
        }))
    }
}

impl Warm {
    async fn calibrate_response(
        &mut self,
        o: ResponseOptions,
        interrupt: &Interrupt,
    ) -> anyhow::Result<Value> {
        if !self.allow_rf {
            return Err(MeasureError::NoPermit { run: "calibration" }.into());
        }
        let request = CalibrateRequest {
            waveform: o.waveform_args.spec(o.waveform)?,
            reference_range_m: o.reference_range_m,
            repetitions: o.repetitions,
            gate_s: measure::gate_or_default_s(o.gate_ns, o.reference_range_m),
            reflector_m: o.reflector_m,
        };
        // The calibration uploads its own waveform: the next capture prepares again.
        self.prepared = None;
        self.connected().await?;
        let permit = self.permit();
        let rig = self.rig.as_mut().expect("connected above");
        let calibrated =
            match measure::calibrate_with(rig, &self.bench, &request, &permit, interrupt).await {
                Ok(c) => c,
                Err(e) => {
                    self.rig = None;
                    return Err(e.into());
                }
            };
        let verdict = calibrated.verdict();
        if let (Err(why), false) = (&verdict, o.force) {
            return Err(MeasureError::CorrectionRefused(format!(
                "not stored: {why} (force=True stores it anyway)"
            ))
            .into());
        }
        let stored = match measure::response_path(o.out.as_deref(), &self.bench) {
            Some(path) => Some(measure::store_response(
                &calibrated,
                &path,
                &mut self.bench,
            )?),
            None => None,
        };
        let refused = verdict.err();
        Ok(measure::response_report(
            &calibrated,
            stored.as_ref(),
            refused.as_deref(),
        ))
    }
}

/// Whether a capture of `b` can reuse the preparation of `a` (everything it was made from).
fn same_request(a: &CaptureRequest, b: &CaptureRequest) -> bool {
    a.waveform == b.waveform
        && a.payload == b.payload
        && a.seed == b.seed
        && a.options == b.options
        && a.tx_off == b.tx_off
        && a.wait_s == b.wait_s
        && a.background == b.background
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::waveform::WaveformKind;

    /// Longest wait for one call in these tests.
    const CALL_TIMEOUT: Duration = Duration::from_secs(120);

    fn capture_options(keywords: &str) -> CaptureOptions {
        CaptureOptions::from_keywords(WaveformKind::MskLfm, keywords, 1, None).unwrap()
    }

    fn ended<T>(call: Call<T>) -> anyhow::Result<T> {
        call.wait(CALL_TIMEOUT).expect("the call ended in time")
    }

    /// The AWG's waveform definitions so far (one per upload).
    fn uploads(session: &BenchSession) -> usize {
        let warm = session.warm.as_ref().unwrap().blocking_lock();
        let lab = &warm.bench.lab.as_ref().unwrap().bench;
        lab.awg
            .log()
            .texts()
            .iter()
            .filter(|t| t.contains(":TRAC1:DEF"))
            .count()
    }

    fn lab_is_safe(session: &BenchSession) -> bool {
        let warm = session.warm.as_ref().unwrap().blocking_lock();
        warm.bench.lab.as_ref().unwrap().bench.is_safe()
    }

    #[test]
    fn captures_are_warm_until_the_options_change_and_a_stop_leaves_the_bench_safe() {
        let session = BenchSession::open(SessionSource {
            allow_rf: true,
            ..SessionSource::default()
        })
        .unwrap();
        let first = ended(session.capture(capture_options("{}"))).unwrap();
        let again = ended(session.capture(capture_options("{}"))).unwrap();
        assert_eq!(uploads(&session), 1, "the waveform is uploaded once");
        // The same target (each capture has its own noise).
        let range = |m: &InMemory| m.summary["targets"][0]["range_m"].as_f64().unwrap();
        assert!((range(&first) - range(&again)).abs() < 1e-3);
        assert!(first.summary.get("files").is_none(), "nothing written");
        // Another waveform parameter: prepared and uploaded again.
        ended(session.capture(capture_options(r#"{"seed": 2}"#))).unwrap();
        assert_eq!(uploads(&session), 2);
        // Stopped as Ctrl-C stops the command: the interruption, the bench safe.
        let call = session.capture(capture_options(r#"{"seed": 3}"#));
        call.stop();
        let err = ended(call).expect_err("stopped");
        assert!(
            matches!(
                err.downcast_ref::<MeasureError>(),
                Some(MeasureError::Interrupted { .. })
            ),
            "{err}"
        );
        assert!(lab_is_safe(&session));
        // The session goes on after the stop.
        ended(session.capture(capture_options("{}"))).unwrap();
        ended(session.close()).unwrap();
        assert!(lab_is_safe(&session));
        let err = ended(session.capture(capture_options("{}"))).err().unwrap();
        assert!(err.to_string().contains("closed"), "{err}");
    }

    #[test]
    fn without_the_permit_a_capture_is_refused_and_bad_keywords_are_named() {
        let session = BenchSession::open(SessionSource::default()).unwrap();
        let err = ended(session.capture(capture_options("{}"))).err().unwrap();
        assert!(
            matches!(
                err.downcast_ref::<MeasureError>(),
                Some(MeasureError::NoPermit { .. })
            ),
            "{err}"
        );
        let err =
            CaptureOptions::from_keywords(WaveformKind::MskLfm, r#"{"bandwith": 1e9}"#, 1, None)
                .unwrap_err()
                .to_string();
        assert!(err.contains("did you mean `bandwidth`"), "{err}");
        let err = CaptureOptions::from_keywords(
            WaveformKind::MskLfm,
            r#"{"window": "hanning"}"#,
            1,
            None,
        )
        .unwrap_err()
        .to_string();
        assert!(err.starts_with("window: "), "{err}");
    }

    #[test]
    fn a_second_session_on_the_same_instruments_is_refused_with_the_reason() {
        // A lab that runs on its own, and its bench file.
        let runtime = tokio::runtime::Runtime::new().unwrap();
        let lab = runtime
            .block_on(Bench::open(BenchSource::BuiltIn(Box::default())))
            .unwrap();
        let dir = tempfile::tempdir().unwrap();
        let file = dir.path().join("bench.toml");
        std::fs::write(&file, toml::to_string(&lab.file).unwrap()).unwrap();
        let source = SessionSource {
            bench: Some(file),
            ..SessionSource::default()
        };
        let first = BenchSession::open(source.clone()).unwrap();
        let err = BenchSession::open(source.clone()).err().expect("refused");
        let text = crate::exit::render(&err);
        assert!(text.contains("the instruments are in use"), "{text}");
        assert!(text.contains(&std::process::id().to_string()), "{text}");
        let class = err
            .downcast_ref::<crate::exit::Classified>()
            .map(|c| c.class);
        assert_eq!(class, Some(crate::exit::ExitClass::Instrument), "{text}");
        drop(first);
        let again = BenchSession::open(source).unwrap();
        drop(again);
        let _inside = runtime.enter();
        drop(lab);
    }
}
