//! MSK-LFM: generator and communication receiver (thesis 2.2, 3.1).
//!
//! One pulse of `Ns` samples at `fs` carries `n_bits` bits as MSK on top of a linear chirp centred
//! on `f0` (complex baseband, unit amplitude; `f0 = 0` by default, `B/2` for the thesis' sweep from
//! its carrier upwards, eq. 2.4):
//!
//! ```text
//! s(t) = m(t) exp(j pi (B/Tp) (t - Tp/2)^2 + j 2 pi f0 (t - Tp/2)),
//! m(t) = a_I(t) cos(pi t / 2T) - j a_Q(t) sin(pi t / 2T)
//! ```
//!
//! with `T = Tp / n_bits`, `t = n / fs` for sample `n = 0..Ns`, `a_I` the even bits and `a_Q` the odd
//! bits mapped `b -> 1 - 2b`. I symbol `k` spans `[(2k-1)T, (2k+1)T)` and Q symbol `k` spans
//! `[2kT, (2k+2)T)`; symbol indices are taken modulo `n_bits / 2`, so the leading half of I symbol 0
//! (`t < 0`) wraps to the last `T` of the pulse and one pulse holds exactly `n_bits` bits. Every
//! symbol edge falls on a zero of its half-sine: the envelope is exactly 1 and the phase continuous
//! within the pulse, and also across the boundary when the pulse repeats (the AWG loops its
//! segment). Back-to-back pulses carrying *different* bits jump in phase at the boundary when their
//! first I bits differ, because the wrapped half of I symbol 0 ends each pulse at a peak of its
//! half-sine.
//!
//! `Ns / n_bits` need not be an integer (the thesis' 4096 bits in 160 000 samples gives 39.0625
//! samples per bit): the half-sines are evaluated at the sample instants, which keeps the envelope
//! and phase properties exact. A pulse needs at least 2 samples per bit.
//!
//! The receiver is coherent and aligned: it expects the pulse to start at sample 0 of its input with
//! no carrier phase offset. It dechirps and integrates each I and Q symbol against its half-sine
//! over 2T (integrate-and-dump matched filter), the wrapped I symbol 0 collecting both its pieces.

use num_complex::Complex64;

use super::bits::{frame_bits, BitSource};
use super::ParamError;

/// How long one pulse is.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum PulseLength {
    /// Seconds; must be a whole number of samples at the sample rate.
    Seconds(f64),
    /// Samples at the sample rate.
    Samples(usize),
}

/// MSK-LFM parameters. [`Default`] is the thesis' setting (Table 4.1).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MskLfmParams {
    /// Sample rate in Sa/s (default 16e9).
    pub sample_rate_hz: f64,
    /// Chirp bandwidth in Hz, swept from `centre_hz - B/2` to `centre_hz + B/2` (default 1e9).
    pub bandwidth_hz: f64,
    /// Centre of the sweep in complex baseband, Hz (default 0). The sweep must stay within the
    /// sample rate's Nyquist band: `|centre_hz| + B/2 <= fs/2`.
    pub centre_hz: f64,
    /// Pulse length (default 10 us = 160 000 samples at 16 GSa/s).
    pub pulse: PulseLength,
    /// Bits per pulse, even (default 128).
    pub bits_per_pulse: usize,
}

impl Default for MskLfmParams {
    fn default() -> Self {
        Self {
            sample_rate_hz: 16e9,
            bandwidth_hz: 1e9,
            centre_hz: 0.0,
            pulse: PulseLength::Seconds(10e-6),
            bits_per_pulse: 128,
        }
    }
}

impl MskLfmParams {
    /// Pulse length in samples, checked to be a whole number of at least 2.
    ///
    /// # Errors
    ///
    /// [`ParamError`] when the sample rate is not positive and finite, a duration is not positive and
    /// finite or not a whole number of samples, or the pulse is shorter than 2 samples.
    pub fn samples_per_pulse(&self) -> Result<usize, ParamError> {
        let fs = self.sample_rate_hz;
        if !(fs.is_finite() && fs > 0.0) {
            return Err(ParamError::out_of_range(
                "sample_rate_hz",
                fs,
                "must be a positive, finite sample rate in Sa/s",
            ));
        }
        let n = match self.pulse {
            PulseLength::Samples(n) => n,
            PulseLength::Seconds(tp) => {
                if !(tp.is_finite() && tp > 0.0) {
                    return Err(ParamError::out_of_range(
                        "pulse length",
                        format!("{tp} s"),
                        "must be a positive, finite duration",
                    ));
                }
                let exact = tp * fs;
                let rounded = exact.round();
                if (exact - rounded).abs() > 1e-6 * rounded.max(1.0) || rounded > 1e12 {
                    return Err(ParamError::out_of_range(
                        "pulse length",
                        format!("{tp} s ({exact} samples at {fs} Sa/s)"),
                        &format!(
                            "must be a whole number of samples; the nearest are {} s or {} s",
                            exact.floor() / fs,
                            exact.ceil() / fs
                        ),
                    ));
                }
                rounded as usize
            }
        };
        if n < 2 {
            return Err(ParamError::out_of_range(
                "pulse length",
                format!("{n} samples"),
                "must be at least 2 samples",
            ));
        }
        Ok(n)
    }
}

/// A validated MSK-LFM waveform with its per-sample tables (chirp, half-sines, symbol indices)
/// computed once, so generating and demodulating pulses costs a multiply per sample.
#[derive(Debug, Clone)]
pub struct MskLfm {
    params: MskLfmParams,
    n_samples: usize,
    n_bits: usize,
    chirp: Vec<Complex64>,
    cos_weight: Vec<f64>,
    sin_weight: Vec<f64>,
    i_index: Vec<u32>,
    q_index: Vec<u32>,
    /// Matched-filter energy per bit (sum of the squared half-sine over its symbol), bit order.
    symbol_energy: Vec<f64>,
}

/// A generated MSK-LFM transmission: pulses back to back.
#[derive(Debug, Clone)]
pub struct MskLfmSignal {
    /// `pulses * samples_per_pulse` complex baseband samples of unit amplitude.
    pub samples: Vec<Complex64>,
    /// The transmitted bits, `bits_per_pulse` per pulse, in transmission order.
    pub bits: Vec<u8>,
    /// Number of pulses.
    pub pulses: usize,
    /// Payload length in bytes when the bits came from a payload.
    pub payload_len: Option<usize>,
}

/// Pulses of at least this many samples build their tables on several threads.
const PARALLEL_TABLES_FROM: usize = 32_768;

/// Most threads building one pulse's tables.
const MAX_TABLE_THREADS: usize = 4;

/// What a sample's table entries are computed from (see [`MskLfm::new`]).
#[derive(Clone, Copy)]
struct Tables {
    spb: f64,
    half_symbols: u32,
    centre: f64,
    chirp_rate: f64,
    shift: f64,
}

impl Tables {
    /// The entries of samples `start..start + chirp.len()`.
    fn fill(
        self,
        start: usize,
        chirp: &mut [Complex64],
        cos_weight: &mut [f64],
        sin_weight: &mut [f64],
        i_index: &mut [u32],
        q_index: &mut [u32],
    ) {
        let Tables {
            spb,
            half_symbols,
            centre,
            chirp_rate,
            shift,
        } = self;
        for (k, c) in chirp.iter_mut().enumerate() {
            let n = start + k;
            let x = n as f64 - centre;
            let (s, co) = (chirp_rate * x * x + shift * x).sin_cos();
            *c = Complex64::new(co, s);
            let (sw, cw) = (std::f64::consts::FRAC_PI_2 * n as f64 / spb).sin_cos();
            cos_weight[k] = cw;
            sin_weight[k] = sw;
            i_index[k] = ((n as f64 + spb) / (2.0 * spb)).floor() as u32 % half_symbols;
            q_index[k] = ((n as f64 / (2.0 * spb)).floor() as u32).min(half_symbols - 1);
        }
    }
}

impl MskLfm {
    /// Validates `params` and builds the tables.
    ///
    /// Errors name the parameter: sample rate not positive, bandwidth not in (0, fs], a pulse that is
    /// not a whole number of samples, a bit count that is zero, odd, or above half the pulse's samples.
    ///
    /// # Errors
    ///
    /// [`ParamError`] for each of the cases above, and when the sweep leaves the Nyquist band.
    pub fn new(params: MskLfmParams) -> Result<Self, ParamError> {
        let n_samples = params.samples_per_pulse()?;
        let fs = params.sample_rate_hz;
        let b = params.bandwidth_hz;
        if !(b.is_finite() && b > 0.0 && b <= fs) {
            return Err(ParamError::out_of_range(
                "bandwidth_hz",
                b,
                &format!("must be above 0 and at most the sample rate ({fs} Sa/s) of the complex baseband"),
            ));
        }
        let f0 = params.centre_hz;
        if !(f0.is_finite() && f0.abs() + b / 2.0 <= fs / 2.0) {
            return Err(ParamError::out_of_range(
                "centre_hz",
                f0,
                &format!(
                    "the sweep ({} .. {} Hz) must stay within the Nyquist band of +-{} Hz",
                    f0 - b / 2.0,
                    f0 + b / 2.0,
                    fs / 2.0
                ),
            ));
        }
        let n_bits = params.bits_per_pulse;
        if n_bits == 0 || n_bits % 2 != 0 {
            return Err(ParamError::out_of_range(
                "bits_per_pulse",
                n_bits,
                "must be even and at least 2 (I takes the even bits, Q the odd bits)",
            ));
        }
        if n_bits > n_samples / 2 {
            return Err(ParamError::out_of_range(
                "bits_per_pulse",
                n_bits,
                &format!(
                    "must be at most half the samples per pulse ({}), i.e. at least 2 samples per bit",
                    n_samples / 2
                ),
            ));
        }
        let spb = n_samples as f64 / n_bits as f64;
        let half_symbols = (n_bits / 2) as u32;
        let centre = n_samples as f64 / 2.0;
        let chirp_rate = std::f64::consts::PI * (b / fs) / n_samples as f64;
        let shift = 2.0 * std::f64::consts::PI * f0 / fs;
        let table = Tables {
            spb,
            half_symbols,
            centre,
            chirp_rate,
            shift,
        };
        let mut chirp = vec![Complex64::new(0.0, 0.0); n_samples];
        let mut cos_weight = vec![0.0; n_samples];
        let mut sin_weight = vec![0.0; n_samples];
        let mut i_index = vec![0u32; n_samples];
        let mut q_index = vec![0u32; n_samples];
        // Each sample's entries depend on its index alone: long pulses are split between threads
        // (the same expression per sample, so the same values as on one thread).
        let threads = if n_samples >= PARALLEL_TABLES_FROM {
            std::thread::available_parallelism().map_or(1, |n| n.get().min(MAX_TABLE_THREADS))
        } else {
            1
        };
        let chunk = n_samples.div_ceil(threads);
        std::thread::scope(|scope| {
            let parts = chirp
                .chunks_mut(chunk)
                .zip(cos_weight.chunks_mut(chunk))
                .zip(sin_weight.chunks_mut(chunk))
                .zip(i_index.chunks_mut(chunk))
                .zip(q_index.chunks_mut(chunk))
                .enumerate();
            let mut here = None;
            for (k, ((((c, cw), sw), ii), qi)) in parts {
                let start = k * chunk;
                if k == 0 {
                    here = Some((c, cw, sw, ii, qi));
                } else {
                    scope.spawn(move || table.fill(start, c, cw, sw, ii, qi));
                }
            }
            if let Some((c, cw, sw, ii, qi)) = here {
                table.fill(0, c, cw, sw, ii, qi);
            }
        });
        let mut symbol_energy = vec![0.0; n_bits];
        for n in 0..n_samples {
            symbol_energy[2 * i_index[n] as usize] += cos_weight[n] * cos_weight[n];
            symbol_energy[2 * q_index[n] as usize + 1] += sin_weight[n] * sin_weight[n];
        }
        Ok(Self {
            params,
            n_samples,
            n_bits,
            chirp,
            cos_weight,
            sin_weight,
            i_index,
            q_index,
            symbol_energy,
        })
    }

    pub fn params(&self) -> &MskLfmParams {
        &self.params
    }

    pub fn sample_rate_hz(&self) -> f64 {
        self.params.sample_rate_hz
    }

    pub fn bandwidth_hz(&self) -> f64 {
        self.params.bandwidth_hz
    }

    pub fn samples_per_pulse(&self) -> usize {
        self.n_samples
    }

    pub fn bits_per_pulse(&self) -> usize {
        self.n_bits
    }

    /// Samples per bit `T fs` (may be fractional). Each I or Q symbol lasts twice this.
    pub fn samples_per_bit(&self) -> f64 {
        self.n_samples as f64 / self.n_bits as f64
    }

    /// Centre of the sweep, Hz (0: centred on the carrier).
    pub fn centre_hz(&self) -> f64 {
        self.params.centre_hz
    }

    /// The bare chirp `exp(j pi (B/Tp)(t - Tp/2)^2 + j 2 pi f0 (t - Tp/2))` of one pulse (no
    /// modulation).
    pub fn chirp(&self) -> &[Complex64] {
        &self.chirp
    }

    /// Writes one pulse carrying `bits` (exactly `bits_per_pulse` of them, values 0/1) into `out`
    /// (exactly `samples_per_pulse` long).
    pub(crate) fn pulse_into(&self, bits: &[u8], out: &mut [Complex64]) -> Result<(), ParamError> {
        if bits.len() != self.n_bits {
            return Err(ParamError::out_of_range(
                "bits for one pulse",
                bits.len(),
                &format!("must be exactly bits_per_pulse = {}", self.n_bits),
            ));
        }
        if out.len() != self.n_samples {
            return Err(ParamError::out_of_range(
                "pulse output length",
                out.len(),
                &format!("must be exactly samples_per_pulse = {}", self.n_samples),
            ));
        }
        let level = |b: u8| 1.0 - 2.0 * f64::from(b & 1);
        for (n, o) in out.iter_mut().enumerate() {
            let a_i = level(bits[2 * self.i_index[n] as usize]);
            let a_q = level(bits[2 * self.q_index[n] as usize + 1]);
            let m = Complex64::new(a_i * self.cos_weight[n], -a_q * self.sin_weight[n]);
            *o = m * self.chirp[n];
        }
        Ok(())
    }

    /// One pulse carrying `bits` (exactly `bits_per_pulse` bits).
    ///
    /// # Errors
    ///
    /// [`ParamError`] when `bits` is not exactly `bits_per_pulse` long.
    pub fn pulse(&self, bits: &[u8]) -> Result<Vec<Complex64>, ParamError> {
        let mut out = vec![Complex64::new(0.0, 0.0); self.n_samples];
        self.pulse_into(bits, &mut out)?;
        Ok(out)
    }

    /// Generates at least `min_pulses` pulses from `source` (a payload takes as many as it needs;
    /// framing in `super::bits`).
    ///
    /// # Errors
    ///
    /// [`ParamError`] when a payload is longer than its 32-bit length header can describe.
    pub fn generate(
        &self,
        source: &BitSource,
        min_pulses: usize,
    ) -> Result<MskLfmSignal, ParamError> {
        let framed = frame_bits(source, self.n_bits, min_pulses)?;
        let mut samples = vec![Complex64::new(0.0, 0.0); framed.units * self.n_samples];
        for (bits, out) in framed
            .bits
            .chunks_exact(self.n_bits)
            .zip(samples.chunks_exact_mut(self.n_samples))
        {
            self.pulse_into(bits, out)?;
        }
        Ok(MskLfmSignal {
            samples,
            bits: framed.bits,
            pulses: framed.units,
            payload_len: framed.payload_len,
        })
    }

    /// Matched-filter outputs of one aligned pulse, one per bit in transmission order, normalised so
    /// a noise-free unit-amplitude pulse gives exactly `1 - 2 b` (more or less for other amplitudes).
    ///
    /// `pulse` must be `samples_per_pulse` long and `soft` `bits_per_pulse` long.
    pub(crate) fn soft_bits_into(
        &self,
        pulse: &[Complex64],
        soft: &mut [f64],
    ) -> Result<(), ParamError> {
        if pulse.len() != self.n_samples {
            return Err(ParamError::out_of_range(
                "received pulse length",
                pulse.len(),
                &format!("must be exactly samples_per_pulse = {}", self.n_samples),
            ));
        }
        if soft.len() != self.n_bits {
            return Err(ParamError::out_of_range(
                "soft output length",
                soft.len(),
                &format!("must be exactly bits_per_pulse = {}", self.n_bits),
            ));
        }
        soft.fill(0.0);
        // soft[2k] accumulates I symbol k, soft[2k+1] Q symbol k.
        for (n, &z) in pulse.iter().enumerate() {
            let d = z * self.chirp[n].conj();
            soft[2 * self.i_index[n] as usize] += d.re * self.cos_weight[n];
            soft[2 * self.q_index[n] as usize + 1] -= d.im * self.sin_weight[n];
        }
        for (v, e) in soft.iter_mut().zip(&self.symbol_energy) {
            *v /= e;
        }
        Ok(())
    }

    /// The matched-filter outputs of every symbol of a capture of whole, aligned pulses, in bit
    /// order (I symbol k at `2k`, Q symbol k at `2k + 1` of each pulse): `+-1` times the echo's
    /// amplitude plus noise.
    pub(crate) fn soft_symbols(&self, capture: &[Complex64]) -> Result<Vec<f64>, ParamError> {
        if capture.is_empty() || capture.len() % self.n_samples != 0 {
            return Err(ParamError::out_of_range(
                "capture length",
                capture.len(),
                &format!(
                    "must be a non-zero multiple of samples_per_pulse = {}",
                    self.n_samples
                ),
            ));
        }
        let mut soft = vec![0.0; self.n_bits];
        let mut all = Vec::with_capacity(capture.len() / self.n_samples * self.n_bits);
        for pulse in capture.chunks_exact(self.n_samples) {
            self.soft_bits_into(pulse, &mut soft)?;
            all.extend_from_slice(&soft);
        }
        Ok(all)
    }

    /// The first `n` samples of an aligned pulse with the chirp taken off, every `stride`-th
    /// one: the MSK signal alone, whose phase moves by +-90 degrees per bit.
    pub(crate) fn dechirped(&self, pulse: &[Complex64], n: usize, stride: usize) -> Vec<Complex64> {
        pulse
            .iter()
            .zip(&self.chirp)
            .take(n)
            .step_by(stride.max(1))
            .map(|(z, c)| z * c.conj())
            .collect()
    }

    /// Hard decisions for a capture of whole, aligned pulses (`len` a multiple of
    /// `samples_per_pulse`): bit 1 where the matched-filter output is negative.
    ///
    /// # Errors
    ///
    /// [`ParamError`] when `capture` is empty or not a whole number of pulses.
    pub fn demodulate(&self, capture: &[Complex64]) -> Result<Vec<u8>, ParamError> {
        if capture.is_empty() || capture.len() % self.n_samples != 0 {
            return Err(ParamError::out_of_range(
                "capture length",
                capture.len(),
                &format!(
                    "must be a non-zero multiple of samples_per_pulse = {}",
                    self.n_samples
                ),
            ));
        }
        let pulses = capture.len() / self.n_samples;
        let mut soft = vec![0.0; self.n_bits];
        let mut bits = Vec::with_capacity(pulses * self.n_bits);
        for pulse in capture.chunks_exact(self.n_samples) {
            self.soft_bits_into(pulse, &mut soft)?;
            bits.extend(soft.iter().map(|&v| u8::from(v < 0.0)));
        }
        Ok(bits)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The tables built on several threads hold the values one thread computes, bit for bit.
    #[test]
    fn tables_built_on_threads_equal_one_threads() {
        let params = MskLfmParams {
            pulse: PulseLength::Samples(PARALLEL_TABLES_FROM * 3 + 17),
            centre_hz: 0.2e9,
            ..MskLfmParams::default()
        };
        let w = MskLfm::new(params).unwrap();
        let n = w.n_samples;
        let spb = n as f64 / w.n_bits as f64;
        let table = Tables {
            spb,
            half_symbols: (w.n_bits / 2) as u32,
            centre: n as f64 / 2.0,
            chirp_rate: std::f64::consts::PI * (params.bandwidth_hz / params.sample_rate_hz)
                / n as f64,
            shift: 2.0 * std::f64::consts::PI * params.centre_hz / params.sample_rate_hz,
        };
        let mut chirp = vec![Complex64::new(0.0, 0.0); n];
        let (mut cw, mut sw) = (vec![0.0; n], vec![0.0; n]);
        let (mut ii, mut qi) = (vec![0u32; n], vec![0u32; n]);
        table.fill(0, &mut chirp, &mut cw, &mut sw, &mut ii, &mut qi);
        let bits = |v: &[f64]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
        let cbits = |v: &[Complex64]| {
            v.iter()
                .map(|z| (z.re.to_bits(), z.im.to_bits()))
                .collect::<Vec<_>>()
        };
        assert_eq!(cbits(&w.chirp), cbits(&chirp));
        assert_eq!(bits(&w.cos_weight), bits(&cw));
        assert_eq!(bits(&w.sin_weight), bits(&sw));
        assert_eq!(w.i_index, ii);
        assert_eq!(w.q_index, qi);
    }

    /// Energy of one pulse of `w` per band `[lo, hi)` Hz, as fractions of the total.
    fn energy_in(w: &MskLfm, bands: &[(f64, f64)]) -> Vec<f64> {
        let bits: Vec<u8> = (0..w.bits_per_pulse())
            .map(|k| (k * 7 % 3 % 2) as u8)
            .collect();
        let mut x = w.pulse(&bits).unwrap();
        let n = x.len();
        rustfft::FftPlanner::new()
            .plan_fft_forward(n)
            .process(&mut x);
        let fs = w.sample_rate_hz();
        let total: f64 = x.iter().map(|v| v.norm_sqr()).sum();
        bands
            .iter()
            .map(|&(lo, hi)| {
                let e: f64 = (0..n)
                    .filter(|&k| {
                        let f = if k <= n / 2 {
                            k as f64
                        } else {
                            k as f64 - n as f64
                        } * fs
                            / n as f64;
                        (lo..hi).contains(&f)
                    })
                    .map(|k| x[k].norm_sqr())
                    .sum();
                e / total
            })
            .collect()
    }

    #[test]
    fn the_sweep_lies_where_its_band_says() {
        let with = |centre_hz| {
            MskLfm::new(MskLfmParams {
                centre_hz,
                pulse: PulseLength::Samples(16_000),
                bits_per_pulse: 32,
                ..Default::default()
            })
            .unwrap()
        };
        // The MSK data widens the chirp's spectrum by a few bit rates (3.2 MHz here) at most.
        let upper = energy_in(&with(0.5e9), &[(-0.01e9, 1.01e9), (-8e9, -0.01e9)]);
        assert!(upper[0] > 0.99 && upper[1] < 0.005, "{upper:?}");
        let centred = energy_in(&with(0.0), &[(-0.51e9, 0.51e9), (0.51e9, 8e9)]);
        assert!(centred[0] > 0.99 && centred[1] < 0.005, "{centred:?}");
        // Beyond the Nyquist band: refused by name.
        let e = MskLfm::new(MskLfmParams {
            centre_hz: 7.6e9,
            ..Default::default()
        })
        .unwrap_err();
        assert!(e.to_string().contains("centre_hz"), "{e}");
    }

    fn small() -> MskLfm {
        MskLfm::new(MskLfmParams {
            pulse: PulseLength::Samples(4096),
            bits_per_pulse: 64,
            ..Default::default()
        })
        .unwrap()
    }

    #[test]
    fn default_is_the_thesis_setting() {
        let w = MskLfm::new(MskLfmParams::default()).unwrap();
        assert_eq!(w.samples_per_pulse(), 160_000);
        assert_eq!(w.samples_per_bit(), 1250.0);
    }

    #[test]
    fn noise_free_round_trip() {
        let w = small();
        let sig = w.generate(&BitSource::Prbs { seed: 11 }, 3).unwrap();
        assert_eq!(sig.samples.len(), 3 * 4096);
        assert_eq!(w.demodulate(&sig.samples).unwrap(), sig.bits);
        let mut soft = vec![0.0; 64];
        w.soft_bits_into(&sig.samples[..4096], &mut soft).unwrap();
        for (s, b) in soft.iter().zip(&sig.bits) {
            assert!((s - (1.0 - 2.0 * f64::from(*b))).abs() < 1e-9);
        }
    }

    #[test]
    fn validation_names_the_parameter() {
        let bad = |p: MskLfmParams| MskLfm::new(p).unwrap_err().message;
        let d = MskLfmParams::default();
        assert!(bad(MskLfmParams {
            bandwidth_hz: 20e9,
            ..d
        })
        .contains("bandwidth_hz"));
        assert!(bad(MskLfmParams {
            bits_per_pulse: 127,
            ..d
        })
        .contains("bits_per_pulse"));
        assert!(bad(MskLfmParams {
            bits_per_pulse: 0,
            ..d
        })
        .contains("bits_per_pulse"));
        assert!(bad(MskLfmParams {
            bits_per_pulse: 100_000,
            ..d
        })
        .contains("bits_per_pulse"));
        let msg = bad(MskLfmParams {
            pulse: PulseLength::Seconds(10.00001e-6),
            ..d
        });
        assert!(msg.contains("whole number of samples"), "{msg}");
        assert!(bad(MskLfmParams {
            sample_rate_hz: f64::NAN,
            ..d
        })
        .contains("sample_rate_hz"));
        let w = small();
        assert!(w.pulse(&[0; 3]).is_err());
        assert!(w.demodulate(&[Complex64::new(0.0, 0.0); 100]).is_err());
    }
}
