//! Detection benchmarks (divan): `dsp::detect` on the thesis profiles it runs on after every
//! capture, with 1 and 4 pillars plus the bench's leakage, and the one-off cost of building the
//! point spread. Run: `cargo bench --bench detect`.

#[path = "../tests/support/detect/mod.rs"]
mod detect_support;

use detect_support::*;
use num_complex::Complex64;
use radbench::dsp::{CfarKind, DetectOptions, Method, TabulatedPsf};

fn main() {
    divan::main();
}

fn scene(count: usize) -> Vec<Pillar> {
    let mut s: Vec<Pillar> = [(1.0, 0.5), (1.3, 0.3), (2.7, 0.1), (5.1, 0.2)]
        .iter()
        .take(count)
        .map(|&(r, a)| Pillar::physical(r, a))
        .collect();
    s.push(leakage(0.01));
    s
}

fn bench_detect(bencher: divan::Bencher, wave: Wave, count: usize, method: Method) {
    let mut bench = Bench::new(wave);
    let axis = bench.axis;
    let z: Vec<Complex64> = bench.scene(&scene(count), Some(SNR_DB), 1).to_vec();
    let mut det = bench.detector(DetectOptions {
        method,
        ..DetectOptions::default()
    });
    let found = det.detect(&z, axis, WINDOW).unwrap().targets.len();
    if let Method::Clean { .. } = method {
        assert_eq!(found, count, "{}", wave.name());
    }
    bencher.bench_local(|| det.detect(&z, axis, WINDOW).unwrap());
}

/// The same on the mock lab's `thesis-lab` chain response (standing-wave echo, tilt, group-delay
/// ripple, dispersion): the chain floor's mismatch check and the pruning of the echoes.
fn bench_detect_thesis_lab(bencher: divan::Bencher, wave: Wave, count: usize) {
    let mut bench = Bench::new(wave);
    let axis = bench.axis;
    let chain = mock_lab::scene::ChainParams::thesis_lab();
    let rx = bench.capture_through(&scene(count), Some(SNR_DB), 1, &|f| chain.response_at(f));
    let z: Vec<Complex64> = bench.process(&rx).to_vec();
    let mut det = bench.detector(DetectOptions::default());
    let found = det.detect(&z, axis, WINDOW).unwrap().targets.len();
    assert_eq!(found, count, "{}", wave.name());
    bencher.bench_local(|| det.detect(&z, axis, WINDOW).unwrap());
}

#[divan::bench(args = [1, 4], sample_count = 30)]
fn clean_msk_lfm_thesis_lab(bencher: divan::Bencher, count: usize) {
    bench_detect_thesis_lab(bencher, Wave::MskLfm, count);
}

#[divan::bench(args = [1, 4], sample_count = 30)]
fn clean_ofdm_thesis_lab(bencher: divan::Bencher, count: usize) {
    bench_detect_thesis_lab(bencher, Wave::Ofdm, count);
}

const CLEAN: Method = Method::Clean {
    noise: radbench::dsp::NoiseEstimate::Global,
};

#[divan::bench(args = [1, 4], sample_count = 30)]
fn clean_msk_lfm(bencher: divan::Bencher, count: usize) {
    bench_detect(bencher, Wave::MskLfm, count, CLEAN);
}

#[divan::bench(args = [1, 4], sample_count = 30)]
fn clean_ofdm(bencher: divan::Bencher, count: usize) {
    bench_detect(bencher, Wave::Ofdm, count, CLEAN);
}

#[divan::bench(args = [1, 4], sample_count = 30)]
fn os_cfar_msk_lfm(bencher: divan::Bencher, count: usize) {
    let os = Method::Cfar {
        kind: CfarKind::Os { rank: 0.75 },
    };
    bench_detect(bencher, Wave::MskLfm, count, os);
}

/// The correlation spread of the 160 000-sample thesis pulse over 1400 lags (once per waveform).
#[divan::bench(sample_count = 10)]
fn psf_correlation_160k(bencher: divan::Bencher) {
    let bench = Bench::new(Wave::MskLfm);
    bencher.bench_local(|| TabulatedPsf::correlation(&bench.reference, None, 1416).unwrap());
}
