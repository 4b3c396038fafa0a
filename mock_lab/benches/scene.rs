//! Scene synthesis speed. Run: `cargo bench -p mock_lab --bench scene`.
//! Target (issue 5): one 1 280 000-sample capture well under 100 ms.

use mock_lab::scene::{
    AwgPlayback, CaptureSetup, ChainPreset, FrontEnds, Scene, Synthesizer, Target,
};

fn main() {
    divan::main();
}

/// An OFDM-frame-sized segment (256 000 samples at 16 GSa/s) of pseudo-random codes.
fn segment() -> (Vec<i8>, Vec<i8>) {
    let mut x: u32 = 12345;
    let mut next = || {
        x = x.wrapping_mul(1_103_515_245).wrapping_add(12_345);
        (x >> 24) as i8
    };
    let i = (0..256_000).map(|_| next()).collect();
    let q = (0..256_000).map(|_| next()).collect();
    (i, q)
}

fn scene(targets: usize, velocity: f64) -> Scene {
    Scene {
        targets: (0..targets)
            .map(|k| Target {
                range_m: 1.0 + 0.3 * k as f64,
                amplitude: 0.5,
                velocity_mps: velocity,
            })
            .collect(),
        ..Scene::default()
    }
}

/// The AWG playing `i` and `q` at 16 GSa/s.
fn playing<'a>(i: &'a [i8], q: &'a [i8]) -> AwgPlayback<'a> {
    AwgPlayback {
        i,
        q,
        sample_rate: 16e9,
        amplitude_vpp: [0.5, 0.5],
        marker_index: 0,
        playing: true,
        marker_out: true,
    }
}

/// 1 280 000 points at 80 GSa/s.
const SETUP: CaptureSetup = CaptureSetup {
    sample_rate: 80e9,
    points: 1_280_000,
    trigger_offset_s: 0.0,
    volts_per_div: [0.05, 0.05],
    offset_v: [0.0, 0.0],
};

#[divan::bench(args = [1, 4])]
fn capture_1280k(bencher: divan::Bencher, targets: usize) {
    let (i, q) = segment();
    let awg = playing(&i, &q);
    let sc = scene(targets, 0.0);
    let mut synth = Synthesizer::new(1);
    bencher.bench_local(|| synth.capture(&sc, &awg, FrontEnds::ALL_ON, &SETUP).unwrap());
}

/// The same capture through the `thesis-lab` chain (issue 21's target: within 1.5x of the ideal
/// chain's time); and with 2 kHz of shared-LO phase noise on top.
#[divan::bench(args = [1, 4])]
fn capture_1280k_thesis_lab(bencher: divan::Bencher, targets: usize) {
    chain_capture(bencher, targets, 0.0);
}

#[divan::bench(args = [1, 4])]
fn capture_1280k_thesis_lab_phase_noise(bencher: divan::Bencher, targets: usize) {
    chain_capture(bencher, targets, 2000.0);
}

fn chain_capture(bencher: divan::Bencher, targets: usize, linewidth: f64) {
    let (i, q) = segment();
    let awg = playing(&i, &q);
    let mut sc = scene(targets, 0.0);
    sc.chain.preset = ChainPreset::ThesisLab;
    sc.impairments.phase_noise_linewidth_hz = linewidth;
    let mut synth = Synthesizer::new(1);
    bencher.bench_local(|| synth.capture(&sc, &awg, FrontEnds::ALL_ON, &SETUP).unwrap());
}
