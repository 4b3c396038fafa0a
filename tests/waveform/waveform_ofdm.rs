//! OFDM generator and receiver: payload round trip through a channel, CP property, spectrum.

use num_complex::Complex64;
use radbench::rng::SplitMix64;
use radbench::waveform::{unframe_payload, BitSource};
use radbench::waveform::{Equalisation, Ofdm, OfdmParams};
use rustfft::FftPlanner;

#[test]
fn payload_round_trip_through_multipath_at_high_snr() {
    let o = Ofdm::new(OfdmParams {
        symbols_per_frame: 10,
        ..Default::default()
    })
    .unwrap();
    let payload: Vec<u8> = (0..5000u32).map(|i| (i * 37 % 251) as u8).collect();
    let sig = o.generate(&BitSource::Payload(payload.clone()), 1).unwrap();
    // 32 + 40 000 bits at 9 * 256 bits per frame -> 18 frames.
    assert_eq!(sig.frames, 18);
    assert_eq!(sig.symbols.symbols(), 180);
    // Two paths, the echo 300 samples late (inside the 512-sample CP), and a gain and phase.
    let g0 = Complex64::from_polar(0.7, 1.1);
    let g1 = Complex64::from_polar(0.3, -2.0);
    let delay = 300;
    let mut rx: Vec<Complex64> = sig.samples.iter().map(|z| z * g0).collect();
    for (r, s) in rx[delay..].iter_mut().zip(&sig.samples) {
        *r += g1 * s;
    }
    // Per-sample SNR 25 dB on the direct path.
    SplitMix64::new(5).add_noise(&mut rx, 0.49 / 10f64.powf(2.5));
    let mut receiver = o.receiver();
    let r = receiver.receive(&rx, &Equalisation::Preamble).unwrap();
    assert_eq!(r.bits, sig.bits);
    assert_eq!(unframe_payload(&r.bits).unwrap(), payload);
    // Without equalisation the rotation alone (1.1 rad) ruins the decisions.
    let r = receiver.receive(&rx, &Equalisation::None).unwrap();
    assert_ne!(r.bits, sig.bits);
}

#[test]
fn energy_only_in_the_occupied_band() {
    // Ideal interpolation: the spectrum of a symbol's useful part occupies exactly N of N*os bins,
    // centred on 0 Hz, ascending-frequency subcarrier k at bin (k - N/2) mod L.
    let o = Ofdm::new(OfdmParams {
        subcarriers: 32,
        oversampling: 8,
        symbols_per_frame: 2,
        ..Default::default()
    })
    .unwrap();
    let sig = o.generate(&BitSource::Prbs { seed: 4 }, 1).unwrap();
    let l = o.fft_len();
    let mut body = sig.samples[o.cp_len()..o.symbol_len()].to_vec();
    FftPlanner::new().plan_fft_forward(l).process(&mut body);
    for (bin, z) in body.iter().enumerate() {
        let k = (bin + 16) % l; // inverse of (k - N/2) mod L
        if k < 32 {
            let want = sig.symbols.row(0)[k] * (l as f64 / 32f64.sqrt());
            assert!((z - want).norm() < 1e-9, "bin {bin}");
        } else {
            assert!(
                z.norm() < 1e-9,
                "bin {bin} outside the band holds {}",
                z.norm()
            );
        }
    }
}

#[test]
fn cyclic_prefix_makes_a_delay_a_phase_ramp() {
    // The CP property: a delay d < CP becomes exp(-j 2 pi f_k d / fs) per subcarrier.
    let o = Ofdm::new(OfdmParams {
        subcarriers: 64,
        oversampling: 4,
        symbols_per_frame: 4,
        ..Default::default()
    })
    .unwrap();
    let sig = o.generate(&BitSource::Prbs { seed: 8 }, 1).unwrap();
    let d = 17;
    let mut rx = vec![Complex64::new(0.0, 0.0); sig.samples.len()];
    rx[d..].copy_from_slice(&sig.samples[..sig.samples.len() - d]);
    let mut values = Vec::new();
    o.receiver().subcarriers_into(&rx, &mut values).unwrap();
    let l = o.fft_len() as f64;
    // Symbol 0 sees zeros before the frame, so check symbols 1..4.
    for s in 1..4 {
        for k in 0..64 {
            let f = k as f64 - 32.0;
            let ramp = Complex64::from_polar(1.0, -2.0 * std::f64::consts::PI * f * d as f64 / l);
            let want = sig.symbols.row(s)[k] * ramp;
            assert!((values[s * 64 + k] - want).norm() < 1e-9);
        }
    }
}
