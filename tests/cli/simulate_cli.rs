//! `radbench simulate` and `radbench bench` as a user runs them: JSON shape, exit codes, files.

use crate::process_support;

use std::process::{Command, Output};
use std::time::Duration;

/// Every run is bounded by this.
const LIMIT: Duration = Duration::from_secs(120);

fn radbench(args: &[&str]) -> Output {
    process_support::output_within(
        Command::new(env!("CARGO_BIN_EXE_radbench")).args(args),
        LIMIT,
    )
}

/// `radbench simulate run ARGS --json`: its one scenario.
fn run_scenario(args: &[&str]) -> serde_json::Value {
    let args: Vec<&str> = ["simulate", "run"]
        .into_iter()
        .chain(args.iter().copied())
        .chain(["--json"])
        .collect();
    json_of(&radbench(&args))["scenarios"][0].clone()
}

fn json_of(out: &Output) -> serde_json::Value {
    assert!(
        out.status.success(),
        "exit {:?}: {}",
        out.status.code(),
        String::from_utf8_lossy(&out.stderr)
    );
    serde_json::from_slice(&out.stdout).expect("stdout is one JSON object")
}

const SCENARIO_KEYS: [&str; 8] = [
    "id",
    "waveform",
    "algorithm",
    "targets_m",
    "peaks_m",
    "width_3db_cm",
    "sidelobe_db",
    "resolved",
];

#[test]
fn thesis_json_parses_and_every_expected_row_agrees() {
    let doc = json_of(&radbench(&["simulate", "thesis", "--json"]));
    let rows = doc["scenarios"].as_array().expect("scenarios array");
    assert!(rows.len() >= 15, "{} rows", rows.len());
    for row in rows {
        for key in SCENARIO_KEYS {
            assert!(row.get(key).is_some(), "row {} lacks {key}", row["id"]);
        }
        let agrees = row["agrees"].as_bool().unwrap();
        if row["expected_to_agree"].as_bool().unwrap() {
            assert!(agrees, "row {} should agree: {row}", row["id"]);
        } else if !agrees {
            assert!(
                row["reason"].as_str().is_some_and(|r| !r.is_empty()),
                "{row}"
            );
        }
    }
    let sections: Vec<&str> = rows
        .iter()
        .map(|r| r["section"].as_str().unwrap())
        .collect();
    for s in [
        "4.1.1", "4.1.2", "4.1.3", "4.2.1", "4.2.2", "4.2.3", "T4.3", "4.2.5", "4.4.2", "T4.8",
    ] {
        assert!(sections.contains(&s), "section {s} missing");
    }
    // Two-target rows come under both conventions.
    let phases: Vec<&str> = rows
        .iter()
        .filter(|r| r["section"] == "4.1.3")
        .map(|r| r["carrier_phase"].as_str().unwrap())
        .collect();
    assert!(phases.contains(&"physical") && phases.contains(&"thesis"));
}

#[test]
fn run_json_has_the_documented_keys() {
    let s = run_scenario(&[
        "--waveform",
        "ofdm",
        "--targets",
        "1,1.06",
        "--algorithm",
        "music",
        "--m",
        "64",
        "--p",
        "2",
    ]);
    for key in SCENARIO_KEYS {
        assert!(s.get(key).is_some(), "missing {key}: {s}");
    }
    assert_eq!(s["waveform"], "ofdm");
    assert_eq!(s["algorithm"], "music");
    assert_eq!(s["carrier_phase"], "physical");
    assert_eq!(s["resolved"], true);
    assert_eq!(s["fft_precision"], "single");
    assert!(s.get("resolved_rate").is_none(), "single trial: no rate");
    // Every key written is in the schema users read.
    let schema = std::fs::read_to_string(
        std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("docs/simulate-json.md"),
    )
    .unwrap();
    for key in s.as_object().unwrap().keys() {
        assert!(
            schema.contains(&format!("| `{key}` |")),
            "{key} is not documented in docs/simulate-json.md"
        );
    }
}

#[test]
fn run_uses_and_reports_the_detector_asked_for() {
    // Two echoes 30 cm apart: cell-averaging CFAR counts each in the other's noise window and
    // misses both, as the detector comparison in docs/detection.md describes; CLEAN finds both.
    let detected = |detector: &str| {
        let s = run_scenario(&[
            "--waveform",
            "msk-lfm",
            "--targets",
            "3,3.3",
            "--snr-db",
            "0",
            "--detector",
            detector,
        ]);
        assert_eq!(s["detector"], detector);
        serde_json::from_value::<Vec<f64>>(s["detected_m"].clone()).unwrap()
    };
    let clean = detected("clean");
    assert_eq!(clean.len(), 2, "{clean:?}");
    assert!((clean[0] - 3.0).abs() < 0.01 && (clean[1] - 3.3).abs() < 0.01);
    assert!(detected("ca-cfar").len() < 2);
}

#[test]
fn fft_precision_double_is_reported_and_agrees_with_single() {
    let peaks = |precision: &str| {
        let s = run_scenario(&[
            "--waveform",
            "ofdm",
            "--targets",
            "2.5,2.8",
            "--fft-precision",
            precision,
        ]);
        assert_eq!(s["fft_precision"], precision);
        serde_json::from_value::<Vec<f64>>(s["peaks_m"].clone()).unwrap()
    };
    let (single, double) = (peaks("single"), peaks("double"));
    assert_eq!(single.len(), 2);
    for (a, b) in single.iter().zip(&double) {
        assert!((a - b).abs() < 1e-6, "{single:?} vs {double:?}");
    }
}

#[test]
fn run_with_trials_reports_rate_and_per_trial_peaks() {
    let s = run_scenario(&[
        "--waveform",
        "msk-lfm",
        "--targets",
        "2",
        "--snr-db",
        "-10",
        "--trials",
        "3",
    ]);
    assert!(s["resolved_rate"].is_number());
    assert_eq!(s["trial_peaks_m"].as_array().unwrap().len(), 3);
}

#[test]
fn run_writes_plots_and_profiles() {
    let dir = tempfile::tempdir().unwrap();
    let svg = dir.path().join("p.svg");
    let png = dir.path().join("p.png");
    let csv = dir.path().join("p.csv");
    let npy = dir.path().join("p.npy");
    for (plot, profile) in [(&svg, &csv), (&png, &npy)] {
        let out = radbench(&[
            "simulate",
            "run",
            "--waveform",
            "ofdm",
            "--targets",
            "1,1.1",
            "--algorithm",
            "music",
            "--p",
            "2",
            "--plot",
            plot.to_str().unwrap(),
            "--profile-out",
            profile.to_str().unwrap(),
        ]);
        assert!(
            out.status.success(),
            "{}",
            String::from_utf8_lossy(&out.stderr)
        );
    }
    let svg_text = std::fs::read_to_string(&svg).unwrap();
    assert!(
        svg_text.contains("MUSIC") && svg_text.contains("Fourier"),
        "both overlaid"
    );
    assert_eq!(&std::fs::read(&png).unwrap()[1..4], b"PNG");
    let csv_text = std::fs::read_to_string(&csv).unwrap();
    assert!(csv_text.starts_with("range_m,"), "{}", &csv_text[..40]);
    assert_eq!(&std::fs::read(&npy).unwrap()[..6], b"\x93NUMPY");
}

#[test]
fn bad_input_exits_2_naming_the_field() {
    let cases: [(&[&str], &str); 7] = [
        (
            &[
                "simulate",
                "run",
                "--waveform",
                "msk-lfm",
                "--targets",
                "3:-1",
            ],
            "--targets",
        ),
        (
            &[
                "simulate",
                "run",
                "--waveform",
                "msk-lfm",
                "--targets",
                "abc",
            ],
            "--targets",
        ),
        (
            &[
                "simulate",
                "run",
                "--waveform",
                "msk-lfm",
                "--targets",
                "3",
                "--algorithm",
                "music",
            ],
            "--algorithm",
        ),
        (
            &[
                "simulate",
                "run",
                "--waveform",
                "ofdm",
                "--targets",
                "3",
                "--capture-rate",
                "50e9",
            ],
            "--capture-rate",
        ),
        (
            &[
                "simulate",
                "run",
                "--waveform",
                "ofdm",
                "--targets",
                "3",
                "--algorithm",
                "music",
                "--m",
                "200",
            ],
            "--m",
        ),
        (
            &[
                "simulate",
                "run",
                "--waveform",
                "ofdm",
                "--targets",
                "3",
                "--algorithm",
                "music",
                "--m",
                "16",
                "--p",
                "16",
            ],
            "--p",
        ),
        (
            &["simulate", "run", "--waveform", "sonar", "--targets", "3"],
            "--waveform",
        ),
    ];
    for (args, field) in cases {
        let out = radbench(args);
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(2), "{args:?}: {stderr}");
        assert!(
            stderr.contains(field),
            "{args:?} should name {field}: {stderr}"
        );
    }
}

#[test]
fn waveform_parameter_errors_exit_2() {
    let out = radbench(&[
        "simulate",
        "run",
        "--waveform",
        "ofdm",
        "--targets",
        "3",
        "--cp-fraction",
        "1.5",
    ]);
    assert_eq!(
        out.status.code(),
        Some(2),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
}

#[test]
fn ber_json_has_every_point_with_its_interval_and_deviation() {
    let doc = json_of(&radbench(&["simulate", "ber", "--bits", "1000", "--json"]));
    let points = doc["ber"].as_array().unwrap();
    assert_eq!(points.len(), 22, "11 Eb/N0 points per waveform");
    for p in points {
        let (lo, hi) = (
            p["ci95_low"].as_f64().unwrap(),
            p["ci95_high"].as_f64().unwrap(),
        );
        let ber = p["ber"].as_f64().unwrap();
        assert!(lo <= ber && ber <= hi, "{p}");
        let theory = p["ber_theory"].as_f64().unwrap();
        assert_eq!(p["theory_within_ci95"], lo <= theory && theory <= hi, "{p}");
        assert!(p["deviation_sigma"].as_f64().unwrap().is_finite(), "{p}");
        assert!(p["bits"].as_u64().unwrap() >= 1000, "{p}");
    }
}
