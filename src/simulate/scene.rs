//! The scene: point targets and their echoes, synthesised exactly in the frequency domain.
//!
//! An echo of a target at range R (amplitude a, radial velocity v) is
//! `a * exp(-j 2 pi f_c tau) * exp(-j 2 pi f_D t) * s(t - tau)`, tau = 2 R / c0 (CONVENTIONS.md).
//! The delay is applied to the band-limited transmit signal as a phase ramp on its spectrum, so a
//! fractional delay is exact rather than interpolated; the same step can place the spectrum into a
//! longer FFT, which is ideal band-limited upsampling (16 -> 80 GSa/s for the lab capture path).
//!
//! The delay is circular over the synthesis window: callers either pad the window beyond the
//! longest delay (a pulse) or rely on the periodic frame (an OFDM frame whose cyclic prefix is longer
//! than the delay sees exactly what a continuously repeated frame would give).
//!
//! Doppler: a moving target adds `f_D = -2 v f_rf / c0` with the bench carrier f_rf = 80 GHz in every
//! phase convention (the convention only sets the constant echo phase; velocity is physics). Range
//! migration within one frame (v * 16 us, 0.16 mm at 10 m/s) is neglected.

use super::SimError;
use crate::dsp::C0;
use num_complex::Complex64;
use rustfft::{Fft, FftPlanner};
use std::f64::consts::PI;
use std::sync::Arc;

/// The bench's RF carrier (the Gotmic E-band front ends), Hz.
pub(crate) const BENCH_CARRIER_HZ: f64 = 80e9;

/// One point target. Velocity is radial, positive when the target moves away.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct Target {
    pub range_m: f64,
    pub amplitude: f64,
    pub velocity_mps: f64,
}

impl Target {
    pub fn at(range_m: f64) -> Self {
        Self {
            range_m,
            amplitude: 1.0,
            velocity_mps: 0.0,
        }
    }

    /// Round-trip delay in seconds.
    pub(crate) fn delay_s(&self) -> f64 {
        2.0 * self.range_m / C0
    }
}

/// The largest target range, amplitude and radial speed a simulation takes (as the mock lab's
/// scenes, ranges up to the processing's own limit).
const MAX_RANGE_M: f64 = 10_000.0;
const MAX_AMPLITUDE: f64 = 10.0;
const MAX_SPEED_MPS: f64 = 1000.0;

/// Parses `R[:AMP[:V]][,R[:AMP[:V]]...]`: range in metres, linear amplitude (default 1), radial
/// velocity in m/s (default 0, positive = receding). Example: `3,3.132:0.5` or `1.0:1:2.5`.
pub fn parse_targets(text: &str) -> Result<Vec<Target>, SimError> {
    let bad = |reason: String| SimError::Param {
        field: "--targets",
        reason,
    };
    let mut targets = Vec::new();
    for (i, item) in text.split(',').enumerate() {
        let item = item.trim();
        if item.is_empty() {
            return Err(bad(format!(
                "target {} is empty; expected R[:AMP[:V]] separated by commas, e.g. 3,3.132:0.5",
                i + 1
            )));
        }
        let parts: Vec<&str> = item.split(':').collect();
        if parts.len() > 3 {
            return Err(bad(format!(
                "target '{item}' has {} fields; expected R[:AMP[:V]] (range m, amplitude, velocity m/s)",
                parts.len()
            )));
        }
        let number = |s: &str, what: &str| -> Result<f64, SimError> {
            s.trim()
                .parse::<f64>()
                .ok()
                .filter(|v| v.is_finite())
                .ok_or_else(|| {
                    bad(format!(
                        "{what} '{s}' in target '{item}' is not a finite number"
                    ))
                })
        };
        let range_m = number(parts[0], "range")?;
        if !(0.0..=MAX_RANGE_M).contains(&range_m) {
            return Err(bad(format!(
                "range {range_m:?} m in target '{item}': allowed 0 ..= {MAX_RANGE_M} m"
            )));
        }
        let amplitude = match parts.get(1) {
            Some(s) => number(s, "amplitude")?,
            None => 1.0,
        };
        if !(amplitude > 0.0 && amplitude <= MAX_AMPLITUDE) {
            return Err(bad(format!(
                "amplitude {amplitude:?} in target '{item}': allowed above 0 up to {MAX_AMPLITUDE} \
                 (linear, 1 = reference)"
            )));
        }
        let velocity_mps = match parts.get(2) {
            Some(s) => number(s, "velocity")?,
            None => 0.0,
        };
        if velocity_mps.abs() > MAX_SPEED_MPS {
            return Err(bad(format!(
                "velocity {velocity_mps:?} m/s in target '{item}': allowed -{MAX_SPEED_MPS} ..= \
                 {MAX_SPEED_MPS} m/s (radial, positive = receding)"
            )));
        }
        targets.push(Target {
            range_m,
            amplitude,
            velocity_mps,
        });
    }
    Ok(targets)
}

/// Which carrier frequency sets the constant echo phase `exp(-j 2 pi f_c tau)`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "lowercase")]
#[derive(strum::VariantArray, strum::IntoStaticStr, strum::EnumMessage)]
#[strum(serialize_all = "lowercase")]
pub enum CarrierPhase {
    /// The bench's 80 GHz carrier: what a real measurement sees (default).
    #[strum(message = "The bench's 80 GHz carrier: what a real measurement sees")]
    Physical,
    /// f_c = 0: pure baseband, no carrier phase.
    Centred,
    /// f_c = B/2: the thesis' own model (its chirp sweeps 0..B); reproduces its two-target figures.
    #[strum(message = "f_c = B/2: the thesis' own model (its chirp sweeps 0..B)")]
    Thesis,
}

impl CarrierPhase {
    pub fn carrier_hz(self, bandwidth_hz: f64) -> f64 {
        match self {
            CarrierPhase::Physical => BENCH_CARRIER_HZ,
            CarrierPhase::Centred => 0.0,
            CarrierPhase::Thesis => bandwidth_hz / 2.0,
        }
    }
}

named_enum!(CarrierPhase, "carrier phase");

/// Echo synthesiser for one transmit signal: holds its spectrum and the FFT plans, so many scenes
/// (targets, trials) reuse one forward FFT.
pub(crate) struct EchoSynth {
    /// Transmit spectrum over the synthesis window (length `window`).
    spectrum: Vec<Complex64>,
    inverse: Arc<dyn Fft<f64>>,
    fs_hz: f64,
    upsample: usize,
}

impl EchoSynth {
    /// `tx` at `fs_hz`, zero-padded to `window` samples (>= tx.len()); echoes come out at
    /// `fs_hz * upsample` with `window * upsample` samples.
    pub(crate) fn new(
        tx: &[Complex64],
        fs_hz: f64,
        window: usize,
        upsample: usize,
    ) -> Result<Self, SimError> {
        if tx.is_empty() || window < tx.len() {
            return Err(SimError::Param {
                field: "window",
                reason: format!(
                    "synthesis window of {window} samples must hold the {} transmit samples",
                    tx.len()
                ),
            });
        }
        if upsample == 0 {
            return Err(SimError::Param {
                field: "--capture-rate",
                reason: "the capture rate must be a whole multiple (>= 1) of the waveform rate"
                    .into(),
            });
        }
        let mut planner = FftPlanner::new();
        let mut spectrum = vec![Complex64::new(0.0, 0.0); window];
        spectrum[..tx.len()].copy_from_slice(tx);
        planner.plan_fft_forward(window).process(&mut spectrum);
        Ok(Self {
            spectrum,
            inverse: planner.plan_fft_inverse(window * upsample),
            fs_hz,
            upsample,
        })
    }

    /// Output sample rate, Hz.
    pub(crate) fn output_rate_hz(&self) -> f64 {
        self.fs_hz * self.upsample as f64
    }

    /// Output length in samples.
    pub(crate) fn output_len(&self) -> usize {
        self.spectrum.len() * self.upsample
    }

    /// The sum of every target's echo (noise-free), at the output rate.
    pub(crate) fn render(&self, targets: &[Target], carrier_hz: f64) -> Vec<Complex64> {
        let mut out = vec![Complex64::new(0.0, 0.0); self.output_len()];
        let mut buf = vec![Complex64::new(0.0, 0.0); self.output_len()];
        // Static targets share one inverse FFT; each moving target needs its own (its Doppler
        // rotation is applied in the time domain).
        let (moving, still): (Vec<&Target>, Vec<&Target>) =
            targets.iter().partition(|t| t.velocity_mps != 0.0);
        if !still.is_empty() {
            buf.fill(Complex64::new(0.0, 0.0));
            for t in &still {
                self.accumulate(&mut buf, t, carrier_hz);
            }
            self.inverse.process(&mut buf);
            for (o, b) in out.iter_mut().zip(&buf) {
                *o += b;
            }
        }
        let dt = 1.0 / self.output_rate_hz();
        for t in moving {
            buf.fill(Complex64::new(0.0, 0.0));
            self.accumulate(&mut buf, t, carrier_hz);
            self.inverse.process(&mut buf);
            let doppler_hz = -2.0 * t.velocity_mps * BENCH_CARRIER_HZ / C0;
            let step = Complex64::from_polar(1.0, 2.0 * PI * doppler_hz * dt);
            // Re-anchor the rotation every 4096 samples so rounding cannot accumulate.
            for (block, (o_chunk, b_chunk)) in
                out.chunks_mut(4096).zip(buf.chunks(4096)).enumerate()
            {
                let t0 = (block * 4096) as f64 * dt;
                let mut rot = Complex64::from_polar(1.0, 2.0 * PI * doppler_hz * t0);
                for (o, b) in o_chunk.iter_mut().zip(b_chunk) {
                    *o += b * rot;
                    rot *= step;
                }
            }
        }
        out
    }

    /// Adds one target's delayed spectrum into `out` (output-length spectrum), scaled so the inverse
    /// FFT gives the echo's samples directly.
    fn accumulate(&self, out: &mut [Complex64], target: &Target, carrier_hz: f64) {
        let n = self.spectrum.len();
        let big = out.len();
        let tau = target.delay_s();
        let gain =
            target.amplitude / n as f64 * Complex64::from_polar(1.0, -2.0 * PI * carrier_hz * tau);
        let df = self.fs_hz / n as f64;
        let mut add = |k_signed: i64, value: Complex64| {
            let f = k_signed as f64 * df;
            let bin = k_signed.rem_euclid(big as i64) as usize;
            out[bin] += value * Complex64::from_polar(1.0, -2.0 * PI * f * tau);
        };
        let half = n / 2;
        for k in 0..n {
            let x = self.spectrum[k] * gain;
            if n % 2 == 0 && k == half {
                // Nyquist bin: split between +fs/2 and -fs/2 so a real component stays real.
                add(half as i64, x * 0.5);
                add(-(half as i64), x * 0.5);
            } else if k < half || (n % 2 == 1 && k == half) {
                add(k as i64, x);
            } else {
                add(k as i64 - n as i64, x);
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::rng::SplitMix64;

    #[test]
    fn carrier_phase_is_listed_by_its_serde_spelling() {
        crate::measure::processing::listed::check_listed::<CarrierPhase>("carrier phase");
    }

    /// A band-limited test signal: random spectrum over the lowest quarter of the band.
    fn band_limited(n: usize, seed: u64) -> Vec<Complex64> {
        let mut rng = SplitMix64::new(seed);
        let mut spec = vec![Complex64::new(0.0, 0.0); n];
        for k in 0..n / 8 {
            spec[k] = rng.complex_gaussian(1.0);
            spec[n - 1 - k] = rng.complex_gaussian(1.0);
        }
        FftPlanner::new().plan_fft_inverse(n).process(&mut spec);
        spec.iter().map(|v| v / n as f64).collect()
    }

    fn max_err(a: &[Complex64], b: &[Complex64]) -> f64 {
        a.iter()
            .zip(b)
            .map(|(x, y)| (x - y).norm())
            .fold(0.0, f64::max)
    }

    #[test]
    fn whole_sample_delay_is_a_circular_shift() {
        let fs = 16e9;
        let x = band_limited(256, 1);
        let synth = EchoSynth::new(&x, fs, 256, 1).unwrap();
        let shift = 7;
        let target = Target::at(shift as f64 * C0 / (2.0 * fs));
        let y = synth.render(&[target], 0.0);
        let expected: Vec<_> = (0..256).map(|i| x[(i + 256 - shift) % 256]).collect();
        assert!(max_err(&y, &expected) < 1e-12);
    }

    #[test]
    fn upsampling_keeps_the_original_samples() {
        let x = band_limited(200, 2);
        let synth = EchoSynth::new(&x, 16e9, 200, 5).unwrap();
        let y = synth.render(&[Target::at(0.0)], 0.0);
        let every_fifth: Vec<_> = y.iter().step_by(5).copied().collect();
        assert!(max_err(&every_fifth, &x) < 1e-12);
    }

    #[test]
    fn fractional_delay_matches_the_upsampled_grid() {
        // A delay of 2/5 sample at 16 GSa/s is sample 2 of the x5 upsampled signal.
        let fs = 16e9;
        let x = band_limited(200, 4);
        let up = EchoSynth::new(&x, fs, 200, 5)
            .unwrap()
            .render(&[Target::at(0.0)], 0.0);
        let t = Target::at(0.4 * C0 / (2.0 * fs));
        let y = EchoSynth::new(&x, fs, 200, 1).unwrap().render(&[t], 0.0);
        let expected: Vec<_> = (0..200).map(|i| up[(5 * i + 1000 - 2) % 1000]).collect();
        assert!(max_err(&y, &expected) < 1e-12);
    }

    #[test]
    fn carrier_phase_and_amplitude_apply() {
        // A constant (DC) signal is unchanged by the delay itself, so only a * exp(-j 2 pi f_c tau)
        // remains: an eighth of a wavelength of range is a quarter turn of round-trip phase.
        let x = vec![Complex64::new(1.0, 0.0); 64];
        let synth = EchoSynth::new(&x, 16e9, 64, 1).unwrap();
        let t = Target {
            range_m: C0 / 80e9 / 8.0,
            amplitude: 0.5,
            velocity_mps: 0.0,
        };
        let y = synth.render(&[t], 80e9);
        let expected = vec![Complex64::new(0.0, -0.5); 64];
        assert!(max_err(&y, &expected) < 1e-12);
    }

    #[test]
    fn moving_target_rotates_at_its_doppler() {
        let n = 1024;
        let x = vec![Complex64::new(1.0, 0.0); n];
        let fs = 16e9;
        let synth = EchoSynth::new(&x, fs, n, 1).unwrap();
        let v = 10.0;
        let t = Target {
            range_m: 0.0,
            amplitude: 1.0,
            velocity_mps: v,
        };
        let y = synth.render(&[t], 0.0);
        let fd = -2.0 * v * BENCH_CARRIER_HZ / C0;
        for (i, s) in y.iter().enumerate().step_by(97) {
            let expected = Complex64::from_polar(1.0, 2.0 * PI * fd * i as f64 / fs);
            assert!((s - expected).norm() < 1e-9, "sample {i}");
        }
    }

    #[test]
    fn targets_parse_with_defaults_and_errors_name_the_field() {
        let t = parse_targets("3, 3.132:0.5 ,1:2:-4").unwrap();
        assert_eq!(t.len(), 3);
        assert_eq!(t[0], Target::at(3.0));
        assert_eq!((t[1].range_m, t[1].amplitude), (3.132, 0.5));
        assert_eq!(t[2].velocity_mps, -4.0);
        for bad in ["", "3,", "x", "3:0", "-1", "1:1:1:1", "inf"] {
            let err = parse_targets(bad).unwrap_err().to_string();
            assert!(err.starts_with("--targets"), "{bad}: {err}");
        }
    }

    #[test]
    fn conventions_give_their_carriers() {
        assert_eq!(CarrierPhase::Physical.carrier_hz(1e9), 80e9);
        assert_eq!(CarrierPhase::Centred.carrier_hz(1e9), 0.0);
        assert_eq!(CarrierPhase::Thesis.carrier_hz(1e9), 0.5e9);
    }
}
