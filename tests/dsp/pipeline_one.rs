//! One pipeline: a simulation and a bench capture of the same samples with the same options give
//! bit-identical range profiles and the same detections, for every algorithm.

use radbench::measure::Algorithm;
use radbench::measure::{Pipeline, RecordGeometry};
use radbench::simulate::Target;
use radbench::simulate::{first_trial, process_options, simulate, transmission};
use radbench::simulate::{RunSpec, WaveformSpec};

fn spec(waveform: WaveformSpec, algorithm: Algorithm) -> RunSpec {
    let mut spec = RunSpec::new(
        "one-pipeline",
        waveform,
        vec![
            Target::at(1.0),
            Target {
                amplitude: 0.6,
                ..Target::at(1.3)
            },
        ],
    );
    spec.processing.algorithm = algorithm;
    spec.snr_db = Some(20.0);
    spec.capture_rate_hz = Some(80e9);
    spec.seed = 7;
    spec
}

/// The capture path: a pipeline built as a capture builds it, `align` then `process` (background
/// subtraction, metrics and payload included).
fn capture_path(spec: &RunSpec) -> radbench::measure::Processed {
    let tx = transmission(spec).unwrap();
    let raw = first_trial(spec).unwrap();
    let window = raw.samples.len() / spec.upsample();
    let sim = radbench::simulate::pipeline(spec, tx.clone(), window).unwrap();
    // The same options and geometry, built independently of the simulation.
    let mut pipeline = Pipeline::new(
        tx,
        process_options(spec),
        RecordGeometry {
            period: window,
            correlation_lags: sim.geometry().correlation_lags,
        },
    )
    .unwrap();
    let aligned = pipeline.align(&raw).unwrap();
    pipeline.process(aligned, None).unwrap()
}

fn check(spec: RunSpec) {
    let outcome = simulate(&spec).unwrap();
    let captured = capture_path(&spec);
    assert_eq!(
        outcome.profiles.len(),
        captured.profiles.len(),
        "{}",
        spec.processing.algorithm.name()
    );
    for (a, b) in outcome.profiles.iter().zip(&captured.profiles) {
        assert_eq!(a.label, b.label);
        assert_eq!(a.axis, b.axis);
        assert!(
            a.amplitude
                .iter()
                .zip(&b.amplitude)
                .all(|(x, y)| x.to_bits() == y.to_bits()),
            "{}: profile {} differs",
            spec.processing.algorithm.name(),
            a.label
        );
    }
    let detected: Vec<f64> = captured.targets.iter().map(|t| t.range_m).collect();
    assert_eq!(
        outcome.result.detected_m,
        detected,
        "{}",
        spec.processing.algorithm.name()
    );
}

#[test]
fn simulate_and_capture_agree_bit_for_bit_msk_lfm() {
    check(spec(
        WaveformSpec::msk_lfm_default(),
        Algorithm::Correlation,
    ));
}

#[test]
fn simulate_and_capture_agree_bit_for_bit_every_ofdm_algorithm() {
    for alg in [
        Algorithm::Correlation,
        Algorithm::Fourier,
        Algorithm::Music,
        Algorithm::RootMusic,
        Algorithm::Esprit,
    ] {
        let mut s = spec(WaveformSpec::ofdm_default(), alg);
        s.processing.music_p = Some(2);
        check(s);
    }
}
