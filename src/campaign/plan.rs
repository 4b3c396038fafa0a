//! The resolved plan: every step with its nominal set-points (target ranges, bandwidth, Tx
//! attenuation, SNR), the waveforms and processing options, the noise seed of each step on a
//! simulated bench. Plain data: `--dry-run` prints it, the manifest stores it, resume runs it.
//!
//! [`plan`] is pure; [`BenchInfo::load`] reads the bench file (or describes the built-in lab)
//! without touching an instrument.

use super::axis::{AxisSetting, AxisValue, SweepParameter};
use super::error::CampaignError;
use super::kind::{sorted_ranges, Setting, SweepAt};
use super::nominal::MAX_VELOCITY_MPS;
pub use super::nominal::{Nominal, Range};
use super::spec::{OutputSection, PositionerKind, SpecError, SpecFile, SweepSection};
use crate::catalog::Catalog;
use crate::measure::bench::scene_control::Scene;
use crate::measure::capture::{CaptureRequest, MAX_REPETITIONS};
use crate::measure::processing::family::overrides::{
    WaveformOverrides, MAX_SAMPLES_PER_REPETITION,
};
use crate::measure::CorrectionMode;
use crate::measure::{planning_scope_resource, AwgLink, Bench, BuiltIn, ScopeLink, ScopeModel};
use crate::measure::{Algorithm, ProcessOptions, ProcessingChoices};
use crate::measure::{BenchCalibration, BenchFile, InstrumentEntry};
use crate::waveform::{WaveformKind, WaveformSpec};
use serde::{Deserialize, Serialize};
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

/// Most steps one campaign may hold.
pub(crate) const MAX_STEPS: usize = 10_000;

/// Most retries of one step (`[run] retries`, `--retries`).
pub const MAX_RETRIES: usize = 10;

/// Longest first wait before a retry, seconds (`[run] retry_backoff_s`).
pub(crate) const MAX_RETRY_BACKOFF_S: f64 = 600.0;

/// The resolved campaign.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Plan {
    pub name: String,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub description: Option<String>,
    pub seed: u64,
    pub repetitions: usize,
    pub wait_s: f64,
    /// Times a step is measured again after a transient fault (`[run] retries`).
    #[serde(default)]
    pub retries: usize,
    /// The wait before a step's first retry, seconds, doubled before each next one.
    #[serde(default)]
    pub retry_backoff_s: f64,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub payload: Option<String>,
    pub bench: BenchPlan,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub positioner: Option<PositionerPlan>,
    /// The distinct waveforms, in the order the steps first use them.
    pub waveforms: Vec<WaveformSpec>,
    /// One entry per algorithm (first = the primary, whose capture files sit in the step folder).
    pub processing: Vec<ProcessOptions>,
    /// The processing of steps that set their own window or algorithm: [`Step::processing`]
    /// `i >= 1` is entry `i - 1` (one entry per algorithm, as `processing`).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub processing_variants: Vec<Vec<ProcessOptions>>,
    /// Who is told when the run ends (`[run] notify`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub notify: Option<super::notify::NotifyPlan>,
    /// Who runs it (`[run] operator`; the manifest records the environment's user without it).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub operator: Option<String>,
    /// Which of a step's files stay (`[output]`; a run from before it kept every file).
    #[serde(default = "OutputSection::keep_all")]
    pub output: OutputSection,
    /// The subspace algorithms take each step's number of targets as their model order
    /// (`music_p = "targets"`).
    #[serde(default, skip_serializing_if = "std::ops::Not::not")]
    pub music_p_from_targets: bool,
    pub steps: Vec<Step>,
}

/// The bench a plan runs on.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct BenchPlan {
    /// The bench file (absolute); `None` for the built-in mock lab.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub file: Option<PathBuf>,
    pub simulated: bool,
    /// Built-in mock lab: its scene (each step sets its seed, and its targets and SNR when the
    /// step says so).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub scene: Option<Scene>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub awg_transport: Option<AwgLink>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub scope_transport: Option<ScopeLink>,
    /// Built-in mock lab: the scope it serves (absent: the LeCroy).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub scope_model: Option<ScopeModel>,
    /// The calibrated system delay subtracted from every range, seconds.
    pub system_delay_s: f64,
    pub calibrated: bool,
}

impl BenchPlan {
    /// What every output of a run on this bench must say about it (it is not calibrated).
    pub fn warnings(&self) -> Vec<String> {
        (!self.calibrated)
            .then(|| crate::measure::uncalibrated_warning(self.file.as_deref()))
            .into_iter()
            .collect()
    }
}

/// Who places the targets.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct PositionerPlan {
    pub kind: PositionerKind,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub program: Option<String>,
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub args: Vec<String>,
    /// The folder the program runs in (the spec's).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub workdir: Option<PathBuf>,
    pub timeout_s: f64,
    pub settle_s: f64,
}

/// A step's set-points in words (the kinds' table says how each value reads).
impl Nominal {
    /// One short line: `position 0.970 m`, `bandwidth 2 GHz, targets 1.000 / 1.080 m`.
    pub fn describe(&self) -> String {
        let mut parts = Vec::new();
        if let Some(l) = &self.label {
            parts.push(l.clone());
        }
        if let (Some(p), Some(v)) = (self.parameter, self.value) {
            parts.push(format!("{p} {}", (p.kind().show)(v)));
        }
        for a in &self.axes {
            let unit = Setting::named(&a.name).map_or("", |s| s.unit());
            match (&a.value, unit) {
                (AxisValue::Number(_), u) if !u.is_empty() => {
                    parts.push(format!("{} {} {u}", a.name, a.value))
                }
                _ => parts.push(format!("{} {}", a.name, a.value)),
            }
        }
        if !self.targets.is_empty() {
            let r: Vec<String> = self
                .targets
                .iter()
                .map(|t| format!("{:.3}", t.range_m))
                .collect();
            parts.push(format!("targets {} m", r.join(" / ")));
        }
        parts.join(", ")
    }
}

/// One step of the plan.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Step {
    /// 1-based.
    pub index: usize,
    pub nominal: Nominal,
    /// Index into [`Plan::waveforms`].
    pub waveform: usize,
    /// The simulated scene's noise seed for this step (simulated benches): a step's noise then
    /// depends only on the campaign's seed and the step, so a resumed run equals an
    /// uninterrupted one.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub noise_seed: Option<u64>,
    /// The subspace algorithms' model order at this step (`music_p = "targets"`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub music_p: Option<usize>,
    /// Its processing: 0 the plan's, `i >= 1` [`Plan::processing_variants`]`[i - 1]`.
    #[serde(default, skip_serializing_if = "is_zero")]
    pub processing: usize,
}

fn is_zero(v: &usize) -> bool {
    *v == 0
}

impl Step {
    /// The step's folder name inside the run folder.
    pub(crate) fn dir_name(&self) -> String {
        format!("step-{:03}", self.index)
    }
}

/// The noise seed of step `index` (SplitMix64's finaliser over the campaign seed and the step),
/// 63 bits so TOML (signed 64-bit integers) can hold it.
pub(crate) fn noise_seed(seed: u64, index: usize) -> u64 {
    let mut z = seed ^ (index as u64).wrapping_mul(0x9E37_79B9_7F4A_7C15);
    z = z.wrapping_add(0x9E37_79B9_7F4A_7C15);
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    (z ^ (z >> 31)) >> 1
}

/// What planning needs to know of the bench, read without touching an instrument.
#[derive(Debug, Clone)]
pub struct BenchInfo {
    /// The bench file (absolute path) and its content; `None` for the built-in mock lab.
    pub file: Option<(PathBuf, BenchFile)>,
    /// The built-in lab's scene.
    pub scene: Option<Scene>,
    pub awg_transport: Option<AwgLink>,
    pub scope_transport: Option<ScopeLink>,
    pub scope_model: Option<ScopeModel>,
    pub simulated: bool,
    /// The Tx attenuation radbench can set, dB (`None`: the bench has no `[tx]`).
    pub tx_attenuation_db: Option<(f64, f64)>,
    /// The Rx attenuation radbench can set, dB (`None`: the bench has no `[rx]`).
    pub rx_attenuation_db: Option<(f64, f64)>,
    /// The AWG's amplitude range, volts peak to peak (its catalog entry).
    pub awg_amplitude_vpp: Option<(f64, f64)>,
    /// The scope's vertical scales, V/div (its catalog entry).
    pub volts_per_div: Option<(f64, f64)>,
}

/// The ranges of the bench's settings a step may set (its catalog's).
struct Ranges {
    tx: Option<(f64, f64)>,
    rx: Option<(f64, f64)>,
    awg: Option<(f64, f64)>,
    vdiv: Option<(f64, f64)>,
}

fn ranges_of(catalog: &Catalog, file: &BenchFile) -> Ranges {
    // The attenuation range the model's register allows.
    let att = |entry: &Option<InstrumentEntry>| -> Option<(f64, f64)> {
        let model = catalog.get(&entry.as_ref()?.model).ok()?;
        let step = model.rf.as_ref()?.attenuation_step_db;
        let reg = model.registers.iter().find(|r| r.name == "GAIN_ATT")?;
        Some((
            f64::from(reg.min.unwrap_or(0)) * step,
            f64::from(reg.max.unwrap_or(0)) * step,
        ))
    };
    let awg = catalog
        .get(&file.awg.model)
        .ok()
        .and_then(|m| m.awg.as_ref())
        .map(|a| (a.amplitude_vpp_min, a.amplitude_vpp_max));
    let vdiv = catalog
        .get(&file.scope.model)
        .ok()
        .and_then(|m| m.digitizer.as_ref())
        .map(|d| (d.volts_per_div_min, d.volts_per_div_max));
    Ranges {
        tx: att(&file.tx),
        rx: att(&file.rx),
        awg,
        vdiv,
    }
}

/// The models the built-in mock lab serves besides its scope (as `mock-lab serve` writes its bench
/// file); the scope's is its [`ScopeModel::catalog_key`].
const BUILT_IN_MODELS: [&str; 3] = ["keysight-m8195a", "gotmic-eband-tx", "gotmic-eband-rx"];

impl BenchInfo {
    /// The bench of `--bench`, or of the spec's `[bench]`, or the built-in mock lab.
    pub fn load(
        spec: &SpecFile,
        bench_override: Option<&Path>,
    ) -> Result<BenchInfo, CampaignError> {
        let section = &spec.spec.bench;
        let file = match bench_override {
            Some(p) => Some(p.to_path_buf()),
            None => section.file.as_ref().map(|p| spec.resolve(p)),
        };
        let built_in_only = |field: &str, given: bool| -> Result<(), CampaignError> {
            if given && file.is_some() {
                return Err(spec
                    .error(
                        &format!("bench.{field}"),
                        "applies to the built-in mock lab only; with a bench file, change the \
                         simulated scene through the lab's control channel",
                    )
                    .into());
            }
            Ok(())
        };
        built_in_only("scene", section.scene.is_some())?;
        built_in_only("awg_transport", section.awg_transport.is_some())?;
        built_in_only("scope_transport", section.scope_transport.is_some())?;
        built_in_only("scope_model", section.scope_model.is_some())?;
        match file {
            Some(path) => {
                let bench = BenchFile::load(&path).map_err(crate::measure::MeasureError::from)?;
                let catalog = bench
                    .catalog()
                    .map_err(crate::measure::MeasureError::from)?;
                let path = std::path::absolute(&path).unwrap_or(path);
                let r = ranges_of(&catalog, &bench);
                Ok(BenchInfo {
                    tx_attenuation_db: r.tx,
                    rx_attenuation_db: r.rx,
                    awg_amplitude_vpp: r.awg,
                    volts_per_div: r.vdiv,
                    simulated: bench.simulation.is_some(),
                    file: Some((path, bench)),
                    scene: None,
                    awg_transport: None,
                    scope_transport: None,
                    scope_model: None,
                })
            }
            None => {
                let scene = match &section.scene {
                    Some(p) => {
                        let p = spec.resolve(p);
                        let text = std::fs::read_to_string(&p).map_err(|e| {
                            spec.error("bench.scene", format!("cannot read {}: {e}", p.display()))
                        })?;
                        Scene::from_toml(&text, &p.display().to_string()).map_err(|e| {
                            spec.error("bench.scene", crate::exit::with_key_hint(&e.to_string()))
                        })?
                    }
                    None => Scene::default(),
                };
                let file = built_in_bench_file(&scene, section.scope_model.unwrap_or_default());
                let catalog = Catalog::embedded().map_err(crate::measure::MeasureError::from)?;
                let r = ranges_of(&catalog, &file);
                Ok(BenchInfo {
                    tx_attenuation_db: r.tx,
                    rx_attenuation_db: r.rx,
                    awg_amplitude_vpp: r.awg,
                    volts_per_div: r.vdiv,
                    file: None,
                    scene: Some(scene),
                    awg_transport: Some(section.awg_transport.unwrap_or_default()),
                    scope_transport: Some(section.scope_transport.unwrap_or_default()),
                    scope_model: section.scope_model,
                    simulated: true,
                })
            }
        }
    }

    /// The instrument catalog of this bench (the bench file's, or the built-in one).
    pub fn catalog(&self) -> Result<Catalog, crate::catalog::CatalogError> {
        match &self.file {
            Some((_, f)) => f.catalog(),
            None => Catalog::embedded(),
        }
    }

    /// The bench file planning checks against (the built-in lab's models for the built-in lab).
    pub fn bench_file(&self) -> BenchFile {
        match (&self.file, &self.scene) {
            (Some((_, f)), _) => f.clone(),
            (None, scene) => built_in_bench_file(
                &scene.clone().unwrap_or_default(),
                self.scope_model.unwrap_or_default(),
            ),
        }
    }
}

/// The built-in lab as a bench file, for planning (the resources are placeholders: the lab's
/// ports are known only once it runs).
fn built_in_bench_file(scene: &Scene, scope: ScopeModel) -> BenchFile {
    let entry = |model: &str, resource: &str| InstrumentEntry {
        model: model.to_string(),
        resource: resource.to_string(),
        driver: None,
        volts_per_div: None,
        attenuation_db: None,
        rf_frequency_hz: None,
        trigger_jitter_s: None,
        reference_clock_hz: None,
    };
    BenchFile {
        catalog: None,
        catalog_overrides: None,
        awg: entry(BUILT_IN_MODELS[0], "TCPIP::127.0.0.1::hislip0::INSTR"),
        scope: InstrumentEntry {
            // The simulated scope's jitter is its scene's.
            trigger_jitter_s: Some(scene.trigger_jitter_s),
            ..entry(scope.catalog_key(), planning_scope_resource(scope))
        },
        tx: Some(entry(BUILT_IN_MODELS[1], "ASRL/dev/null::INSTR")),
        rx: Some(entry(BUILT_IN_MODELS[2], "ASRL/dev/null::INSTR")),
        simulation: None,
        calibration: Some(BenchCalibration {
            system_delay_s: scene.system_delay_s,
            reference_range_m: None,
            measured_at: None,
            response: None,
        }),
        reference: None,
        manual: Vec::new(),
        lines: Default::default(),
        path: PathBuf::from("(built-in mock lab)"),
    }
}

impl BenchPlan {
    /// A bench for planning and preparing (no instrument, no lab started).
    pub(crate) fn planning_bench(&self, info_file: Option<&BenchFile>) -> Bench {
        let file = match info_file {
            Some(f) => f.clone(),
            None => built_in_bench_file(
                &self.scene.clone().unwrap_or_default(),
                self.scope_model.unwrap_or_default(),
            ),
        };
        Bench {
            file,
            path: self.file.clone(),
            lab: None,
        }
    }

    /// The built-in lab with `scene`.
    pub(crate) fn built_in(&self, scene: Scene) -> BuiltIn {
        BuiltIn {
            scene,
            awg: self.awg_transport.unwrap_or_default(),
            scope: self.scope_transport.unwrap_or_default(),
            scope_model: self.scope_model.unwrap_or_default(),
        }
    }

    pub fn describe(&self) -> String {
        match &self.file {
            Some(p) => format!(
                "bench file {}{}",
                p.display(),
                if self.simulated { " (simulated)" } else { "" }
            ),
            None => "the built-in mock lab (simulated, in-process on 127.0.0.1)".into(),
        }
    }
}

impl Plan {
    /// The capture request of waveform `w` with the primary processing.
    pub fn request(&self, w: usize) -> CaptureRequest {
        CaptureRequest {
            waveform: self.waveforms[w],
            payload: self.payload.as_ref().map(|p| p.as_bytes().to_vec()),
            seed: self.seed,
            options: self.processing[0].clone(),
            tx_off: false,
            wait_s: self.wait_s,
            background: None,
        }
    }

    /// The receive correction every step applies (the same for every algorithm).
    pub(crate) fn correction(&self) -> Option<&crate::measure::CorrectionUsed> {
        self.processing.first().and_then(|o| o.correction.as_ref())
    }

    /// The algorithms' names, in order.
    pub(crate) fn algorithm_names(&self) -> Vec<&'static str> {
        self.processing.iter().map(|o| o.algorithm.name()).collect()
    }

    /// The processing of variant `v` (0: the plan's own; see [`Step::processing`]).
    pub(crate) fn processing_of(&self, v: usize) -> &[ProcessOptions] {
        match v {
            0 => &self.processing,
            v => &self.processing_variants[v - 1],
        }
    }

    /// The algorithms' names of variant `v`, in order.
    pub(crate) fn algorithm_names_of(&self, v: usize) -> Vec<&'static str> {
        self.processing_of(v)
            .iter()
            .map(|o| o.algorithm.name())
            .collect()
    }

    /// The repetitions of step `k` (0-based).
    pub(crate) fn repetitions_at(&self, k: usize) -> usize {
        self.steps[k]
            .nominal
            .repetitions
            .unwrap_or(self.repetitions)
    }

    /// Whether step `k` (0-based) places targets (its targets differ from the step before, or it
    /// is the first step of a session).
    pub(crate) fn moves_at(&self, k: usize, first_of_session: bool) -> bool {
        let here = &self.steps[k].nominal.targets;
        !here.is_empty()
            && (first_of_session || k == 0 || self.steps[k - 1].nominal.targets != *here)
    }
}

/// Resolves a spec against the bench: every value checked, located in the spec on error. Reads
/// nothing but the response calibration the processing names (checked whole: header and table).
pub fn plan(spec: &SpecFile, bench: &BenchInfo) -> Result<Plan, SpecError> {
    let s = &spec.spec;
    if !(1..=MAX_REPETITIONS).contains(&s.repetitions) {
        return Err(spec.error(
            "repetitions",
            format!("{}: allowed 1..={MAX_REPETITIONS}", s.repetitions),
        ));
    }
    if !(s.wait_s.is_finite() && s.wait_s > 0.0 && s.wait_s <= 3600.0) {
        return Err(spec.error(
            "wait_s",
            format!("{}: allowed 0 < seconds <= 3600", s.wait_s),
        ));
    }
    if s.run.retries > MAX_RETRIES {
        return Err(spec.error(
            "run.retries",
            format!("{}: allowed 0..={MAX_RETRIES}", s.run.retries),
        ));
    }
    let backoff = s.run.retry_backoff_s;
    if !(backoff.is_finite() && (0.0..=MAX_RETRY_BACKOFF_S).contains(&backoff)) {
        return Err(spec.error(
            "run.retry_backoff_s",
            format!("{backoff}: allowed 0 <= seconds <= {MAX_RETRY_BACKOFF_S}"),
        ));
    }
    if let Some(o) = &s.run.operator {
        if o.trim().is_empty() || o.chars().any(char::is_control) || o.chars().count() > 200 {
            return Err(spec.error(
                "run.operator",
                format!("{o:?}: allowed a name of 1 to 200 characters on one line"),
            ));
        }
    }
    let base = base_waveform(spec)?;
    let mut processing = processing(spec, &s.processing, base.kind(), bench)?;
    let correction = correction(spec, bench)?;
    if let Some((mode, cal)) = &correction {
        // Resolved once: every step's pipelines apply (and record) the same calibration.
        for o in &mut processing {
            o.correction = Some(cal.used_as(*mode));
        }
    }
    let from_targets = matches!(
        s.processing.music_p,
        Some(crate::measure::ModelOrderChoice::Named(_))
    ) && processing.iter().any(|o| o.algorithm.is_subspace());
    let positioner = positioner(spec, bench)?;
    let mut steps = raw_steps(spec, &base, bench)?;
    let min = processing[0].min_range_m;
    let max = processing[0].max_range_m;
    let mut waveforms: Vec<WaveformSpec> = Vec::new();
    let mut variants: Vec<Vec<ProcessOptions>> = Vec::new();
    for (k, step) in steps.iter_mut().enumerate() {
        check_nominal(spec, bench, k, &step.nominal, (min, max))?;
        let wf = step_waveform(spec, &base, k, &step.nominal)?;
        step.waveform = match waveforms.iter().position(|w| *w == wf) {
            Some(i) => i,
            None => {
                waveforms.push(wf);
                waveforms.len() - 1
            }
        };
        let n = &step.nominal;
        if n.window.is_some() || n.algorithm.is_some() {
            let mut choices = s.processing.clone();
            if let Some(w) = n.window {
                choices.window = Some(w);
            }
            if let Some(a) = n.algorithm {
                choices.algorithm = Some(a);
                choices.algorithms.clear();
            }
            let mut own = processing_at(spec, k, &choices, wf.kind(), bench)?;
            if let Some((mode, cal)) = &correction {
                for o in &mut own {
                    o.correction = Some(cal.used_as(*mode));
                }
            }
            step.processing = if own == processing {
                0
            } else {
                match variants.iter().position(|v| *v == own) {
                    Some(i) => i + 1,
                    None => {
                        variants.push(own);
                        variants.len()
                    }
                }
            };
        }
        if bench.simulated {
            step.noise_seed = Some(noise_seed(s.seed, step.index));
        }
        if from_targets && !step.nominal.targets.is_empty() {
            let p = step.nominal.targets.len();
            let m = processing[0].music_m;
            if p >= m {
                return Err(spec.error(
                    "processing.music_p",
                    format!(
                        "\"targets\" gives p = {p} at step {}, which must stay below music_m = {m}",
                        step.index
                    ),
                ));
            }
            step.music_p = Some(p);
        }
    }
    // MUSIC's M against each planned waveform, named in the spec (not as the CLI's --m).
    for wf in &waveforms {
        if let Some(subcarriers) = crate::measure::processing::family::of(wf).subcarriers() {
            let every = processing.iter().chain(variants.iter().flatten());
            for o in every.filter(|o| o.algorithm.is_subspace()) {
                if o.music_m < 2 || o.music_m > subcarriers {
                    return Err(spec.error(
                        "processing.music_m",
                        format!(
                            "music_m = {}: allowed 2..={subcarriers} (at most the waveform's \
                             {subcarriers} subcarriers)",
                            o.music_m
                        ),
                    ));
                }
            }
        }
    }
    let places = steps.iter().any(|st| !st.nominal.targets.is_empty());
    if places && positioner.is_none() {
        return Err(spec.error(
            "positioner",
            "the steps place targets but no positioner is named: add [positioner] with kind = \
             \"prompt\" (the operator places them) or \"command\" (a program does); \"mock-lab\" \
             needs a simulated bench",
        ));
    }
    Ok(Plan {
        name: spec.name(),
        description: s.description.clone(),
        seed: s.seed,
        repetitions: s.repetitions,
        wait_s: s.wait_s,
        retries: s.run.retries,
        retry_backoff_s: backoff,
        payload: s.waveform.payload.clone(),
        bench: BenchPlan {
            file: bench.file.as_ref().map(|(p, _)| p.clone()),
            simulated: bench.simulated,
            scene: bench.scene.clone(),
            awg_transport: bench.awg_transport,
            scope_transport: bench.scope_transport,
            scope_model: bench.scope_model,
            system_delay_s: bench.bench_file().system_delay_s(),
            calibrated: bench.bench_file().calibration.is_some(),
        },
        positioner,
        waveforms,
        processing,
        processing_variants: variants,
        output: s.output,
        notify: notify_plan(spec)?,
        operator: s.run.operator.clone(),
        music_p_from_targets: from_targets,
        steps,
    })
}

/// `[run] notify`, checked.
fn notify_plan(spec: &SpecFile) -> Result<Option<super::notify::NotifyPlan>, SpecError> {
    let r = &spec.spec.run;
    let t = r.notify_timeout_s;
    if !(t.is_finite() && t > 0.0 && t <= 3600.0) {
        return Err(spec.error(
            "run.notify_timeout_s",
            format!("{t}: allowed 0 < seconds <= 3600"),
        ));
    }
    match r.notify.first() {
        // No program, but its bound, for a `--notify` on the command line.
        None if t != super::notify::DEFAULT_NOTIFY_TIMEOUT_S => {
            Ok(Some(super::notify::NotifyPlan {
                command: Vec::new(),
                workdir: None,
                timeout_s: t,
            }))
        }
        None => Ok(None),
        Some(p) if p.trim().is_empty() => Err(spec.error(
            "run.notify",
            "the first entry is the program: a path relative to the spec's folder or a name on \
             PATH",
        )),
        Some(_) => Ok(Some(super::notify::NotifyPlan {
            command: r.notify.clone(),
            workdir: Some(std::path::absolute(spec.folder()).unwrap_or(spec.folder())),
            timeout_s: t,
        })),
    }
}

/// Step `k`'s targets stand inside the processing window, and what it sets the bench can set.
fn check_nominal(
    spec: &SpecFile,
    bench: &BenchInfo,
    k: usize,
    nominal: &Nominal,
    (min, max): (f64, f64),
) -> Result<(), SpecError> {
    for (i, t) in nominal.targets.iter().enumerate() {
        let r = t.range_m;
        if !(r.is_finite() && r >= min && r <= max) {
            return Err(spec.error(
                &step_field(spec, k, "targets", Some(i)),
                format!(
                    "{r} m: a target must stand inside the processing window {min} .. {max} m \
                     (processing.min_range_m / max_range_m)"
                ),
            ));
        }
    }
    if nominal.velocity_mps.is_some() && !bench.simulated {
        return Err(spec.error(
            &step_field(spec, k, "velocity_mps", None),
            "the targets' velocity is set only on a simulated bench (the built-in mock lab, or a \
             bench file with [simulation])",
        ));
    }
    if nominal.snr_db.is_some() && !bench.simulated {
        return Err(spec.error(
            &step_field(spec, k, "snr_db", None),
            "the SNR is set only on a simulated bench (the built-in mock lab, or a bench file \
             with [simulation]); on a real bench sweep tx-attenuation instead",
        ));
    }
    if let Some(att) = nominal.tx_attenuation_db {
        let Some((lo, hi)) = bench.tx_attenuation_db else {
            return Err(spec.error(
                &step_field(spec, k, "tx_attenuation_db", None),
                "the bench has no [tx] radbench controls: add the Tx to the bench file",
            ));
        };
        if !(att.is_finite() && att >= lo && att <= hi) {
            return Err(spec.error(
                &step_field(spec, k, "tx_attenuation_db", None),
                format!("{att} dB: the Tx sets {lo} .. {hi} dB"),
            ));
        }
    }
    let levels = [
        (
            nominal.rx_attenuation_db,
            bench.rx_attenuation_db,
            "rx_attenuation_db",
            "dB",
            "the bench has no [rx] radbench controls: add the Rx to the bench file",
        ),
        (
            nominal.awg_amplitude_vpp,
            bench.awg_amplitude_vpp,
            "awg_amplitude_vpp",
            "Vpp",
            "the bench's AWG model has no amplitude range in its catalog",
        ),
        (
            nominal.volts_per_div,
            bench.volts_per_div,
            "volts_per_div",
            "V/div",
            "the bench's scope model has no vertical scales in its catalog",
        ),
    ];
    for (value, range, field, unit, missing) in levels {
        let Some(v) = value else { continue };
        let Some((lo, hi)) = range else {
            return Err(spec.error(&step_field(spec, k, field, None), missing));
        };
        if !(v.is_finite() && v >= lo && v <= hi) {
            return Err(spec.error(
                &step_field(spec, k, field, None),
                format!("{v} {unit}: allowed {lo} ..= {hi} {unit} (the bench's catalog)"),
            ));
        }
    }
    Ok(())
}

/// The field of step `k`: `steps[k].name` for an explicit list, the sweep's field otherwise.
fn step_field(spec: &SpecFile, k: usize, name: &str, item: Option<usize>) -> String {
    let item = item.map(|i| format!("[{i}]")).unwrap_or_default();
    let Some(sweeps) = &spec.spec.sweep else {
        // A [[steps]] entry may give the field by its setting's name.
        let by_setting = super::kind::SETTINGS
            .iter()
            .find(|s| s.field == name && spec.spec.steps[k].settings.contains_key(s.name));
        return match by_setting {
            Some(s) => format!("steps[{k}].{}", s.name),
            None => format!("steps[{k}].{name}{item}"),
        };
    };
    let tables = sweeps.tables();
    // The axis that sets the field, else the table naming the targets, else the first.
    let sets = tables
        .iter()
        .find(|(_, sw)| Setting::named(&sw.parameter).is_some_and(|s| s.field == name));
    match (name, sets) {
        (_, Some((prefix, _))) => format!("{prefix}.values"),
        ("targets", None) => {
            let holder = tables.iter().find(|(_, sw)| sw.targets.is_some());
            let prefix = holder
                .or(tables.first())
                .map_or("sweep", |(p, _)| p.as_str());
            format!("{prefix}.targets{item}")
        }
        _ => tables
            .first()
            .map_or("sweep".into(), |(p, _)| format!("{p}.values")),
    }
}

/// Step `k`'s waveform: the spec's with what the step sets (bandwidth, pulse, bits,
/// subcarriers), checked as the spec's own.
fn step_waveform(
    spec: &SpecFile,
    base: &WaveformSpec,
    k: usize,
    n: &Nominal,
) -> Result<WaveformSpec, SpecError> {
    let shaped = n.pulse_s.is_some() || n.bits_per_pulse.is_some() || n.subcarriers.is_some();
    if !shaped {
        return base
            .with_bandwidth(n.bandwidth_hz)
            .map_err(|e| spec.error(&step_field(spec, k, "bandwidth_hz", None), e.to_string()));
    }
    let w = &spec.spec.waveform;
    let overrides = WaveformOverrides {
        bandwidth_hz: Some(n.bandwidth_hz),
        sample_rate_hz: w.sample_rate_hz,
        pulse_s: n.pulse_s.or(w.pulse_s),
        bits_per_pulse: n.bits_per_pulse.or(w.bits_per_pulse),
        band: w.band,
        subcarriers: n.subcarriers.or(w.subcarriers),
        oversampling: w.oversampling,
        cp_fraction: w.cp_fraction,
        symbols: w.symbols,
        preamble_symbols: w.preamble_symbols,
    };
    // The field of the step's own setting that the waveform refuses, else the bandwidth's.
    let field = |f: &str| -> String {
        let own = match f {
            "pulse_s" if n.pulse_s.is_some() => Some("pulse_s"),
            "bits_per_pulse" if n.bits_per_pulse.is_some() => Some("bits_per_pulse"),
            "subcarriers" if n.subcarriers.is_some() => Some("subcarriers"),
            _ => None,
        };
        step_field(spec, k, own.unwrap_or("bandwidth_hz"), None)
    };
    let out = overrides
        .apply(w.kind)
        .map_err(|e| spec.error(&field(e.field()), e.to_string()))?;
    let guess = if n.subcarriers.is_some() {
        "subcarriers"
    } else if n.bits_per_pulse.is_some() {
        "bits_per_pulse"
    } else {
        "pulse_s"
    };
    match out.samples_per_repetition() {
        Ok(s) if s as f64 > MAX_SAMPLES_PER_REPETITION => {
            return Err(spec.error(
                &field(guess),
                format!(
                    "one repetition of {s} samples; allowed at most \
                     {MAX_SAMPLES_PER_REPETITION:.0e}"
                ),
            ))
        }
        Ok(_) => {}
        Err(e) => return Err(spec.error(&field(guess), e.to_string())),
    }
    crate::measure::processing::family::of(&out)
        .check()
        .map_err(|e| spec.error(&field(guess), e.to_string()))?;
    Ok(out)
}

/// The spec's waveform: the thesis' defaults with the parameters given.
fn base_waveform(spec: &SpecFile) -> Result<WaveformSpec, SpecError> {
    let w = &spec.spec.waveform;
    let kind = w.kind;
    let overrides = WaveformOverrides {
        bandwidth_hz: w.bandwidth_hz,
        sample_rate_hz: w.sample_rate_hz,
        pulse_s: w.pulse_s,
        bits_per_pulse: w.bits_per_pulse,
        band: w.band,
        subcarriers: w.subcarriers,
        oversampling: w.oversampling,
        cp_fraction: w.cp_fraction,
        symbols: w.symbols,
        preamble_symbols: w.preamble_symbols,
    };
    let spec_out = overrides
        .apply(kind)
        .map_err(|e| spec.error(&format!("waveform.{}", e.field()), e.to_string()))?;
    // The generators check every parameter (named, with what is allowed); do it before anything
    // else so the message points at the waveform.
    match spec_out.samples_per_repetition() {
        Ok(n) if n as f64 > MAX_SAMPLES_PER_REPETITION => {
            return Err(spec.error(
                "waveform",
                format!(
                    "one repetition of {n} samples; allowed at most \
                     {MAX_SAMPLES_PER_REPETITION:.0e}"
                ),
            ))
        }
        Ok(_) => {}
        Err(e) => return Err(spec.error("waveform", e.to_string())),
    }
    if let Err(e) = crate::measure::processing::family::of(&spec_out).check() {
        return Err(spec.error("waveform", e.to_string()));
    }
    Ok(spec_out)
}

/// One set of processing options per algorithm of step `k`, which sets its own window or
/// algorithm (errors name the step's field).
fn processing_at(
    spec: &SpecFile,
    k: usize,
    choices: &ProcessingChoices,
    kind: WaveformKind,
    bench: &BenchInfo,
) -> Result<Vec<ProcessOptions>, SpecError> {
    processing(spec, choices, kind, bench).map_err(|e| match e {
        SpecError::Field { message, .. } => {
            spec.error(&step_field(spec, k, "algorithm", None), message)
        }
        other => other,
    })
}

/// One set of processing options per algorithm.
fn processing(
    spec: &SpecFile,
    p: &ProcessingChoices,
    kind: WaveformKind,
    bench: &BenchInfo,
) -> Result<Vec<ProcessOptions>, SpecError> {
    let algorithms = match (p.algorithm, p.algorithms.is_empty()) {
        (Some(_), false) => {
            return Err(spec.error(
                "processing.algorithm",
                "given with processing.algorithms: list every algorithm in `algorithms`",
            ))
        }
        (Some(a), true) => vec![a],
        (None, true) => vec![Algorithm::default_for(kind)],
        (None, false) => p.algorithms.clone(),
    };
    let mut out: Vec<ProcessOptions> = Vec::new();
    for (i, &a) in algorithms.iter().enumerate() {
        if !a.supports(kind) {
            return Err(spec.error(
                &format!("processing.algorithms[{i}]"),
                format!(
                    "{} needs an OFDM waveform; MSK-LFM is processed by correlation",
                    a.name()
                ),
            ));
        }
        if algorithms[..i].contains(&a) {
            return Err(spec.error(
                &format!("processing.algorithms[{i}]"),
                format!("{} is listed twice", a.name()),
            ));
        }
        // The section's choices over the defaults, with this algorithm (a step's "targets"
        // model order is counted per step).
        let mut o = p.apply(ProcessOptions::default());
        o.algorithm = a;
        bench.bench_file().processing_of_this_bench(&mut o);
        out.push(o);
    }
    Ok(out)
}

/// The response calibration the processing corrects with: `processing.correction` and
/// `processing.calibration` (relative to the spec), else the one the bench file names; as
/// `radbench capture` resolves `--correction` and `--calibration`.
fn correction(
    spec: &SpecFile,
    bench: &BenchInfo,
) -> Result<Option<(CorrectionMode, std::sync::Arc<crate::measure::Calibration>)>, SpecError> {
    let p = &spec.spec.processing;
    let mode = p.correction.unwrap_or(CorrectionMode::Rx);
    let given = p.calibration.as_ref().map(|c| spec.resolve(c));
    let named = bench
        .file
        .as_ref()
        .and_then(|(path, f)| f.response_path(path));
    let (field, path) = match (p.correction, given, named) {
        (Some(CorrectionMode::None), Some(_), _) => {
            return Err(spec.error(
                "processing.calibration",
                "given with correction = \"none\": remove one of them (correction = \"rx\" \
                 corrects with it)",
            ))
        }
        (Some(CorrectionMode::None), None, _) => return Ok(None),
        (_, Some(path), _) => ("processing.calibration", path),
        (_, None, Some(path)) => ("processing.correction", path),
        (Some(m), None, None) => {
            return Err(spec.error(
                "processing.correction",
                format!(
                    "\"{}\" needs a response calibration: give processing.calibration = \"FILE\" \
                 (relative to the spec), or name one in the bench file's [calibration] response \
                 (`radbench calibrate response` does); allowed without one: \"none\"",
                    m.name()
                ),
            ))
        }
        (None, None, None) => return Ok(None),
    };
    crate::measure::Calibration::load(&path)
        .map(|c| Some((mode, std::sync::Arc::new(c))))
        .map_err(|e| {
            let from = if field == "processing.correction" {
                " (named by the bench file's [calibration] response; correction = \"none\" \
                 runs without it)"
            } else {
                ""
            };
            spec.error(field, format!("{e}{from}"))
        })
}

/// The positioner, with defaults; `None` when nothing places targets.
fn positioner(spec: &SpecFile, bench: &BenchInfo) -> Result<Option<PositionerPlan>, SpecError> {
    let section = spec.spec.positioner.as_ref();
    let kind = match section.map(|p| p.kind) {
        Some(k) => k,
        None if bench.simulated => PositionerKind::MockLab,
        None => return Ok(None),
    };
    if kind == PositionerKind::MockLab && !bench.simulated {
        return Err(spec.error(
            "positioner.kind",
            "mock-lab moves simulated targets: the bench is real; use \"prompt\" or \"command\"",
        ));
    }
    let timeout_s = section.and_then(|p| p.timeout_s).unwrap_or(60.0);
    if !(timeout_s.is_finite() && timeout_s > 0.0 && timeout_s <= 3600.0) {
        return Err(spec.error(
            "positioner.timeout_s",
            format!("{timeout_s}: allowed 0 < seconds <= 3600"),
        ));
    }
    let settle_s = section.and_then(|p| p.settle_s).unwrap_or(0.0);
    if !(settle_s.is_finite() && (0.0..=600.0).contains(&settle_s)) {
        return Err(spec.error(
            "positioner.settle_s",
            format!("{settle_s}: allowed 0 ..= 600 seconds"),
        ));
    }
    let program = section.and_then(|p| p.program.clone());
    let args = section.map(|p| p.args.clone()).unwrap_or_default();
    match kind {
        PositionerKind::Command if program.is_none() => {
            return Err(spec.error(
                "positioner.program",
                "kind = \"command\" needs the program to run, e.g. program = \"./stage.sh\"",
            ))
        }
        PositionerKind::Command => {}
        _ => {
            if program.is_some() || !args.is_empty() || section.and_then(|p| p.timeout_s).is_some()
            {
                return Err(spec.error(
                    "positioner.program",
                    format!(
                        "program, args and timeout_s apply to kind = \"command\" only; this is \
                         \"{}\"",
                        kind.name()
                    ),
                ));
            }
        }
    }
    Ok(Some(PositionerPlan {
        kind,
        program,
        args,
        workdir: (kind == PositionerKind::Command).then(|| {
            let folder = spec.folder();
            std::path::absolute(&folder).unwrap_or(folder)
        }),
        timeout_s,
        settle_s,
    }))
}

/// The values of the sweep table at `prefix`.
fn sweep_values(
    spec: &SpecFile,
    prefix: &str,
    sw: &SweepSection,
) -> Result<Vec<AxisValue>, SpecError> {
    let f = |name: &str| format!("{prefix}.{name}");
    let values = match (&sw.values, sw.start, sw.step, sw.count) {
        (Some(v), None, None, None) => v.clone(),
        (None, Some(start), Some(step), Some(count)) => {
            if !(1..=MAX_STEPS).contains(&count) {
                return Err(spec.error(&f("count"), format!("{count}: allowed 1..={MAX_STEPS}")));
            }
            for (field, v) in [(f("start"), start), (f("step"), step)] {
                if !v.is_finite() {
                    return Err(spec.error(
                        &field,
                        format!("{v:?}: a finite number in the parameter's unit"),
                    ));
                }
            }
            (0..count)
                .map(|k| AxisValue::Number(start + step * k as f64))
                .collect()
        }
        (None, Some(start), None, None) => vec![AxisValue::Number(start)],
        _ => {
            return Err(spec.error(
                prefix,
                "give either `values = [...]` or `start`, `step` and `count`",
            ))
        }
    };
    if values.is_empty() || values.len() > MAX_STEPS {
        return Err(spec.error(
            &f("values"),
            format!("{} values: allowed 1..={MAX_STEPS}", values.len()),
        ));
    }
    if let Some(i) = values
        .iter()
        .position(|v| v.number().is_some_and(|x| !x.is_finite()))
    {
        return Err(spec.error(
            &format!("{prefix}.values[{i}]"),
            "a finite number in the parameter's unit",
        ));
    }
    Ok(values)
}

/// The steps before waveforms and seeds are filled in.
fn raw_steps(
    spec: &SpecFile,
    base: &WaveformSpec,
    bench: &BenchInfo,
) -> Result<Vec<Step>, SpecError> {
    let bandwidth = base.bandwidth_hz();
    match (&spec.spec.sweep, spec.spec.steps.is_empty()) {
        (Some(_), false) => Err(spec.error("steps", "give either [sweep] or [[steps]], not both")),
        (None, true) => Err(spec.error(
            "steps",
            "the campaign has no steps: add [sweep] or one [[steps]] table per step",
        )),
        (Some(sw), true) => sweep_steps(spec, &sw.tables(), bandwidth, bench),
        (None, false) => listed_steps(spec, bandwidth),
    }
}

/// Step `index` (1-based) at `nominal`, with the first waveform and no overrides yet.
fn nominal_step(index: usize, nominal: Nominal) -> Step {
    Step {
        index,
        nominal,
        waveform: 0,
        noise_seed: None,
        music_p: None,
        processing: 0,
    }
}

/// One axis of a sweep: its table, its setting and its values.
struct Axis<'a> {
    prefix: &'a str,
    sweep: &'a SweepSection,
    setting: &'static Setting,
    values: Vec<AxisValue>,
}

/// The steps of the sweep tables: every combination of their values, the last table varying
/// fastest. One table of a kind sweeps as that kind always has (its `parameter` and `value`
/// in every output); other sweeps name each step's values in `axes`.
fn sweep_steps(
    spec: &SpecFile,
    tables: &[(String, &SweepSection)],
    bandwidth: f64,
    bench: &BenchInfo,
) -> Result<Vec<Step>, SpecError> {
    let mut axes: Vec<Axis<'_>> = Vec::new();
    for (prefix, sw) in tables {
        let setting = Setting::named(&sw.parameter).ok_or_else(|| {
            spec.error(
                &format!("{prefix}.parameter"),
                "not a setting (checked when parsed)",
            )
        })?;
        let kind = setting.kind();
        if sw.target.is_some() && kind != Some(SweepParameter::Position) {
            return Err(spec.error(
                &format!("{prefix}.target"),
                "applies to parameter = \"position\" only",
            ));
        }
        if kind.is_some_and(|p| p.kind().simulated_only) && !bench.simulated {
            return Err(spec.error(
                &format!("{prefix}.parameter"),
                format!(
                    "{} is set only on a simulated bench (the built-in mock lab, or a bench file \
                     with [simulation]); on a real bench sweep tx-attenuation instead",
                    setting.name
                ),
            ));
        }
        if let Some((other, _)) = axes
            .iter()
            .map(|a| (a.prefix, a))
            .find(|(_, a)| a.setting.field == setting.field)
        {
            return Err(spec.error(
                &format!("{prefix}.parameter"),
                format!("{} sets what {other} already sweeps", setting.name),
            ));
        }
        axes.push(Axis {
            prefix,
            sweep: sw,
            setting,
            values: sweep_values(spec, prefix, sw)?,
        });
    }
    let total = axes
        .iter()
        .try_fold(1usize, |n, a| n.checked_mul(a.values.len()))
        .filter(|n| *n <= MAX_STEPS)
        .ok_or_else(|| {
            spec.error(
                "sweep",
                format!("more than {MAX_STEPS} steps in all (the product of the tables' values)"),
            )
        })?;
    let legacy = match axes.as_slice() {
        [one] => one.setting.kind(),
        _ => None,
    };
    let targets = axes.iter().find_map(|a| a.sweep.targets.clone());
    let mut out = Vec::with_capacity(total);
    for index in 0..total {
        let mut n = Nominal {
            targets: targets.clone().map(sorted_ranges).unwrap_or_default(),
            bandwidth_hz: bandwidth,
            ..Nominal::default()
        };
        // The value index of each axis: the last varies fastest.
        let mut rest = index;
        let mut at_axis = vec![0; axes.len()];
        for (i, a) in axes.iter().enumerate().rev() {
            at_axis[i] = rest % a.values.len();
            rest /= a.values.len();
        }
        for (a, &k) in axes.iter().zip(&at_axis) {
            let v = &a.values[k];
            let at = SweepAt {
                spec,
                targets: a.sweep.targets.as_deref(),
                target: a.sweep.target,
                setting: a.setting,
                value_field: format!("{}.values[{k}]", a.prefix),
                prefix: a.prefix.to_string(),
            };
            (a.setting.apply)(&mut n, v, &at)?;
            match legacy {
                Some(p) => {
                    n.parameter = Some(p);
                    n.value = v.number();
                }
                None => n.axes.push(AxisSetting {
                    name: a.setting.name.to_string(),
                    value: v.clone(),
                }),
            }
        }
        out.push(nominal_step(index + 1, n));
    }
    Ok(out)
}

/// The steps of a list of `[[steps]]`: each keeps what the one before set unless it sets it again.
fn listed_steps(spec: &SpecFile, bandwidth: f64) -> Result<Vec<Step>, SpecError> {
    let s = &spec.spec;
    let mut out = Vec::new();
    // What the steps carry from one to the next.
    let mut n = Nominal {
        bandwidth_hz: bandwidth,
        ..Nominal::default()
    };
    for (k, st) in s.steps.iter().enumerate() {
        if let Some(t) = &st.targets {
            n.targets = sorted_ranges(t.clone());
        }
        if let Some(b) = st.bandwidth_hz {
            n.bandwidth_hz = b;
        }
        if st.tx_attenuation_db.is_some() {
            n.tx_attenuation_db = st.tx_attenuation_db;
        }
        if st.snr_db.is_some() {
            n.snr_db = st.snr_db;
        }
        if st.velocity_mps.is_some() {
            n.velocity_mps = st.velocity_mps;
        }
        for (name, v) in &st.settings {
            let setting = Setting::named(name).ok_or_else(|| {
                spec.error(
                    &format!("steps[{k}].{name}"),
                    "not a setting (checked when parsed)",
                )
            })?;
            let at = SweepAt {
                spec,
                targets: None,
                target: None,
                setting,
                value_field: format!("steps[{k}].{name}"),
                prefix: format!("steps[{k}]"),
            };
            (setting.apply)(&mut n, v, &at)?;
        }
        if let Some(v) = n.velocity_mps {
            if !(v.is_finite() && v.abs() <= MAX_VELOCITY_MPS) {
                return Err(spec.error(
                    &step_field(spec, k, "velocity_mps", None),
                    format!("{v}: allowed -{MAX_VELOCITY_MPS} ..= {MAX_VELOCITY_MPS} m/s"),
                ));
            }
        }
        if let Some(v) = n.snr_db {
            if !(-60.0..=200.0).contains(&v) {
                return Err(spec.error(
                    &step_field(spec, k, "snr_db", None),
                    format!("{v}: allowed -60 ..= 200 dB"),
                ));
            }
        }
        let mut here = n.clone();
        here.label = st.label.clone();
        out.push(nominal_step(k + 1, here));
    }
    Ok(out)
}

/// What the plan needs to know of a prepared waveform to describe a step.
#[derive(Debug, Clone, Copy)]
pub struct WaveformCost {
    /// Samples of one repetition at the waveform rate (the AWG segment).
    pub samples: usize,
    /// Points per channel of one capture at the scope's rate.
    pub points: usize,
    pub capture_rate_hz: f64,
}

/// Rough durations on the built-in mock lab and over a LAN, seconds (measured: docs/campaign.md).
const CONNECT_S: f64 = 0.03;
const PER_CAPTURE_S: f64 = 0.04;
const CAPTURE_BYTES_PER_S: f64 = 4e8;
const SYNTH_POINTS_PER_S: f64 = 1.2e7;
const UPLOAD_BYTES_PER_S: f64 = 4e8;
const FILES_PER_STEP_S: f64 = 0.12;
const PROCESS_POINTS_PER_S: f64 = 3e7;

impl Plan {
    /// The estimated duration of step `k` (0-based) without the operator's time, seconds.
    pub fn estimate_step_s(&self, k: usize, costs: &[WaveformCost], uploads: bool) -> f64 {
        let step = &self.steps[k];
        let c = costs[step.waveform];
        let reps = self.repetitions_at(k) as f64;
        let mut t = FILES_PER_STEP_S;
        if k == 0 {
            t += CONNECT_S;
        }
        if uploads {
            t += 2.0 * c.samples as f64 / UPLOAD_BYTES_PER_S;
        }
        let points = c.points as f64;
        let per_rep = PER_CAPTURE_S
            + 4.0 * points / CAPTURE_BYTES_PER_S
            + if self.bench.simulated {
                points / SYNTH_POINTS_PER_S
            } else {
                0.0
            };
        t += reps * per_rep;
        t += self.processing_of(step.processing).len() as f64
            * (reps + 1.0).min(reps * 2.0)
            * points
            / PROCESS_POINTS_PER_S;
        if let Some(p) = &self.positioner {
            if self.moves_at(k, k == 0) {
                t += p.settle_s;
            }
        }
        t
    }

    /// Whether step `k` uploads a waveform (the first step, and a waveform that differs from the
    /// step before's; also whenever the AWG lost it, which the plan cannot know).
    pub fn uploads_at(&self, k: usize) -> bool {
        k == 0 || self.steps[k - 1].waveform != self.steps[k].waveform
    }

    /// The dry-run text: every step, what will be sent, and the estimated duration.
    pub fn describe(&self, costs: &[WaveformCost]) -> String {
        let mut out = String::new();
        let _ = writeln!(out, "campaign {}: {} steps", self.name, self.steps.len());
        if let Some(d) = &self.description {
            let _ = writeln!(out, "  {d}");
        }
        let _ = writeln!(out, "bench: {}", self.bench.describe());
        let _ = writeln!(
            out,
            "calibration: system delay {:.3} ns{}",
            self.bench.system_delay_s * 1e9,
            if self.bench.calibrated {
                ""
            } else {
                " (none: ranges include the fixed delay)"
            }
        );
        for (w, spec) in self.waveforms.iter().enumerate() {
            let c = costs[w];
            let _ = writeln!(
                out,
                "waveform {}: {} {} GHz, {} samples per repetition at {} GSa/s; capture {} points \
                 per channel at {} GSa/s",
                w + 1,
                spec.name(),
                spec.bandwidth_hz() / 1e9,
                c.samples,
                spec.sample_rate_hz() / 1e9,
                c.points,
                c.capture_rate_hz / 1e9
            );
        }
        let _ = writeln!(
            out,
            "correction: {}",
            match self.correction() {
                Some(c) => format!(
                    "{} with the response calibration {} (measured {}, SHA-256 {})",
                    c.mode, c.calibration, c.measured_at, c.sha256
                ),
                None => "none".into(),
            }
        );
        let _ = writeln!(
            out,
            "processing: {} (each applied to the same captures); {} repetition(s) per step; seed {}",
            self.algorithm_names().join(", "),
            self.repetitions,
            self.seed
        );
        if let Some(p) = &self.positioner {
            let _ = writeln!(out, "positioner: {}", describe_positioner(p));
        }
        let mut total = 0.0;
        let mut bytes = 0;
        let mut operator = false;
        for k in 0..self.steps.len() {
            let step = &self.steps[k];
            let n = &step.nominal;
            let _ = writeln!(
                out,
                "step {}/{}: {}",
                step.index,
                self.steps.len(),
                n.describe()
            );
            let mut sends = Vec::new();
            if let Some(p) = &self.positioner {
                if self.moves_at(k, k == 0) {
                    let r: Vec<String> = n.ranges().iter().map(|r| format!("{r:.4}")).collect();
                    sends.push(match p.kind {
                        PositionerKind::MockLab => {
                            format!("mock lab: targets at {} m", r.join(", "))
                        }
                        PositionerKind::Prompt => {
                            operator = true;
                            format!(
                                "prompt: the operator places the targets at {} m (RF off)",
                                r.join(", ")
                            )
                        }
                        PositionerKind::Command => format!(
                            "command: {} (at most {} s)",
                            command_line(p, &n.ranges(), step.index, self.steps.len()),
                            p.timeout_s
                        ),
                    });
                }
            }
            if let Some(seed) = step.noise_seed {
                let snr = n
                    .snr_db
                    .map(|s| format!(", SNR {s} dB"))
                    .unwrap_or_default();
                let velocity = n
                    .velocity_mps
                    .map(|v| format!(", targets moving at {v} m/s"))
                    .unwrap_or_default();
                sends.push(format!("scene: noise seed {seed:#018x}{snr}{velocity}"));
            }
            let c = costs[step.waveform];
            if self.uploads_at(k) {
                sends.push(format!(
                    "AWG: configure and upload waveform {} ({} samples per channel)",
                    step.waveform + 1,
                    c.samples
                ));
            }
            if let Some(a) = n.tx_attenuation_db {
                sends.push(format!("Tx: attenuation {a} dB"));
            }
            if let Some(a) = n.rx_attenuation_db {
                sends.push(format!("Rx: attenuation {a} dB"));
            }
            if let Some(a) = n.awg_amplitude_vpp {
                sends.push(format!("AWG: amplitude {a} Vpp"));
            }
            if let Some(v) = n.volts_per_div {
                sends.push(format!("scope: {v} V/div"));
            }
            if step.processing != 0 {
                let o = &self.processing_of(step.processing)[0];
                sends.push(format!(
                    "processing: {}, window {}",
                    self.algorithm_names_of(step.processing).join(", "),
                    o.window.name()
                ));
            }
            if let Some(p) = step.music_p {
                sends.push(format!("processing: subspace model order p = {p}"));
            }
            sends.push(format!(
                "RF on, {} marker-triggered capture(s) of {} points per channel, RF off",
                self.repetitions_at(k),
                c.points
            ));
            let t = self.estimate_step_s(k, costs, self.uploads_at(k));
            let b = self.estimate_step_bytes(k, costs);
            total += t;
            bytes += b;
            for s in sends {
                let _ = writeln!(out, "    {s}");
            }
            let _ = writeln!(out, "    about {t:.2} s, {} on disk", megabytes(b));
        }
        let _ = writeln!(
            out,
            "estimated duration (connecting, uploads, captures, processing and files): about \
             {total:.1} s{}",
            if operator {
                ", plus the operator's time at each prompt"
            } else {
                ""
            }
        );
        let o = &self.output;
        let _ = writeln!(
            out,
            "estimated disk: about {} ([output] keep_trc = {}, keep_bitmaps = {}, \
             keep_link_plots = {})",
            megabytes(bytes),
            o.keep_trc,
            o.keep_bitmaps,
            o.keep_link_plots
        );
        out
    }
}

/// Bytes as megabytes, one decimal.
fn megabytes(bytes: u64) -> String {
    format!("{:.1} MB", bytes as f64 / 1e6)
}

/// One line on the positioner.
pub(crate) fn describe_positioner(p: &PositionerPlan) -> String {
    match p.kind {
        PositionerKind::MockLab => "mock-lab (moves the simulated targets)".into(),
        PositionerKind::Prompt => {
            "prompt (the operator places the targets and presses Enter)".into()
        }
        PositionerKind::Command => format!(
            "command {} {} (timeout {} s)",
            p.program.as_deref().unwrap_or(""),
            p.args.join(" "),
            p.timeout_s
        ),
    }
}

/// The positioner command of a step, placeholders replaced.
pub(crate) fn command_line(p: &PositionerPlan, ranges: &[f64], step: usize, of: usize) -> String {
    let mut parts = vec![p.program.clone().unwrap_or_default()];
    parts.extend(substitute(&p.args, ranges, step, of));
    parts.join(" ")
}

/// The arguments with `{position_m}`, `{positions_m}`, `{step}` and `{of}` replaced.
pub(crate) fn substitute(args: &[String], ranges: &[f64], step: usize, of: usize) -> Vec<String> {
    let first = ranges.first().map(|r| format!("{r}")).unwrap_or_default();
    let all: Vec<String> = ranges.iter().map(|r| format!("{r}")).collect();
    args.iter()
        .map(|a| {
            a.replace("{position_m}", &first)
                .replace("{positions_m}", &all.join(","))
                .replace("{step}", &step.to_string())
                .replace("{of}", &of.to_string())
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn plan_of(text: &str) -> Result<Plan, SpecError> {
        let spec = SpecFile::parse(text, Path::new("t.toml")).unwrap();
        let bench = BenchInfo::load(&spec, None).unwrap();
        plan(&spec, &bench)
    }

    #[test]
    fn a_position_sweep_moves_one_target() {
        let p =
            plan_of("[sweep]\nparameter = \"position\"\nstart = 1.0\nstep = -0.03\ncount = 6\n")
                .unwrap();
        assert_eq!(p.steps.len(), 6);
        assert!((p.steps[5].nominal.targets[0].range_m - 0.85).abs() < 1e-12);
        assert_eq!(p.positioner.unwrap().kind, PositionerKind::MockLab);
        assert!(p.steps.iter().all(|s| s.noise_seed.is_some()));
        assert_ne!(p.steps[0].noise_seed, p.steps[1].noise_seed);
    }

    #[test]
    fn a_bandwidth_sweep_makes_one_waveform_per_value() {
        let p = plan_of(
            "[sweep]\nparameter = \"bandwidth\"\nvalues = [1e9, 2e9, 1e9]\ntargets = [1.0, 1.08]\n",
        )
        .unwrap();
        assert_eq!(p.waveforms.len(), 2);
        assert_eq!(
            p.steps.iter().map(|s| s.waveform).collect::<Vec<_>>(),
            [0, 1, 0]
        );
        assert_eq!(p.steps[1].nominal.ranges(), [1.0, 1.08]);
    }

    #[test]
    fn values_out_of_range_name_their_field() {
        let err = plan_of("[[steps]]\ntargets = [1.0]\n\n[[steps]]\ntargets = [1.0, 12.0]\n")
            .unwrap_err()
            .to_string();
        assert!(err.starts_with("t.toml:5: `steps[1].targets[1]`"), "{err}");
        let err = plan_of(
            "[waveform]\nkind = \"msk-lfm\"\n[processing]\nalgorithms = [\"music\"]\n[[steps]]\n",
        )
        .unwrap_err()
        .to_string();
        assert!(
            err.starts_with("t.toml:4: `processing.algorithms[0]`"),
            "{err}"
        );
        let err = plan_of("repetitions = 0\n[[steps]]\n")
            .unwrap_err()
            .to_string();
        assert!(err.starts_with("t.toml:1: `repetitions`"), "{err}");
        let err = plan_of("[[steps]]\ntx_attenuation_db = 40\n")
            .unwrap_err()
            .to_string();
        assert!(
            err.contains("steps[0].tx_attenuation_db") && err.contains("31.5"),
            "{err}"
        );
    }

    #[test]
    fn velocity_is_a_plan_field_set_by_steps_or_a_sweep_on_simulated_benches_only() {
        let p = plan_of("[[steps]]\ntargets = [1.0]\nvelocity_mps = 20\n\n[[steps]]\n").unwrap();
        assert_eq!(p.steps[0].nominal.velocity_mps, Some(20.0));
        // What a step does not give stays as the step before left it.
        assert_eq!(p.steps[1].nominal.velocity_mps, Some(20.0));
        let p = plan_of("[sweep]\nparameter = \"velocity\"\nvalues = [0, 50]\ntargets = [1.0]\n")
            .unwrap();
        assert_eq!(p.steps[1].nominal.parameter, Some(SweepParameter::Velocity));
        assert_eq!(p.steps[1].nominal.velocity_mps, Some(50.0));
        assert_eq!(
            p.steps[1].nominal.describe(),
            "velocity 50 m/s, targets 1.000 m"
        );
        let err = plan_of("[sweep]\nparameter = \"velocity\"\nvalues = [0, 5000]\n")
            .unwrap_err()
            .to_string();
        assert!(
            err.contains("`sweep.values[1]`") && err.contains("1000"),
            "{err}"
        );
        let err = plan_of("[[steps]]\nvelocity_mps = -2000\n")
            .unwrap_err()
            .to_string();
        assert!(
            err.starts_with("t.toml:2: `steps[0].velocity_mps`"),
            "{err}"
        );
    }

    #[test]
    fn the_swept_parameter_reads_and_writes_as_before() {
        // A plan without velocities writes no velocity (manifests of today stay as they were).
        let p = plan_of("[sweep]\nparameter = \"tx-attenuation\"\nvalues = [3]\n").unwrap();
        let json = serde_json::to_value(&p.steps[0].nominal).unwrap();
        assert_eq!(json["parameter"], "tx-attenuation");
        assert!(json.get("velocity_mps").is_none(), "{json}");
        let back: Nominal = serde_json::from_value(json).unwrap();
        assert_eq!(back, p.steps[0].nominal);
    }

    #[test]
    fn noise_seeds_differ_per_step_and_campaign() {
        assert_ne!(noise_seed(1, 1), noise_seed(1, 2));
        assert_ne!(noise_seed(1, 1), noise_seed(2, 1));
        assert_eq!(noise_seed(7, 3), noise_seed(7, 3));
    }

    #[test]
    fn the_plan_survives_toml() {
        let p = plan_of(
            "[waveform]\nkind = \"ofdm\"\n[processing]\nalgorithms = [\"fourier\", \"music\"]\n\
             [sweep]\nparameter = \"separation\"\ntargets = [1.0]\nvalues = [0.3]\n",
        )
        .unwrap();
        let text = toml::to_string(&p).unwrap();
        let back: Plan = toml::from_str(&text).unwrap();
        assert_eq!(back, p);
    }
}
