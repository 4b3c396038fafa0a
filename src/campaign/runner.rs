//! The runner: the steps (connect, place the targets, set the simulated scene, capture under the
//! safe-state guard, hand the capture to the worker), settling the steps the worker finished, and
//! the finish (`results.json`, the report, the manifest, the final safe state).

use super::error::{io, CampaignError};
use super::folder::FolderIdentity;
use super::manifest::{
    self, FileRecord, Instruments, Manifest, Session, Status, StepStatus, Timing,
};
use super::plan::{Plan, Step};
use super::positioner::{LineSource, Positioner};
use super::prepare::PreparedSet;
use super::report;
use super::results::{self, Results, StepResult};
use super::run::{Finished, Observer, StepDone, Summary, RESULTS_FILE, STEP_RESULT};
use super::step_job::{JournalPart, StepJob, WorkerOutcome, WorkerSide};
use super::worker::StepWorker;
use crate::catalog::Catalog;
use crate::driver::{Journal, RfPermit};
use crate::exit::Classify;
use crate::measure::bench::scene_control::{Scene, SceneControlError, Target};
use crate::measure::Interrupt;
use crate::measure::MeasureError;
use crate::measure::Provenance;
use crate::measure::{Bench, BenchSource};
use crate::measure::{Rig, Taken};
use crate::storage::write_atomic;
use serde_json::json;
use std::collections::VecDeque;
use std::path::{Path, PathBuf};
use std::sync::{Arc, Mutex};
use std::time::Instant;

pub(super) fn new_session(kind: &str, now: &str, journal: &Path) -> Session {
    Session {
        kind: kind.into(),
        started: now.into(),
        ended: None,
        journal: journal.to_path_buf(),
        skipped: Vec::new(),
        remeasured: Vec::new(),
        forced: None,
        final_safe_state: None,
        timing: Timing::default(),
    }
}

/// A captured step that the worker processes (every algorithm), writes, hashes and records in
/// the manifest while the next steps are captured.
struct PendingStep {
    step: Step,
    outcome: tokio::sync::oneshot::Receiver<WorkerOutcome>,
}

/// Most captured steps waiting for (or with) the worker. Two lets a step whose processing and
/// files took longer than one capture catch up during the next one, instead of holding it;
/// more would only hide a worker that cannot keep up, and hold more captures in memory.
const STEPS_IN_FLIGHT: usize = 2;

/// The connected bench.
struct Connection {
    bench: Bench,
    rig: Rig,
}

pub(super) struct Runner {
    dir: PathBuf,
    /// The run folder as it was when this session opened it: checked before every write.
    folder: FolderIdentity,
    pub(super) manifest: Manifest,
    plan: Plan,
    prepared: PreparedSet,
    /// The levels each waveform's plan had before any step changed them.
    base_levels: Vec<Levels>,
    /// Each waveform's capture size, for the disk check before each step.
    costs: Vec<crate::campaign::WaveformCost>,
    /// The AWG amplitude and V/div the last capture was configured with (a change uploads
    /// again: the AWG and scope take them with the waveform).
    configured: Option<(f64, f64)>,
    journal: Option<Journal>,
    permit: RfPermit,
    interrupt: Interrupt,
    positioner: Option<Positioner>,
    connection: Option<Connection>,
    /// The scene every step starts from (simulated benches).
    base_scene: Option<Scene>,
    /// Whether the next placement is the first of this session (the targets' position unknown).
    first_placement: bool,
    /// Whether this session has checked the instruments' identities.
    identified: bool,
    /// Whether the simulated lab reseeds its noise on request (`None`: not asked yet).
    reseed: Option<bool>,
    /// Whether the user was told that the noise will not be reproducible.
    warned_noise: bool,
    force: bool,
    /// Processes and writes the steps beside the captures.
    worker: StepWorker,
    worker_side: Arc<Mutex<WorkerSide>>,
    /// The steps handed to the worker and not collected yet, oldest first.
    pending: VecDeque<PendingStep>,
    /// When the session began (before its preparation).
    pub(super) started: Instant,
    measured: usize,
    skipped: usize,
    pub(super) timing: Timing,
    /// The manifest's retries already handed to a step's journal line (or in the file).
    retries_journaled: usize,
}

impl Runner {
    #[allow(clippy::too_many_arguments)]
    pub(super) fn new(
        dir: PathBuf,
        manifest: Manifest,
        mut prepared: PreparedSet,
        journal_path: PathBuf,
        permit: RfPermit,
        interrupt: Interrupt,
        input: Option<LineSource>,
        force: bool,
    ) -> Result<Runner, CampaignError> {
        let plan = manifest.plan.clone();
        let journal_file = if journal_path.is_absolute() {
            journal_path
        } else {
            dir.join(journal_path)
        };
        let journal = Journal::create(&journal_file, false).map_err(|e| CampaignError::Io {
            path: journal_file.clone(),
            source: std::io::Error::other(e.to_string()),
        })?;
        let positioner = plan.positioner.clone().map(|p| Positioner::new(p, input));
        let worker_side = Arc::new(Mutex::new(WorkerSide::lend_all(&mut prepared)?));
        let worker = StepWorker::start().map_err(|e| CampaignError::Io {
            path: dir.clone(),
            source: e,
        })?;
        let folder = FolderIdentity::of(&dir)?;
        Ok(Runner {
            folder,
            base_levels: prepared
                .base
                .iter()
                .map(|p| Levels::of(&p[0].plan))
                .collect(),
            configured: None,
            costs: prepared.costs(),
            base_scene: plan.bench.scene.clone().or(manifest.base_scene.clone()),
            dir,
            plan,
            manifest,
            prepared,
            journal: Some(journal),
            permit,
            interrupt,
            positioner,
            connection: None,
            first_placement: true,
            identified: false,
            reseed: None,
            warned_noise: false,
            force,
            worker,
            worker_side,
            pending: VecDeque::new(),
            started: Instant::now(),
            measured: 0,
            skipped: 0,
            timing: Timing::default(),
            retries_journaled: 0,
        })
    }

    /// Runs every step not done yet, then writes the results, the report and the manifest.
    pub(super) async fn execute(
        mut self,
        observer: &mut dyn Observer,
    ) -> Result<Finished, CampaignError> {
        let t = Instant::now();
        self.folder.check(&self.dir)?;
        self.store_manifest(true)?;
        self.retries_journaled = self.manifest.retries.len();
        // Every step's table is in the file now: keep only the steps' states (memory stays flat
        // over a long run; see `manifest_store`).
        for step in &mut self.manifest.steps {
            *step = step.status_only();
        }
        self.timing.overhead_s += t.elapsed().as_secs_f64();
        let mut stopped = self.steps(observer).await.err();
        // The last steps' files (also when the run stopped: a capture taken is kept).
        if let Err(e) = self.settle_all(observer).await {
            match &stopped {
                None => stopped = Some(e),
                Some(_) => observer.note(&format!("the last step's files: {e}")),
            }
        }
        // Nothing radiates between measurements and every measurement's guard ran the safe
        // state; run it once more on whatever is connected (a bench found in an unknown state
        // and left by an error before its first capture), then close the links.
        let mut safe = true;
        if let Some(conn) = self.connection.take() {
            let report = conn.rig.safe_state().engage().await;
            safe = report.is_safe();
            if !safe {
                observer.note(&format!(
                    "WARNING: the final safe state did not complete: {report}; switch the bench \
                     off by hand"
                ));
            }
            self.manifest.session_mut().final_safe_state = Some(report.to_string());
        }
        let t = Instant::now();
        let outcome = self.finish(stopped).await;
        self.timing.overhead_s += t.elapsed().as_secs_f64();
        outcome.map_err(|e| {
            let e = self.unrecorded(e, safe);
            self.record_status_in_place(&e, observer);
            e
        })
    }

    /// The session's end could not be stored whole (`e`): the manifest's status room, rewritten
    /// in place, says `interrupted` and why, so that the folder does not claim a process still
    /// works on it (see the manifest's module docs).
    fn record_status_in_place(&mut self, e: &CampaignError, observer: &mut dyn Observer) {
        if matches!(e, CampaignError::FolderLost { .. }) {
            return;
        }
        let m = &mut self.manifest;
        m.status = Status::Interrupted;
        if m.reason.is_none() {
            m.reason = Some(format!(
                "every step was measured, but the run's end could not be written: {}",
                match e {
                    CampaignError::Unrecorded { source, .. } => crate::exit::render_chain(source),
                    other => crate::exit::render_chain(other),
                }
            ));
        }
        m.exit_code = Some(e.exit_class().code());
        if let Err(err) = m.store_status_in_place(&self.dir) {
            observer.note(&format!(
                "the manifest's status could not be recorded either ({err}): readers take a \
                 `running` manifest with no process holding the folder's lock as interrupted"
            ));
        }
    }

    /// A session's end that could not be written (`results.json`, the report, the manifest: a
    /// read-only file system, a full disk) as the error the user sees: the write that failed,
    /// why the run had stopped, the bench's state and how to go on. The bare write error ("cannot
    /// write results.json") dropped the stop it was to record (the step whose files had failed)
    /// and said nothing of resuming.
    fn unrecorded(&self, e: CampaignError, safe: bool) -> CampaignError {
        if matches!(e, CampaignError::FolderLost { .. }) {
            return e;
        }
        if let Some(lost) = self.folder.lost(&self.dir) {
            return lost;
        }
        CampaignError::Unrecorded {
            dir: self.dir.clone(),
            stopped: self.manifest.reason.clone(),
            safe,
            source: Box::new(e),
        }
    }

    async fn steps(&mut self, observer: &mut dyn Observer) -> Result<(), CampaignError> {
        let n = self.plan.steps.len();
        for k in 0..n {
            let step = self.plan.steps[k].clone();
            if self.manifest.steps[k].status == StepStatus::Done {
                self.settle_all(observer).await?;
                let result = self.stored_result(&step)?;
                self.skipped += 1;
                self.manifest.session_mut().skipped.push(step.index);
                observer.step_done(&StepDone {
                    step: &step,
                    of: n,
                    result: &result,
                    primary: self.plan.algorithm_names_of(step.processing)[0],
                    dir: self.dir.join(step.dir_name()),
                    skipped: true,
                });
                // The targets may have been moved since: place them again at the next step.
                self.first_placement = true;
                continue;
            }
            if let Some(signal) = self.interrupt.received() {
                return Err(CampaignError::Interrupted {
                    signal,
                    where_: format!("before step {} of {n}; nothing was radiating", step.index),
                });
            }
            // Before any RF of the step: is there room for its files? (A step before that
            // failed to write is the first failure, and the one reported.)
            let needed = self.plan.estimate_step_files_bytes(k, &self.costs);
            let when = format!("for step {} of {n}", step.index);
            if let Err(e) = super::disk::check(&self.dir, needed, &when, 0) {
                self.settle_all(observer).await?;
                return Err(e);
            }
            self.measure_step_retrying(k, &step, observer).await?;
            if let Some(signal) = self.interrupt.received() {
                if k + 1 < n {
                    return Err(CampaignError::Interrupted {
                        signal,
                        where_: format!("after step {} of {n} (its capture is kept)", step.index),
                    });
                }
            }
        }
        Ok(())
    }

    /// A step measured by an earlier session: its stored result.
    fn stored_result(&self, step: &Step) -> Result<StepResult, CampaignError> {
        let path = self.dir.join(step.dir_name()).join(STEP_RESULT);
        let text = std::fs::read_to_string(&path).map_err(io(&path))?;
        serde_json::from_str(&text).map_err(|e| CampaignError::Manifest {
            path,
            message: format!("not a step result: {e}"),
        })
    }

    /// The simulated scene of a step: the base scene with the step's noise seed, SNR and the
    /// targets where the positioner puts them; `placed`: the targets a program or the operator
    /// placed on the bench (the lab's own, as they stand now), kept as they are.
    fn step_scene(&self, step: &Step, placed: Option<Vec<Target>>) -> Option<Scene> {
        let mut scene = self.base_scene.clone()?;
        if let Some(targets) = placed {
            scene.targets = targets;
        }
        if let Some(seed) = step.noise_seed {
            scene.seed = seed;
        }
        if let Some(snr) = step.nominal.snr_db {
            scene.snr_db = snr;
        }
        if let Some(p) = &self.positioner {
            p.place_in_scene(&step.nominal, &mut scene);
        }
        if let Some(v) = step.nominal.velocity_mps {
            for t in &mut scene.targets {
                t.velocity_mps = v;
            }
        }
        Some(scene)
    }

    /// Connects for `step`: a fresh built-in lab with the step's scene, or the bench file's
    /// instruments once.
    async fn connect(&mut self, step: &Step) -> Result<(), CampaignError> {
        let built_in = self.plan.bench.file.is_none();
        if built_in && (self.reseed == Some(false) || self.connection.is_none()) {
            // A fresh lab per step when it cannot reseed its noise (see the module docs). Close
            // the previous lab's links before its servers go.
            self.connection = None;
            let scene = self.step_scene(step, None).unwrap_or_default();
            let bench = Bench::open(BenchSource::BuiltIn(Box::new(
                self.plan.bench.built_in(scene),
            )))
            .await?;
            let rig = Rig::connect(&bench, &catalog(&bench)?, self.journal.clone()).await?;
            self.connection = Some(Connection { bench, rig });
        } else if self.connection.is_none() {
            let path = self.plan.bench.file.clone().expect("a bench file");
            let bench = Bench::open(BenchSource::File(path)).await?;
            let rig = Rig::connect(&bench, &catalog(&bench)?, self.journal.clone()).await?;
            self.connection = Some(Connection { bench, rig });
        }
        if self.plan.bench.simulated && self.reseed.is_none() {
            // Does the lab reseed its noise on request? (mock_lab's `seed` control request; a lab
            // without it refuses and changes nothing.)
            let conn = self.connection.as_ref().expect("connected");
            let seed = step.noise_seed.unwrap_or(self.plan.seed);
            self.reseed = Some(conn.bench.reseed(seed).await.is_ok());
        }
        if !self.identified {
            self.identified = true;
            let conn = self.connection.as_ref().expect("connected");
            let now = Instruments::from(conn.rig.identities());
            match &self.manifest.instruments {
                None => self.manifest.instruments = Some(now),
                Some(then) if *then == now => {}
                Some(then) => {
                    let what = format!(
                        "the instruments answer differently than when the run was measured \
                         (then: {then:?}; now: {now:?})"
                    );
                    if !self.force {
                        return Err(CampaignError::DifferentBench { what });
                    }
                    let s = self.manifest.session_mut();
                    s.forced = Some(match s.forced.take() {
                        Some(f) => format!("{f}; {what}"),
                        None => what,
                    });
                }
            }
            // A bench file's simulated lab: the scene every step starts from.
            if self.base_scene.is_none() && self.plan.bench.simulated {
                let scene = conn.bench.scene().await.map_err(control)?;
                self.manifest.base_scene = Some(scene.clone());
                self.base_scene = Some(scene);
            }
        }
        Ok(())
    }

    /// On a simulated bench whose targets a program or the operator places (a `command` or
    /// `prompt` positioner, as in a rehearsal of the lab's stage script moving the simulated
    /// pillar over the control channel): the lab's targets as they stand, which the step's scene
    /// keeps (only the noise seed and the SNR are the step's). `None` when the runner places them.
    async fn placed_targets(&self) -> Result<Option<Vec<Target>>, CampaignError> {
        let Some(p) = &self.positioner else {
            return Ok(None);
        };
        let Some(conn) = &self.connection else {
            return Ok(None);
        };
        if !p.places_real_targets() || !self.plan.bench.simulated {
            return Ok(None);
        }
        Ok(Some(conn.bench.scene().await.map_err(control)?.targets))
    }

    /// [`measure_step`](Self::measure_step), measured again from the start after a transient
    /// fault (see `retry`), at most `plan.retries` times: before each retry the bench is put in
    /// its safe state, its links closed (opened again, identities checked again, by the retry),
    /// the retry recorded and told, and the wait (doubled each time) passed. A fault that is not
    /// transient, or one that outlasts the retries, stops the run as without retries.
    async fn measure_step_retrying(
        &mut self,
        k: usize,
        step: &Step,
        observer: &mut dyn Observer,
    ) -> Result<(), CampaignError> {
        let mut attempt = 0;
        loop {
            let e = match self.measure_step(k, step, observer).await {
                Ok(()) => return Ok(()),
                Err(e) => e,
            };
            let Some(instrument) = super::retry::transient_instrument(&e) else {
                return Err(e);
            };
            if attempt >= self.plan.retries {
                return Err(e);
            }
            attempt += 1;
            let instrument = instrument.to_string();
            let fault = crate::exit::render_chain(&e);
            let at = crate::time::rfc3339_millis(std::time::SystemTime::now());
            // The capture's guard has run the safe state already; once more on every link, and
            // then they are closed: the retry connects afresh.
            let safe_state = match self.connection.take() {
                Some(conn) => conn.rig.safe_state().engage().await.to_string(),
                None => "nothing was connected".into(),
            };
            self.identified = false;
            self.first_placement = true;
            let wait = super::retry::backoff(self.plan.retry_backoff_s, attempt);
            let n = self.plan.steps.len();
            // A link's error names its instrument already ("scope: VICP::...: ..."): once.
            let told = fault
                .strip_prefix(&format!("{instrument}: "))
                .unwrap_or(&fault);
            let text = format!(
                "step {} of {n}: {instrument}: {told}; safe state: {safe_state}; retry \
                 {attempt} of {} in {:.1} s",
                step.index,
                self.plan.retries,
                wait.as_secs_f64()
            );
            let record = super::retry::RetryRecord {
                step: step.index,
                attempt,
                instrument,
                fault,
                at,
                safe_state,
                wait_s: wait.as_secs_f64(),
            };
            observer.retrying(&super::run::Retrying {
                record: &record,
                of: n,
                retries: self.plan.retries,
                text: &text,
            });
            self.manifest.retries.push(record);
            tokio::select! {
                () = tokio::time::sleep(wait) => {}
                signal = self.interrupt.wait() => return Err(CampaignError::Interrupted {
                    signal,
                    where_: format!(
                        "waiting to retry step {} of {n}, which will be measured again; \
                         nothing was radiating",
                        step.index
                    ),
                }),
            }
        }
    }

    /// Measures step `k` and hands its files to the writer (see [`Runner::settle_oldest`]).
    async fn measure_step(
        &mut self,
        k: usize,
        step: &Step,
        observer: &mut dyn Observer,
    ) -> Result<(), CampaignError> {
        let n = self.plan.steps.len();
        let t_bench = Instant::now();
        self.connect(step).await?;
        if self.plan.moves_at(k, self.first_placement) {
            if let Some(p) = self.positioner.as_mut() {
                p.place(&step.nominal.ranges(), step.index, n, &self.interrupt)
                    .await?;
            }
            self.first_placement = false;
        }
        let scene = self.step_scene(step, self.placed_targets().await?);
        let reseeds = self.reseed == Some(true);
        // A built-in lab started afresh for this step already has its scene.
        let started_with_scene = self.plan.bench.file.is_none() && !reseeds;
        if !reseeds && !started_with_scene && !self.warned_noise {
            self.warned_noise = true;
            observer.note(
                "note: this simulated bench cannot reseed its noise per step (it refused \
                 {\"cmd\":\"seed\"}): a resumed run will differ from an uninterrupted one in \
                 the noise",
            );
        }
        let conn = self.connection.as_mut().expect("connected");
        if let (Some(scene), false) = (scene, started_with_scene) {
            conn.bench.set_scene(&scene).await.map_err(control)?;
            if reseeds {
                conn.bench.reseed(scene.seed).await.map_err(control)?;
            }
        }
        observer.step_starting(step, n, &conn.bench);
        let w = step.waveform;
        let primary = self.prepared.get_mut(w, step.processing, 0, step.music_p);
        let levels = self.base_levels[w].with(&step.nominal);
        levels.set(&mut primary.plan);
        let configured = (levels.awg_vpp, levels.volts_per_div);
        if self.configured.is_some_and(|c| c != configured) {
            conn.rig.forget_upload();
        }
        self.configured = Some(configured);
        let taken = conn
            .rig
            .acquire(
                &conn.bench,
                primary,
                step.nominal.repetitions.unwrap_or(self.plan.repetitions),
                &self.permit,
                &self.interrupt,
            )
            .await
            .map_err(|e| match e {
                MeasureError::Interrupted { signal, report } => CampaignError::Interrupted {
                    signal,
                    where_: format!(
                        "during step {} of {n}, which will be measured again (safe state: \
                         {report})",
                        step.index
                    ),
                },
                other => other.into(),
            })?;
        self.timing.bench_s += t_bench.elapsed().as_secs_f64();
        // The steps before were processed and written while this one was captured: wait for
        // the oldest when the worker has its fill, then hand this step over. A failure of a step
        // before still hands this capture to the worker, so it is written before the run stops.
        let before = if self.pending.len() >= STEPS_IN_FLIGHT {
            self.settle_oldest(observer).await
        } else {
            Ok(())
        };
        self.hand_over(step, taken);
        before
    }

    /// Gives `taken` to the worker, which processes it with every algorithm, writes the step's
    /// files, hashes them and stores the manifest recording it.
    fn hand_over(&mut self, step: &Step, taken: Taken) {
        // What the step's journal line records beside the step (the worker's store has every
        // step's table; the head is stored whole at the session's end).
        let part = JournalPart {
            session: self.manifest.sessions.len(),
            retries: self.manifest.retries[self.retries_journaled..].to_vec(),
            timing: self.timing.clone(),
        };
        self.retries_journaled = self.manifest.retries.len();
        let job = StepJob {
            dir: self.dir.clone(),
            folder: self.folder,
            step: step.clone(),
            names: self.plan.algorithm_names_of(step.processing),
            bandwidth_hz: self.plan.waveforms[step.waveform].bandwidth_hz(),
            output: self.plan.output,
            provenance: Provenance {
                bench_file: self.plan.bench.file.clone(),
                simulated: self.plan.bench.simulated,
            },
        };
        let side = self.worker_side.clone();
        let outcome = self.worker.submit(move || job.run(&side, taken, part));
        self.pending.push_back(PendingStep {
            step: step.clone(),
            outcome,
        });
    }

    /// Collects every step handed to the worker.
    async fn settle_all(&mut self, observer: &mut dyn Observer) -> Result<(), CampaignError> {
        let mut first_error = None;
        while !self.pending.is_empty() {
            if let Err(e) = self.settle_oldest(observer).await {
                match first_error {
                    None => first_error = Some(e),
                    Some(_) => observer.note(&format!("a later step: {e}")),
                }
            }
        }
        first_error.map_or(Ok(()), Err)
    }

    /// Waits for the oldest step the worker has, records it done and tells the observer.
    async fn settle_oldest(&mut self, observer: &mut dyn Observer) -> Result<(), CampaignError> {
        let Some(p) = self.pending.pop_front() else {
            return Ok(());
        };
        let t = Instant::now();
        let outcome = p.outcome.await.map_err(|_| {
            CampaignError::Measure(MeasureError::Worker(format!(
                "step {}'s processing stopped with a panic",
                p.step.index
            )))
        })?;
        let waited = t.elapsed().as_secs_f64();
        self.timing.wait_s += waited;
        self.timing.processing_s += outcome.processing_s;
        let (result, written) = outcome.done?;
        self.timing.files_s += written.files_s;
        self.timing.overhead_s += written.overhead_s;
        tracing::debug!(
            step = p.step.index,
            processing_s = outcome.processing_s,
            files_s = written.files_s,
            bookkeeping_s = written.overhead_s,
            waited_s = waited,
            "step processed and written"
        );
        *self.manifest.step_mut(p.step.index) = written.record;
        self.measured += 1;
        observer.step_done(&StepDone {
            step: &p.step,
            of: self.plan.steps.len(),
            result: &result,
            primary: self.plan.algorithm_names_of(p.step.processing)[0],
            dir: self.dir.join(p.step.dir_name()),
            skipped: false,
        });
        Ok(())
    }

    /// Stores the manifest: `whole` from its records (before the first step), else its head with
    /// the step tables the worker's store last recorded, in the file or its step journal (no job
    /// runs: every step handed over has been collected).
    fn store_manifest(&mut self, whole: bool) -> Result<(), CampaignError> {
        let mut side = self.worker_side.lock().unwrap_or_else(|p| p.into_inner());
        if whole {
            side.store.store_whole(&mut self.manifest, &self.dir)
        } else {
            side.store.store(&mut self.manifest, &self.dir)
        }
    }

    /// `results.json` with every step that has a result, in step order, and `results.csv` from
    /// it. The results are read back from the steps' folders (each step's `result.json`, as a
    /// resume reads the steps it keeps), not held in memory over the run.
    fn write_results(&mut self) -> Result<Results, CampaignError> {
        self.folder.check(&self.dir)?;
        let mut steps = Vec::new();
        for (k, step) in self.plan.steps.iter().enumerate() {
            if self.manifest.steps[k].status == StepStatus::Done {
                steps.push(self.stored_result(step)?);
            }
        }
        let results = Results { steps };
        let path = self.dir.join(RESULTS_FILE);
        write_atomic(&path, format!("{:#}\n", json!(results)).as_bytes())?;
        self.manifest
            .set_file(FileRecord::of(&self.dir, Path::new(RESULTS_FILE))?);
        write_atomic(
            &self.dir.join(results::CSV_FILE),
            results::to_csv(&results).as_bytes(),
        )?;
        self.manifest
            .set_file(FileRecord::of(&self.dir, Path::new(results::CSV_FILE))?);
        Ok(results)
    }

    async fn finish(&mut self, stopped: Option<CampaignError>) -> Result<Finished, CampaignError> {
        let status = if stopped.is_some() {
            Status::Interrupted
        } else {
            Status::Complete
        };
        let first_pending = self
            .manifest
            .steps
            .iter()
            .find(|s| s.status != StepStatus::Done)
            .map(|s| s.index);
        self.manifest.status = status;
        let n = self.plan.steps.len();
        self.manifest.reason = stopped.as_ref().map(|e| match (e, first_pending) {
            (CampaignError::Interrupted { .. }, _) | (_, None) => crate::exit::render_chain(e),
            (_, Some(k)) => format!("step {k} of {n}: {}", crate::exit::render_chain(e)),
        });
        self.manifest.stopped_at_step = stopped.as_ref().and(first_pending);
        self.manifest.exit_code = stopped.as_ref().map(|e| e.exit_class().code());
        // After the reason: should a write fail from here on, the error tells the stop it was
        // to record (see `unrecorded`).
        let results = self.write_results()?;
        let now = crate::time::rfc3339_millis(std::time::SystemTime::now());
        self.manifest.session_mut().ended = Some(now);
        self.timing.total_s = self.started.elapsed().as_secs_f64();
        self.manifest.session_mut().timing = self.timing.clone();
        // The journals are final now: hash them.
        let journals: Vec<PathBuf> = self
            .manifest
            .sessions
            .iter()
            .map(|s| s.journal.clone())
            .filter(|p| p.is_relative())
            .collect();
        if let Some(journal) = self.journal.take() {
            journal.flush();
        }
        for j in journals {
            if self.dir.join(&j).exists() {
                self.manifest.set_file(FileRecord::of(&self.dir, &j)?);
            }
        }
        let report = report::write(&self.dir, &self.manifest, &results)?;
        self.manifest
            .set_file(FileRecord::of(&self.dir, Path::new(report::REPORT_FILE))?);
        self.manifest
            .set_file(FileRecord::of(&self.dir, Path::new(report::HTML_FILE))?);
        self.folder.check(&self.dir)?;
        self.store_manifest(false)?;
        let max = |f: fn(&results::AlgorithmResult) -> Option<f64>| {
            results
                .steps
                .iter()
                .flat_map(|s| s.algorithms.values())
                .filter_map(f)
                .map(f64::abs)
                .fold(None, |a: Option<f64>, x| Some(a.map_or(x, |a| a.max(x))))
        };
        let summary = Summary {
            name: self.plan.name.clone(),
            steps: self.plan.steps.len(),
            done: results.steps.len(),
            measured: self.measured,
            skipped: self.skipped,
            algorithms: self.plan.algorithm_names(),
            max_abs_error_m: max(|a| a.error_m),
            max_abs_truth_error_m: max(|a| a.truth_error_m),
            reason: self.manifest.reason.clone(),
            stopped_at_step: self.manifest.stopped_at_step,
            manifest: self.dir.join(manifest::MANIFEST_FILE),
            results: self.dir.join(RESULTS_FILE),
            report,
        };
        Ok(Finished {
            dir: self.dir.clone(),
            status,
            summary,
            stopped,
        })
    }
}

/// A refusal of the simulated bench's scene control, as the campaign's error.
/// The bench levels a step may set, as a waveform's capture plan holds them.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Levels {
    tx_db: f64,
    rx_db: f64,
    awg_vpp: f64,
    volts_per_div: f64,
}

impl Levels {
    fn of(plan: &crate::measure::CapturePlan) -> Levels {
        Levels {
            tx_db: plan.tx.attenuation_db,
            rx_db: plan.rx.attenuation_db,
            awg_vpp: plan.awg.i_amplitude_vpp,
            volts_per_div: plan.scope.i_volts_per_div,
        }
    }

    /// These levels with what the step sets.
    fn with(self, n: &crate::campaign::Nominal) -> Levels {
        Levels {
            tx_db: n.tx_attenuation_db.unwrap_or(self.tx_db),
            rx_db: n.rx_attenuation_db.unwrap_or(self.rx_db),
            awg_vpp: n.awg_amplitude_vpp.unwrap_or(self.awg_vpp),
            volts_per_div: n.volts_per_div.unwrap_or(self.volts_per_div),
        }
    }

    fn set(self, plan: &mut crate::measure::CapturePlan) {
        plan.tx.attenuation_db = self.tx_db;
        plan.rx.attenuation_db = self.rx_db;
        plan.awg.i_amplitude_vpp = self.awg_vpp;
        plan.awg.q_amplitude_vpp = self.awg_vpp;
        plan.scope.i_volts_per_div = self.volts_per_div;
        plan.scope.q_volts_per_div = self.volts_per_div;
    }
}

fn control(e: SceneControlError) -> CampaignError {
    CampaignError::Control(e.to_string())
}

fn catalog(bench: &Bench) -> Result<Catalog, CampaignError> {
    Ok(bench.file.catalog().map_err(MeasureError::from)?)
}
