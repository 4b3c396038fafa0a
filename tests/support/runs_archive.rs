//! A synthetic archive of run folders for the run catalog's tests and benchmark: each folder a
//! `manifest.toml` and a `results.json` serialised from radbench's own types (`Manifest`,
//! `Results`), varied by a seed (campaign name, scope, calibration, creation time, errors). No
//! step's capture files: the catalog reads the manifest and results only.

use radbench::campaign::{
    AlgorithmResult, BenchInfo, CalibrationRecord, FileRecord, InputFile, Instruments, Manifest,
    Plan, Results, SpecFile, Status, StepRecord, StepResult, StepStatus, TargetResult,
};
use std::path::Path;

/// The scopes the archive's runs name (by `*IDN?`).
pub const SCOPES: [&str; 2] = [
    "KEYSIGHT TECHNOLOGIES,UXR0704A,MY0001,10.0",
    "TELEDYNE LECROY,LABMASTER10ZI-A,LCRY0001,9.1",
];

/// The plans of the archive's two campaign kinds (planned once: a plan is the same for every
/// run of its spec).
pub fn plans() -> Vec<Plan> {
    let specs = [
        "name = \"accuracy\"\n[sweep]\nparameter = \"position\"\nvalues = [1.0, 0.97, 0.94, 0.91]\n",
        "name = \"resolution\"\n[sweep]\nparameter = \"bandwidth\"\nvalues = [1e9, 2e9, 3e9]\ntargets = [1.0, 1.08]\n",
    ];
    specs
        .iter()
        .map(|text| {
            let spec = SpecFile::parse(text, Path::new("spec.toml")).expect("the spec parses");
            let bench = BenchInfo::load(&spec, None).expect("the built-in bench");
            radbench::campaign::plan(&spec, &bench).expect("the plan")
        })
        .collect()
}

/// SplitMix64: the archive's numbers from its seed.
fn mix(mut z: u64) -> u64 {
    z = z.wrapping_add(0x9E37_79B9_7F4A_7C15);
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

/// Uniform in [0, 1) from `seed` and `salt`.
fn unit(seed: u64, salt: u64) -> f64 {
    (mix(seed ^ mix(salt)) >> 11) as f64 / (1u64 << 53) as f64
}

/// Writes run number `i` of the archive (seeded by `seed`) into `dir` (created).
pub fn write_run(dir: &Path, plans: &[Plan], seed: u64, i: u64) {
    std::fs::create_dir_all(dir).expect("the run folder");
    let s = mix(seed ^ i);
    let plan = plans[(s % plans.len() as u64) as usize].clone();
    let day = 1 + (i % 28);
    let created = format!(
        "2026-{:02}-{day:02}T{:02}:{:02}:{:02}.{:03}Z",
        1 + (i / 28) % 12,
        (s >> 8) % 24,
        (s >> 16) % 60,
        (s >> 24) % 60,
        i % 1000
    );
    let complete = unit(s, 1) > 0.1;
    let calibrated = unit(s, 2) > 0.5;
    let steps_done = if complete {
        plan.steps.len()
    } else {
        plan.steps.len() / 2
    };
    let step_dir = |index: usize| format!("step-{index:03}");
    let steps: Vec<StepRecord> = plan
        .steps
        .iter()
        .map(|st| {
            let done = st.index <= steps_done;
            StepRecord {
                index: st.index,
                status: if done {
                    StepStatus::Done
                } else {
                    StepStatus::Pending
                },
                dir: step_dir(st.index).into(),
                measured_at: done.then(|| created.clone()),
                applied: None,
                files: if done {
                    vec![FileRecord {
                        path: format!("{}/summary.json", step_dir(st.index)).into(),
                        bytes: 1000 + st.index as u64,
                        sha256: format!("{:064x}", mix(s ^ st.index as u64)),
                    }]
                } else {
                    Vec::new()
                },
            }
        })
        .collect();
    let results = Results {
        steps: plan
            .steps
            .iter()
            .filter(|st| st.index <= steps_done)
            .map(|st| {
                // Errors spread over three decades, so `--where` has something to tell apart.
                let error_m =
                    (unit(s, 10 + st.index as u64) - 0.5) * 10f64.powf(-2.0 - 2.0 * unit(s, 3));
                let snr_db = 60.0 + 20.0 * unit(s, 20 + st.index as u64);
                let algorithm = AlgorithmResult {
                    targets: st
                        .nominal
                        .targets
                        .iter()
                        .map(|t| TargetResult {
                            range_m: t.range_m + error_m,
                            range_std_m: None,
                            range_uncertainty_m: None,
                            level_db: -40.0,
                            on_grid_m: None,
                        })
                        .collect(),
                    width_3db_cm: Some(15.0),
                    sidelobe_db: Some(-13.3),
                    snr_db: Some(snr_db),
                    error_m: Some(error_m),
                    error_on_grid_m: Some(error_m * 2.0),
                    truth_error_m: None,
                    truth_error_on_grid_m: None,
                    missed: 0,
                    resolved: (st.nominal.targets.len() > 1).then_some(unit(s, 4) > 0.3),
                    payload: None,
                    spread: None,
                    chain_echoes: Vec::new(),
                };
                StepResult {
                    index: st.index,
                    nominal: st.nominal.clone(),
                    repetitions: 1,
                    algorithms: [("correlation".to_string(), algorithm)].into(),
                    truth: None,
                }
            })
            .collect(),
    };
    let scope = SCOPES[((s >> 40) % SCOPES.len() as u64) as usize];
    let manifest = Manifest {
        format: 1,
        status: if complete {
            Status::Complete
        } else {
            Status::Interrupted
        },
        reason: (!complete).then(|| "SIGINT".to_string()),
        stopped_at_step: (!complete).then_some(steps_done + 1),
        exit_code: (!complete).then_some(130),
        radbench_version: "0.1.0".into(),
        git_commit: None,
        created: created.clone(),
        updated: created.clone(),
        spec: InputFile {
            path: "/lab/specs/spec.toml".into(),
            copy: "spec.toml".into(),
            sha256: format!("{:064x}", mix(s ^ 77)),
        },
        bench_file: None,
        bench_catalog: Vec::new(),
        calibration: calibrated.then(|| CalibrationRecord {
            mode: radbench::measure::CorrectionMode::Rx,
            path: "/lab/cal/response.toml".into(),
            copy: "calibration/response.toml".into(),
            table_copy: "calibration/response.npy".into(),
            sha256: if unit(s, 5) > 0.5 {
                "aa11".repeat(16)
            } else {
                "bb22".repeat(16)
            },
            measured_at: "2026-01-01T00:00:00.000Z".into(),
        }),
        operator: Some("archive".into()),
        instruments: Some(Instruments {
            awg: "KEYSIGHT,M8195A,DE0001,4.0".into(),
            scope: scope.into(),
            tx: None,
            rx: None,
        }),
        base_scene: None,
        plan,
        sessions: Vec::new(),
        steps,
        files: Vec::new(),
        retries: Vec::new(),
    };
    let text = toml::to_string(&manifest).expect("the manifest serialises");
    std::fs::write(dir.join("manifest.toml"), text).expect("manifest.toml");
    let json = serde_json::to_vec(&results).expect("the results serialise");
    std::fs::write(dir.join("results.json"), json).expect("results.json");
}

/// `n` runs under `root`, named `run-00000`, ...
pub fn write_archive(root: &Path, n: u64, seed: u64) {
    let plans = plans();
    for i in 0..n {
        write_run(&root.join(format!("run-{i:05}")), &plans, seed, i);
    }
}
