//! The five DSP kernels `radbench bench` and `benches/dsp.rs` time, on thesis-sized inputs, and
//! their inputs (seeded, so `benches/compare_numpy.py` can time numpy/scipy on the same data).
//!
//! | kernel | input | work |
//! |---|---|---|
//! | `decimate_800k` | 800 000 samples at 80 GSa/s (one MSK-LFM pulse echo + noise) | decimate by 5 |
//! | `decimate_1280k` | 1 280 000 samples (one OFDM frame echo + noise) | decimate by 5 |
//! | `xcorr_160k` | 160 000 samples at 16 GSa/s | FFT correlation, lags 0..4095, tx spectrum cached |
//! | `ofdm_rx_100sym` | 256 000 samples (100 symbols) | CP removal, FFT, I_div, 1280-point profile |
//! | `music_m64` | one 128-subcarrier I_div column | covariance (M = 64, FB), eigen, 1280-point grid |
//!
//! Plans, filters and buffers are built once outside the timed call, as a measurement loop would.

use super::scene::{EchoSynth, Target, BENCH_CARRIER_HZ};
use super::SimError;
use crate::dsp::CrossCorrelator;
use crate::dsp::{Decimator, DecimatorConfig};
use crate::dsp::{IDiv, OfdmRadar, OfdmRadarConfig, RangeProfile};
use crate::dsp::{Music, MusicConfig, MusicSpectrum};
use crate::rng::SplitMix64;
use crate::waveform::BitSource;
use crate::waveform::{MskLfm, MskLfmParams};
use crate::waveform::{Ofdm, OfdmParams};
use num_complex::Complex64;
use serde::Serialize;
use std::time::Instant;

/// Kernel names, in report order.
pub(crate) const KERNEL_NAMES: [&str; 5] = [
    "decimate_800k",
    "decimate_1280k",
    "xcorr_160k",
    "ofdm_rx_100sym",
    "music_m64",
];

/// Lags computed by `xcorr_160k` (0 .. 4095: ranges up to 38 m at 16 GSa/s).
pub const XCORR_LAGS: usize = 4096;

/// The seeded inputs of every kernel.
pub struct KernelInputs {
    pub capture_800k: Vec<Complex64>,
    pub capture_1280k: Vec<Complex64>,
    pub msk_tx: Vec<Complex64>,
    pub msk_rx: Vec<Complex64>,
    pub ofdm_tx_symbols: Vec<Complex64>,
    pub ofdm_rx: Vec<Complex64>,
    pub music_column: Vec<Complex64>,
}

impl KernelInputs {
    /// Targets at 1.0 and 1.06 m, 10 dB per-sample SNR, seed `seed`.
    pub fn generate(seed: u64) -> Result<Self, SimError> {
        let targets = [Target::at(1.0), Target::at(1.06)];
        let mut rng = SplitMix64::new(seed ^ 0xBE4C_0000);
        let noisy = |mut x: Vec<Complex64>, rng: &mut SplitMix64| {
            rng.add_noise(&mut x, 0.1);
            x
        };
        let msk = MskLfm::new(MskLfmParams::default())?;
        let msk_tx = msk.generate(&BitSource::Prbs { seed }, 1)?.samples;
        let ofdm = Ofdm::new(OfdmParams {
            preamble_symbols: 0,
            ..OfdmParams::default()
        })?;
        let ofdm_sig = ofdm.generate(&BitSource::Prbs { seed }, 1)?;
        let fs = msk.sample_rate_hz();
        let echo = |tx: &[Complex64], up: usize| -> Result<Vec<Complex64>, SimError> {
            Ok(EchoSynth::new(tx, fs, tx.len(), up)?.render(&targets, BENCH_CARRIER_HZ))
        };
        let capture_800k = noisy(echo(&msk_tx, 5)?, &mut rng);
        let capture_1280k = noisy(echo(&ofdm_sig.samples, 5)?, &mut rng);
        let msk_rx = noisy(echo(&msk_tx, 1)?, &mut rng);
        let ofdm_rx = noisy(echo(&ofdm_sig.samples, 1)?, &mut rng);
        // The MUSIC column: I_div of the first symbol of the OFDM echo.
        let mut radar = OfdmRadar::new(OfdmRadarConfig::default())?;
        let mut idiv = IDiv::new();
        let n = ofdm.subcarriers();
        let symbol_len = ofdm.symbol_len();
        radar.divide(
            &ofdm_rx[..symbol_len],
            0,
            &ofdm_sig.symbols.as_slice()[..n],
            &mut idiv,
        )?;
        Ok(Self {
            capture_800k,
            capture_1280k,
            msk_tx,
            msk_rx,
            ofdm_tx_symbols: ofdm_sig.symbols.as_slice().to_vec(),
            ofdm_rx,
            music_column: idiv.as_slice().to_vec(),
        })
    }
}

/// Prepared kernels: every plan and buffer allocated, ready to run repeatedly.
pub struct Kernels<'a> {
    inputs: &'a KernelInputs,
    decimator: Decimator,
    decimated: Vec<Complex64>,
    correlator: CrossCorrelator,
    correlation: Vec<Complex64>,
    radar: OfdmRadar,
    idiv: IDiv,
    profile: RangeProfile,
    music: Music,
    spectrum: MusicSpectrum,
}

impl<'a> Kernels<'a> {
    pub fn new(inputs: &'a KernelInputs) -> Result<Self, SimError> {
        let correlator = CrossCorrelator::new(
            &inputs.msk_tx,
            inputs.msk_rx.len(),
            0..=(XCORR_LAGS as isize - 1),
        )?;
        Ok(Self {
            inputs,
            decimator: Decimator::new(&DecimatorConfig::default())?,
            decimated: Vec::with_capacity(inputs.capture_1280k.len() / 5 + 1),
            correlation: vec![Complex64::new(0.0, 0.0); correlator.output_len()],
            correlator,
            radar: OfdmRadar::new(OfdmRadarConfig::default())?,
            idiv: IDiv::new(),
            profile: RangeProfile::new(),
            // The thesis' MUSIC (Table 4.2): 128 subcarriers, subarray 64, two targets.
            music: Music::new(MusicConfig::default())?,
            spectrum: MusicSpectrum::default(),
        })
    }

    /// FFT length of the correlator (compare_numpy.py uses the same).
    pub fn xcorr_fft_len(&self) -> usize {
        self.correlator.fft_len()
    }

    /// Runs kernel `name` once; returns a checksum so the work cannot be optimised away.
    pub fn run(&mut self, name: &str) -> Result<f64, SimError> {
        let x = self.inputs;
        Ok(match name {
            "decimate_800k" | "decimate_1280k" => {
                let input = if name == "decimate_800k" {
                    &x.capture_800k
                } else {
                    &x.capture_1280k
                };
                self.decimated.clear();
                self.decimator.process(input, &mut self.decimated);
                self.decimator.finish(&mut self.decimated);
                self.decimated[self.decimated.len() / 2].norm()
            }
            "xcorr_160k" => {
                self.correlator
                    .correlate_into(&x.msk_rx, &mut self.correlation)?;
                self.correlation[0].norm()
            }
            "ofdm_rx_100sym" => {
                self.radar.process(
                    &x.ofdm_rx,
                    0,
                    &x.ofdm_tx_symbols,
                    &mut self.idiv,
                    &mut self.profile,
                )?;
                self.profile.amplitude[0]
            }
            "music_m64" => {
                self.music.estimate(&x.music_column, &mut self.spectrum)?;
                self.spectrum.pseudo_spectrum[0]
            }
            other => {
                return Err(SimError::Param {
                    field: "kernel",
                    reason: format!(
                        "unknown kernel '{other}'; known: {}",
                        KERNEL_NAMES.join(", ")
                    ),
                })
            }
        })
    }
}

/// One kernel's timing (an element of `radbench bench --json`'s `"kernels"`).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct KernelTiming {
    pub name: &'static str,
    pub median_ms: f64,
    pub min_ms: f64,
    pub max_ms: f64,
    pub runs: usize,
    pub input_samples: usize,
    pub samples_per_s: f64,
    pub threads: usize,
}

/// Times every kernel on the calling thread: one warm-up run, then at least `min_runs` runs and
/// until `min_total_s` seconds have passed (at most 200 runs); reports the median.
pub fn time_all(
    inputs: &KernelInputs,
    min_runs: usize,
    min_total_s: f64,
) -> Result<Vec<KernelTiming>, SimError> {
    let mut kernels = Kernels::new(inputs)?;
    let mut sink = 0.0;
    let mut out = Vec::with_capacity(KERNEL_NAMES.len());
    for name in KERNEL_NAMES {
        sink += kernels.run(name)?;
        let mut times = Vec::new();
        let start_all = Instant::now();
        while times.len() < min_runs.max(1)
            || (start_all.elapsed().as_secs_f64() < min_total_s && times.len() < 200)
        {
            let t = Instant::now();
            sink += kernels.run(name)?;
            times.push(t.elapsed().as_secs_f64() * 1e3);
        }
        times.sort_by(f64::total_cmp);
        let median = if times.len() % 2 == 1 {
            times[times.len() / 2]
        } else {
            0.5 * (times[times.len() / 2 - 1] + times[times.len() / 2])
        };
        let input_samples = match name {
            "decimate_800k" => inputs.capture_800k.len(),
            "decimate_1280k" => inputs.capture_1280k.len(),
            "xcorr_160k" => inputs.msk_rx.len(),
            "ofdm_rx_100sym" => inputs.ofdm_rx.len(),
            _ => inputs.music_column.len(),
        };
        out.push(KernelTiming {
            name,
            median_ms: median,
            min_ms: times[0],
            max_ms: times[times.len() - 1],
            runs: times.len(),
            input_samples,
            samples_per_s: input_samples as f64 / (median * 1e-3),
            threads: 1,
        });
    }
    std::hint::black_box(sink);
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn inputs_have_the_documented_sizes_and_every_kernel_runs() {
        let inputs = KernelInputs::generate(1).unwrap();
        assert_eq!(inputs.capture_800k.len(), 800_000);
        assert_eq!(inputs.capture_1280k.len(), 1_280_000);
        assert_eq!(inputs.msk_rx.len(), 160_000);
        assert_eq!(inputs.ofdm_rx.len(), 256_000);
        assert_eq!(inputs.music_column.len(), 128);
        let mut k = Kernels::new(&inputs).unwrap();
        for name in KERNEL_NAMES {
            assert!(k.run(name).unwrap().is_finite(), "{name}");
        }
        assert!(k.run("nope").is_err());
    }
}
