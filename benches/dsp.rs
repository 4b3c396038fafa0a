//! DSP benchmarks (divan): the five kernels of `radbench bench`, on the same seeded inputs
//! (`radbench::simulate::kernels`). Run: `cargo bench --bench dsp` (a few seconds per kernel).

use radbench::simulate::{KernelInputs, Kernels};
use std::sync::OnceLock;

fn main() {
    divan::main();
}

fn inputs() -> &'static KernelInputs {
    static INPUTS: OnceLock<KernelInputs> = OnceLock::new();
    INPUTS.get_or_init(|| KernelInputs::generate(1).expect("kernel inputs"))
}

fn bench_kernel(bencher: divan::Bencher, name: &str) {
    let mut kernels = Kernels::new(inputs()).expect("kernels");
    kernels.run(name).expect("warm-up");
    bencher.bench_local(|| kernels.run(name).expect("kernel runs"));
}

#[divan::bench(sample_count = 20)]
fn decimate_800k(bencher: divan::Bencher) {
    bench_kernel(bencher, "decimate_800k");
}

#[divan::bench(sample_count = 20)]
fn decimate_1280k(bencher: divan::Bencher) {
    bench_kernel(bencher, "decimate_1280k");
}

#[divan::bench(sample_count = 20)]
fn xcorr_160k(bencher: divan::Bencher) {
    bench_kernel(bencher, "xcorr_160k");
}

#[divan::bench(sample_count = 20)]
fn ofdm_rx_100sym(bencher: divan::Bencher) {
    bench_kernel(bencher, "ofdm_rx_100sym");
}

#[divan::bench(sample_count = 50)]
fn music_m64(bencher: divan::Bencher) {
    bench_kernel(bencher, "music_m64");
}
