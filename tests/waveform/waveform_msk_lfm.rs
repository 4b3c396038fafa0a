//! MSK-LFM generator and receiver: envelope, phase continuity, payload round trip.

use num_complex::Complex64;
use radbench::rng::SplitMix64;
use radbench::waveform::BitSource;
use radbench::waveform::{MskLfm, MskLfmParams, PulseLength};

/// Largest phase step between neighbouring samples that a continuous-phase MSK-LFM can take: the
/// chirp's instantaneous frequency is within +-B/2 and MSK adds +-1/(4T).
fn max_phase_step(w: &MskLfm) -> f64 {
    std::f64::consts::PI * w.bandwidth_hz() / w.sample_rate_hz()
        + std::f64::consts::FRAC_PI_2 / w.samples_per_bit()
}

/// Checks every pulse of `samples`, and each pulse looped onto itself (as the AWG plays it).
fn check_envelope_and_phase(w: &MskLfm, samples: &[Complex64]) {
    for pulse in samples.chunks_exact(w.samples_per_pulse()) {
        let mut looped = pulse.to_vec();
        looped.extend_from_slice(&pulse[..1000]);
        check_one(w, &looped);
    }
}

fn check_one(w: &MskLfm, samples: &[Complex64]) {
    for (n, z) in samples.iter().enumerate() {
        assert!(
            (z.norm() - 1.0).abs() < 1e-12,
            "envelope {} at {n}",
            z.norm()
        );
    }
    let bound = max_phase_step(w) * (1.0 + 1e-9);
    for (n, pair) in samples.windows(2).enumerate() {
        let step = (pair[1] * pair[0].conj()).arg().abs();
        assert!(
            step <= bound,
            "phase jump {step} rad at sample {n} (bound {bound})"
        );
    }
}

#[test]
fn constant_envelope_and_continuous_phase_thesis_pulses() {
    let w = MskLfm::new(MskLfmParams::default()).unwrap();
    let sig = w.generate(&BitSource::Prbs { seed: 42 }, 3).unwrap();
    assert_eq!(sig.samples.len(), 3 * 160_000);
    check_envelope_and_phase(&w, &sig.samples);
}

#[test]
fn constant_envelope_and_continuous_phase_with_fractional_samples_per_bit() {
    // Thesis 4.1.2: 4096 bits in the same 160 000 samples (39.0625 samples per bit).
    let w = MskLfm::new(MskLfmParams {
        bits_per_pulse: 4096,
        ..Default::default()
    })
    .unwrap();
    let sig = w.generate(&BitSource::Prbs { seed: 7 }, 2).unwrap();
    check_envelope_and_phase(&w, &sig.samples);
    assert_eq!(w.demodulate(&sig.samples).unwrap(), sig.bits);
}

#[test]
fn a_flipped_symbol_sign_would_break_the_phase_check() {
    // Guard that the phase test can fail: a sign flip mid-symbol is a pi jump.
    let w = MskLfm::new(MskLfmParams::default()).unwrap();
    let mut sig = w.generate(&BitSource::Prbs { seed: 1 }, 1).unwrap().samples;
    for z in &mut sig[1000..] {
        *z = -*z;
    }
    let step = (sig[1000] * sig[999].conj()).arg().abs();
    assert!(step > max_phase_step(&w) * 10.0);
}

#[test]
fn payload_round_trip_at_high_snr() {
    let w = MskLfm::new(MskLfmParams::default()).unwrap();
    let text = "radbench: MSK-LFM carries data while it measures range.";
    let sig = w.generate(&BitSource::text(text), 1).unwrap();
    // 32 + 8 * 55 = 472 bits -> 4 pulses of 128 bits.
    assert_eq!(sig.pulses, 4);
    let mut rx = sig.samples.clone();
    // Eb/N0 = 12 dB: sigma^2 = 1250 / 10^1.2, BER ~ 1e-8.
    SplitMix64::new(9).add_noise(&mut rx, 1250.0 / 10f64.powf(1.2));
    let bits = w.demodulate(&rx).unwrap();
    assert_eq!(bits, sig.bits);
    let payload = radbench::waveform::unframe_payload(&bits).unwrap();
    assert_eq!(String::from_utf8(payload).unwrap(), text);
}

#[test]
fn pulse_length_in_samples_or_seconds() {
    let a = MskLfm::new(MskLfmParams {
        pulse: PulseLength::Samples(160_000),
        ..Default::default()
    })
    .unwrap();
    let b = MskLfm::new(MskLfmParams::default()).unwrap();
    let bits = SplitMix64::new(3).bits(128);
    assert_eq!(a.pulse(&bits).unwrap(), b.pulse(&bits).unwrap());
}
