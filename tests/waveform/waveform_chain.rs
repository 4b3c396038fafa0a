//! The lab chain on the waveform side: an MSK-LFM echo captured at 80 GSa/s, decimated by 5 with
//! delay compensation, correlated against the 16 GSa/s transmit pulse: the echo's delay survives.

use num_complex::Complex64;
use radbench::dsp::CrossCorrelator;
use radbench::dsp::{Alignment, Decimator, DecimatorConfig};
use radbench::rng::SplitMix64;
use radbench::waveform::BitSource;
use radbench::waveform::{MskLfm, MskLfmParams};

/// Peak lag with parabolic interpolation on the magnitude.
fn peak(r: &[Complex64]) -> f64 {
    let k = (1..r.len() - 1)
        .max_by(|&a, &b| r[a].norm().total_cmp(&r[b].norm()))
        .unwrap();
    let (a, b, c) = (r[k - 1].norm(), r[k].norm(), r[k + 1].norm());
    k as f64 + 0.5 * (a - c) / (a - 2.0 * b + c)
}

fn chain(alignment: Alignment, delay80: usize) -> f64 {
    let fast = MskLfm::new(MskLfmParams {
        sample_rate_hz: 80e9,
        ..Default::default()
    })
    .unwrap();
    let slow = MskLfm::new(MskLfmParams::default()).unwrap();
    let source = BitSource::Prbs { seed: 21 };
    let tx80 = fast.generate(&source, 1).unwrap().samples;
    let tx16 = slow.generate(&source, 1).unwrap().samples;
    // Same bits, same analogue waveform: the 16 GSa/s pulse is every 5th sample of the 80 GSa/s one.
    for m in (0..tx16.len()).step_by(997) {
        assert!((tx16[m] - tx80[5 * m]).norm() < 1e-6);
    }
    let mut rx80 = vec![Complex64::new(0.0, 0.0); tx80.len()];
    rx80[delay80..].copy_from_slice(&tx80[..tx80.len() - delay80]);
    SplitMix64::new(3).add_noise(&mut rx80, 0.1);
    let cfg = DecimatorConfig {
        alignment,
        ..Default::default()
    };
    let mut dec = Decimator::new(&cfg).unwrap();
    // In chunks, as a streaming capture would arrive.
    let mut rx16 = Vec::with_capacity(tx16.len());
    for chunk in rx80.chunks(100_003) {
        dec.process(chunk, &mut rx16);
    }
    dec.finish(&mut rx16);
    assert_eq!(rx16.len(), tx16.len());
    let mut corr = CrossCorrelator::new(&tx16, rx16.len(), 0..=2047).unwrap();
    peak(&corr.correlate(&rx16).unwrap())
}

#[test]
fn decimated_capture_keeps_the_echo_delay() {
    // 617 samples at 80 GSa/s = 123.4 samples at 16 GSa/s (1.156 m).
    let lag = chain(Alignment::Compensated, 617);
    assert!((lag - 123.4).abs() < 0.05, "peak at lag {lag}, want 123.4");
}

#[test]
fn without_compensation_the_filter_delay_shows() {
    let d = Decimator::new(&DecimatorConfig::default()).unwrap();
    let lag = chain(Alignment::Causal, 617);
    let want = 123.4 + d.group_delay_output_samples();
    assert!((lag - want).abs() < 0.05, "peak at lag {lag}, want {want}");
}
