//! Range processing for simulations, on top of `dsp`: correlation ([`dsp::correlate`]), the lab's
//! decimator ([`dsp::decimate`]) applied to a periodic capture, MUSIC/ESPRIT ([`dsp::music`]) and
//! root-MUSIC (here: the polynomial form of the same signal subspace).
//!
//! [`dsp::correlate`]: crate::dsp::correlate
//! [`dsp::decimate`]: crate::dsp::decimate
//! [`dsp::music`]: crate::dsp::music

use super::SimError;
use crate::dsp::correlate::CrossCorrelator;
use crate::dsp::decimate::{Decimator, DecimatorConfig};
use crate::dsp::metrics::Axis;
use crate::dsp::music::Music;
use crate::dsp::C0;
use nalgebra::DMatrix;
use num_complex::Complex64;
use std::f64::consts::PI;

const ZERO: Complex64 = Complex64 { re: 0.0, im: 0.0 };

/// A range profile: linear amplitude on a uniform range axis (metres).
#[derive(Debug, Clone)]
pub struct Profile {
    pub label: String,
    pub axis: Axis,
    pub amplitude: Vec<f64>,
}

impl Profile {
    pub fn ranges(&self) -> Vec<f64> {
        (0..self.amplitude.len())
            .map(|i| self.axis.at(i as f64))
            .collect()
    }

    /// 20 log10 of the amplitude relative to the maximum.
    pub fn normalised_db(&self) -> Vec<f64> {
        let max = self
            .amplitude
            .iter()
            .cloned()
            .fold(0.0, f64::max)
            .max(1e-300);
        self.amplitude
            .iter()
            .map(|a| crate::dsp::metrics::amplitude_db(a / max))
            .collect()
    }
}

/// Correlation range profile: lags `0..lags` of `r[l] = sum rx[n] conj(tx[n - l])`, normalised by
/// the transmit energy so a unit echo peaks at 1.
pub struct CorrelationProfiler {
    correlator: CrossCorrelator,
    out: Vec<Complex64>,
    fs_hz: f64,
    energy: f64,
}

impl CorrelationProfiler {
    pub fn new(tx: &[Complex64], rx_len: usize, lags: usize, fs_hz: f64) -> Result<Self, SimError> {
        let last = (lags.max(1) - 1).min(rx_len - 1) as isize;
        let correlator = CrossCorrelator::new(tx, rx_len, 0..=last)?;
        Ok(Self {
            out: vec![ZERO; correlator.output_len()],
            correlator,
            fs_hz,
            energy: tx.iter().map(|v| v.norm_sqr()).sum::<f64>().max(1e-300),
        })
    }

    pub fn profile(&mut self, rx: &[Complex64]) -> Result<Profile, SimError> {
        self.correlator.correlate_into(rx, &mut self.out)?;
        Ok(Profile {
            label: "correlation".into(),
            axis: Axis {
                start: 0.0,
                step: C0 / (2.0 * self.fs_hz),
            },
            amplitude: self.out.iter().map(|v| v.norm() / self.energy).collect(),
        })
    }
}

/// The lab decimator (`dsp::decimate`, delay-compensated) applied to a periodic capture: the
/// capture is extended circularly by whole output samples on both sides, so the filter sees what a
/// continuously repeated frame (or a zero-padded pulse) would give, with no edge transient.
pub struct PeriodicDecimator {
    decimator: Decimator,
    /// Extension on each side, input samples (a multiple of the factor).
    guard: usize,
}

impl PeriodicDecimator {
    /// Decimation of a capture at `capture_rate_hz` by `factor`, flat over +-`band_edge_hz`.
    pub fn new(capture_rate_hz: f64, factor: usize, band_edge_hz: f64) -> Result<Self, SimError> {
        let decimator = Decimator::new(&DecimatorConfig::for_band(
            capture_rate_hz,
            factor,
            band_edge_hz,
        )?)?;
        let half = decimator.taps().len() / 2 + 1;
        Ok(Self {
            guard: half.div_ceil(factor) * factor,
            decimator,
        })
    }

    pub fn decimate(&mut self, x: &[Complex64]) -> Vec<Complex64> {
        let n = x.len();
        let g = self.guard.min(n);
        let mut extended = Vec::with_capacity(n + 2 * g);
        extended.extend_from_slice(&x[n - g..]);
        extended.extend_from_slice(x);
        extended.extend_from_slice(&x[..g]);
        self.decimator.reset();
        let y = self.decimator.decimate(&extended);
        let factor = self.decimator.factor();
        let skip = g / factor;
        y[skip..skip + n / factor].to_vec()
    }
}

/// MUSIC pseudo-spectrum as a profile: amplitude sqrt(P), so its dB scale is 10 log10 P.
pub fn music_profile(range_m: &[f64], pseudo_spectrum: &[f64], m: usize, p: usize) -> Profile {
    Profile {
        label: format!("MUSIC (M = {m}, p = {p})"),
        axis: Axis::from_samples(range_m),
        amplitude: pseudo_spectrum.iter().map(|v| v.max(0.0).sqrt()).collect(),
    }
}

/// Root-MUSIC ranges from the signal subspace of the last `music` call (`p` vectors).
///
/// With `a(w)[i] = w^i`, `w = exp(-j 2 pi df tau)`, the inverse pseudo-spectrum
/// `a^H (I - Es Es^H) a` is the Laurent polynomial `sum_d c_d w^d`, `c_d` the sum of the d-th
/// diagonal of the noise projector. Its roots pair up as (z, 1/z*); the p roots inside the unit
/// circle closest to it give the ranges, `R = -arg(z) / (2 pi df) * c0 / 2` modulo the unambiguous
/// range. The roots are the eigenvalues of the companion matrix.
pub fn root_music_ranges(music: &Music, p: usize, df_hz: f64) -> Result<Vec<f64>, SimError> {
    let eigen = music.eigen();
    let m = music.config().subarray;
    if p == 0 || p > eigen.vector_count() {
        return Err(SimError::Param {
            field: "--p",
            reason: format!(
                "root-MUSIC needs 1..={} signal vectors; {p} requested",
                eigen.vector_count()
            ),
        });
    }
    // Noise projector, then its diagonal sums c_d for d = -(m-1)..=(m-1).
    let mut projector = DMatrix::<Complex64>::identity(m, m);
    for j in 0..p {
        let q = eigen.vector(j);
        for r in 0..m {
            for c in 0..m {
                projector[(r, c)] -= q[r] * q[c].conj();
            }
        }
    }
    let degree = 2 * (m - 1);
    // coef[e] multiplies z^e after multiplying by z^(m-1): e = d + m - 1, d = c - r.
    let mut coef = vec![ZERO; degree + 1];
    for r in 0..m {
        for c in 0..m {
            coef[c + m - 1 - r] += projector[(r, c)];
        }
    }
    let lead = coef[degree];
    if lead.norm() < 1e-300 {
        return Err(SimError::Param {
            field: "--p",
            reason: "root-MUSIC polynomial is degenerate; use music or esprit".into(),
        });
    }
    // Companion matrix of the monic polynomial.
    let companion = DMatrix::<Complex64>::from_fn(degree, degree, |r, c| {
        if r == 0 {
            -coef[degree - 1 - c] / lead
        } else if r == c + 1 {
            Complex64::new(1.0, 0.0)
        } else {
            ZERO
        }
    });
    let roots = nalgebra::Schur::new(companion)
        .eigenvalues()
        .ok_or_else(|| SimError::Param {
            field: "--algorithm",
            reason: "root-MUSIC: the polynomial roots did not converge; use music or esprit".into(),
        })?;
    let mut inside: Vec<Complex64> = roots.iter().copied().filter(|z| z.norm() <= 1.0).collect();
    inside.sort_by(|a, b| (1.0 - a.norm()).total_cmp(&(1.0 - b.norm())));
    let unambiguous = C0 / (2.0 * df_hz);
    let mut ranges: Vec<f64> = inside
        .iter()
        .take(p)
        .map(|z| (-z.arg() / (2.0 * PI)).rem_euclid(1.0) * unambiguous)
        .collect();
    ranges.sort_by(f64::total_cmp);
    Ok(ranges)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::dsp::music::{ModelOrder, MusicConfig, MusicSpectrum};

    /// I_div of point targets, one symbol: x[k] = sum exp(-j 2 pi (k - N/2) df tau).
    fn synthetic_idiv(n: usize, df: f64, ranges: &[f64]) -> Vec<Complex64> {
        (0..n)
            .map(|k| {
                ranges.iter().fold(ZERO, |acc, &r| {
                    let tau = 2.0 * r / C0;
                    acc + Complex64::from_polar(
                        1.0,
                        -2.0 * PI * (k as f64 - n as f64 / 2.0) * df * tau,
                    )
                })
            })
            .collect()
    }

    #[test]
    fn root_music_finds_noise_free_targets() {
        let df = 1e9 / 128.0;
        let idiv = synthetic_idiv(128, df, &[1.0, 1.06]);
        let mut music = Music::new(MusicConfig {
            subcarriers: 128,
            subarray: 32,
            order: ModelOrder::Fixed(2),
            forward_backward: true,
            grid_points: 1280,
            bandwidth_hz: 1e9,
        })
        .unwrap();
        let mut spectrum = MusicSpectrum::default();
        music.estimate(&idiv, &mut spectrum).unwrap();
        let ranges = root_music_ranges(&music, 2, df).unwrap();
        assert!(
            (ranges[0] - 1.0).abs() < 1e-5 && (ranges[1] - 1.06).abs() < 1e-5,
            "{ranges:?}"
        );
    }

    #[test]
    fn periodic_decimation_keeps_a_band_limited_tone_everywhere() {
        let n = 5000;
        let x: Vec<Complex64> = (0..n)
            .map(|i| Complex64::from_polar(1.0, 2.0 * PI * 10.0 * i as f64 / n as f64))
            .collect();
        let mut d = PeriodicDecimator::new(80e9, 5, 0.5e9).unwrap();
        let y = d.decimate(&x);
        assert_eq!(y.len(), 1000);
        for (m, v) in y.iter().enumerate() {
            assert!(
                (v - x[5 * m]).norm() < 0.02,
                "sample {m}: {v} vs {}",
                x[5 * m]
            );
        }
    }
}
