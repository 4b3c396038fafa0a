//! Must-hold figures of the simulation (issue 2), through the library API.

use radbench::simulate::mean_psl_and_width;
use radbench::simulate::simulate;
use radbench::simulate::{run_steps, AccuracySpec};
use radbench::simulate::{Algorithm, RunSpec, WaveformSpec};
use radbench::simulate::{CarrierPhase, Target};

fn one_target(waveform: WaveformSpec) -> (f64, f64) {
    let spec = RunSpec::new("t", waveform, vec![Target::at(3.0)]);
    let r = simulate(&spec).unwrap().result;
    (r.width_3db_cm.unwrap(), r.sidelobe_db.unwrap())
}

#[test]
fn msk_lfm_one_target_at_3_m_has_the_thesis_lobe() {
    let (width, psl) = one_target(WaveformSpec::msk_lfm_default());
    assert!((13.2..=13.4).contains(&width), "width {width} cm");
    assert!((-13.6..=-13.0).contains(&psl), "PSL {psl} dB");
}

#[test]
fn ofdm_one_target_at_3_m_with_1280_points_has_the_thesis_lobe() {
    let (width, psl) = one_target(WaveformSpec::ofdm_default());
    assert!((13.2..=13.4).contains(&width), "width {width} cm");
    assert!((-13.6..=-13.0).contains(&psl), "PSL {psl} dB");
}

#[test]
fn msk_lfm_4096_bits_lower_the_sidelobes_by_2_5_to_4_5_db() {
    let (psl128, w128, _) = mean_psl_and_width(128).unwrap();
    let (psl4096, w4096, _) = mean_psl_and_width(4096).unwrap();
    let drop = psl128 - psl4096;
    assert!(
        (2.5..=4.5).contains(&drop),
        "mean PSL {psl128} -> {psl4096} dB"
    );
    assert!((w4096 - w128).abs() < 1.0, "width {w128} -> {w4096} cm");
}

#[test]
fn accuracy_steps_through_the_80_to_16_gsa_chain_are_exact_enough() {
    let study = run_steps(&AccuracySpec::thesis()).unwrap();
    assert_eq!(study.steps.len(), 6, "reference and 5 steps");
    for s in &study.steps {
        assert!(
            s.error_cm.abs() < 0.05,
            "interpolated error at {} m: {} cm",
            s.true_m,
            s.error_cm
        );
        assert!(
            s.error_on_grid_cm.abs() <= study.half_bin_cm + 1e-9,
            "grid error at {} m: {} cm (half bin {})",
            s.true_m,
            s.error_on_grid_cm,
            study.half_bin_cm
        );
    }
    // The capture path really ran at 80 GSa/s.
    assert_eq!(study.result.capture_rate_hz, 80e9);
}

#[test]
fn ofdm_3_00_and_3_15_m_with_a_128_point_ifft_are_not_resolved() {
    for carrier in [
        CarrierPhase::Physical,
        CarrierPhase::Centred,
        CarrierPhase::Thesis,
    ] {
        let mut spec = RunSpec::new(
            "t",
            WaveformSpec::ofdm_default(),
            vec![Target::at(3.0), Target::at(3.15)],
        );
        spec.processing.zero_pad = 1;
        spec.carrier = carrier;
        assert!(!simulate(&spec).unwrap().result.resolved, "{carrier}");
    }
}

#[test]
fn echo_phase_convention_decides_the_ofdm_two_target_figure() {
    let mut spec = RunSpec::new(
        "t",
        WaveformSpec::ofdm_default(),
        vec![Target::at(3.0), Target::at(3.15)],
    );
    spec.carrier = CarrierPhase::Thesis;
    assert!(
        simulate(&spec).unwrap().result.resolved,
        "thesis phase: two peaks (Fig. 4.4b)"
    );
}

#[test]
fn esprit_returns_noise_free_ranges_directly() {
    let mut spec = RunSpec::new(
        "t",
        WaveformSpec::ofdm_default(),
        vec![Target::at(1.0), Target::at(1.06)],
    );
    spec.processing.algorithm = Algorithm::Esprit;
    spec.processing.music_p = Some(2);
    let r = simulate(&spec).unwrap().result;
    assert!(r.resolved && r.range_bin_m.is_none());
    for e in r.errors_cm {
        assert!(e.unwrap().abs() < 0.01);
    }
}

#[test]
fn trials_report_a_rate_and_every_trials_peaks() {
    let mut spec = RunSpec::new("t", WaveformSpec::msk_lfm_default(), vec![Target::at(2.0)]);
    spec.snr_db = Some(-20.0);
    spec.trials = 3;
    let r = simulate(&spec).unwrap().result;
    assert_eq!(r.trial_peaks_m.as_ref().unwrap().len(), 3);
    let rate = r.resolved_rate.unwrap();
    assert!((0.0..=1.0).contains(&rate));
    // Noise differs between trials: the peaks are not all identical.
    let peaks = r.trial_peaks_m.unwrap();
    assert!(peaks.windows(2).any(|w| w[0] != w[1]), "{peaks:?}");
}
