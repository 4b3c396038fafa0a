//! Waveform-side kernels (divan): decimation 80 -> 16 GSa/s and FFT cross-correlation, on the
//! thesis' sizes. Run: `cargo bench --bench kernels_wave` (short: a few seconds).

use divan::Bencher;
use num_complex::Complex64;
use radbench::dsp::CrossCorrelator;
use radbench::dsp::{Decimator, DecimatorConfig};
use radbench::rng::SplitMix64;
use radbench::waveform::BitSource;
use radbench::waveform::{MskLfm, MskLfmParams};

fn main() {
    divan::main();
}

fn noise(n: usize) -> Vec<Complex64> {
    let mut r = SplitMix64::new(1);
    (0..n).map(|_| r.complex_gaussian(1.0)).collect()
}

#[divan::bench(args = [800_000, 1_280_000], sample_count = 30)]
fn decimate_by_5(bencher: Bencher, n: usize) {
    let x = noise(n);
    let mut d = Decimator::new(&DecimatorConfig::default()).unwrap();
    let mut out = Vec::with_capacity(n / 5 + 1);
    bencher.bench_local(|| {
        out.clear();
        d.process(&x, &mut out);
        d.finish(&mut out);
        out.len()
    });
}

#[divan::bench(sample_count = 10)]
fn decimator_design() -> usize {
    Decimator::new(&DecimatorConfig::default())
        .unwrap()
        .taps()
        .len()
}

fn msk_pair() -> (Vec<Complex64>, Vec<Complex64>) {
    let w = MskLfm::new(MskLfmParams::default()).unwrap();
    let tx = w.generate(&BitSource::Prbs { seed: 1 }, 1).unwrap().samples;
    let mut rx = vec![Complex64::new(0.0, 0.0); tx.len()];
    rx[300..].copy_from_slice(&tx[..tx.len() - 300]);
    SplitMix64::new(2).add_noise(&mut rx, 1.0);
    (tx, rx)
}

#[divan::bench(sample_count = 30)]
fn xcorr_160k_all_lags(bencher: Bencher) {
    let (tx, rx) = msk_pair();
    let mut c = CrossCorrelator::full(&tx, rx.len()).unwrap();
    let mut out = vec![Complex64::new(0.0, 0.0); c.output_len()];
    bencher.bench_local(|| c.correlate_into(&rx, &mut out).unwrap());
}

#[divan::bench(sample_count = 30)]
fn xcorr_160k_lags_0_to_2047(bencher: Bencher) {
    let (tx, rx) = msk_pair();
    let mut c = CrossCorrelator::new(&tx, rx.len(), 0..=2047).unwrap();
    let mut out = vec![Complex64::new(0.0, 0.0); c.output_len()];
    bencher.bench_local(|| c.correlate_into(&rx, &mut out).unwrap());
}

#[divan::bench(sample_count = 30)]
fn xcorr_160k_nonneg_lags(bencher: Bencher) {
    let (tx, rx) = msk_pair();
    let mut c = CrossCorrelator::new(&tx, rx.len(), 0..=rx.len() as isize - 1).unwrap();
    let mut out = vec![Complex64::new(0.0, 0.0); c.output_len()];
    bencher.bench_local(|| c.correlate_into(&rx, &mut out).unwrap());
}

/// One forward FFT at candidate correlation lengths (for choosing `fast_fft_len`'s factors).
#[divan::bench(args = [320_000, 322_560, 327_680, 331_776, 345_600, 393_216, 524_288], sample_count = 20)]
fn fft_len_candidates(bencher: Bencher, n: usize) {
    let mut planner = rustfft::FftPlanner::new();
    let fft = planner.plan_fft_forward(n);
    let mut buf = noise(n);
    let mut scratch = vec![Complex64::new(0.0, 0.0); fft.get_inplace_scratch_len()];
    bencher.bench_local(|| fft.process_with_scratch(&mut buf, &mut scratch));
}
