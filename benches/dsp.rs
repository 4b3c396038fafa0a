//! DSP benchmarks (divan). Run: `cargo bench --bench dsp`.

fn main() {
    divan::main();
}
