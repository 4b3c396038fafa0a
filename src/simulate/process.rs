//! Range processing for simulations: correlation, decimation, OFDM Fourier, MUSIC and ESPRIT.
//!
//! OFDM range profiles come from `dsp::ofdm_radar`.
//!
//! INTERIM: `dsp::correlate`, `dsp::decimate` and `dsp::music` were still empty
//! when this was written, so the simulation carries compact reference versions of them here, with
//! the conventions of CONVENTIONS.md. They are to be replaced by calls into `dsp` as those land
//! (the engine in `run.rs` only sees [`Profile`] and range lists).

use super::SimError;
use crate::dsp::metrics::Axis;
use crate::dsp::C0;
use nalgebra::{DMatrix, DVector};
use num_complex::Complex64;
use rustfft::{Fft, FftPlanner};
use std::f64::consts::PI;
use std::sync::Arc;

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

/// FFT cross-correlation `r[l] = sum rx[n] conj(tx[n - l])` over a circular window, with the
/// transmit spectrum computed once.
pub struct Correlator {
    tx_spectrum_conj: Vec<Complex64>,
    forward: Arc<dyn Fft<f64>>,
    inverse: Arc<dyn Fft<f64>>,
    fs_hz: f64,
    energy: f64,
}

impl Correlator {
    pub fn new(tx: &[Complex64], window: usize, fs_hz: f64) -> Self {
        let mut planner = FftPlanner::new();
        let forward = planner.plan_fft_forward(window);
        let inverse = planner.plan_fft_inverse(window);
        let mut spec = vec![ZERO; window];
        spec[..tx.len()].copy_from_slice(tx);
        forward.process(&mut spec);
        let energy = tx.iter().map(|v| v.norm_sqr()).sum::<f64>();
        Self {
            tx_spectrum_conj: spec.iter().map(|v| v.conj()).collect(),
            forward,
            inverse,
            fs_hz,
            energy,
        }
    }

    /// Correlation magnitude for lags `0..lags`, normalised so a unit echo peaks at 1.
    pub fn profile(&self, rx: &[Complex64], lags: usize) -> Profile {
        let mut buf = rx.to_vec();
        self.forward.process(&mut buf);
        for (b, t) in buf.iter_mut().zip(&self.tx_spectrum_conj) {
            *b *= t;
        }
        self.inverse.process(&mut buf);
        let scale = 1.0 / (buf.len() as f64 * self.energy);
        Profile {
            label: "correlation".into(),
            axis: Axis {
                start: 0.0,
                step: C0 / (2.0 * self.fs_hz),
            },
            amplitude: buf[..lags.min(buf.len())]
                .iter()
                .map(|v| v.norm() * scale)
                .collect(),
        }
    }
}

/// Decimation by an integer factor with a Kaiser-windowed-sinc anti-alias low-pass (pass band to
/// 60 % of the output Nyquist, stop band from the output Nyquist, 70 dB), applied circularly and
/// centred so it adds no delay.
pub struct CircularDecimator {
    factor: usize,
    taps: Vec<f64>,
}

impl CircularDecimator {
    pub fn new(factor: usize) -> Self {
        let nyq_out = 0.5 / factor as f64;
        let (f_pass, f_stop) = (0.6 * nyq_out, nyq_out);
        let atten = 70.0;
        let beta = 0.1102 * (atten - 8.7);
        let len = ((atten - 8.0) / (2.285 * 2.0 * PI * (f_stop - f_pass))).ceil() as usize | 1;
        let cutoff = 0.5 * (f_pass + f_stop);
        let mid = (len / 2) as f64;
        let i0b = bessel_i0(beta);
        let mut taps: Vec<f64> = (0..len)
            .map(|i| {
                let t = i as f64 - mid;
                let sinc = if t == 0.0 {
                    2.0 * cutoff
                } else {
                    (2.0 * PI * cutoff * t).sin() / (PI * t)
                };
                let r = t / mid;
                sinc * bessel_i0(beta * (1.0 - r * r).max(0.0).sqrt()) / i0b
            })
            .collect();
        let sum: f64 = taps.iter().sum();
        taps.iter_mut().for_each(|t| *t /= sum);
        Self { factor, taps }
    }

    pub fn decimate(&self, x: &[Complex64]) -> Vec<Complex64> {
        let n = x.len();
        let half = self.taps.len() / 2;
        (0..n / self.factor)
            .map(|m| {
                let centre = m * self.factor + n;
                self.taps
                    .iter()
                    .enumerate()
                    .fold(ZERO, |acc, (k, &h)| acc + x[(centre + half - k) % n] * h)
            })
            .collect()
    }
}

fn bessel_i0(x: f64) -> f64 {
    let (mut sum, mut term, mut k) = (1.0, 1.0, 1.0);
    while term > 1e-16 * sum {
        term *= (x / (2.0 * k)) * (x / (2.0 * k));
        sum += term;
        k += 1.0;
    }
    sum
}

/// Spatially smoothed M x M covariance of the I_div columns (every symbol), optionally with
/// forward-backward averaging.
pub fn smoothed_covariance(
    idiv: &[Complex64],
    n: usize,
    m: usize,
    forward_backward: bool,
) -> DMatrix<Complex64> {
    let mut r = DMatrix::<Complex64>::zeros(m, m);
    let mut count = 0.0;
    for row in idiv.chunks_exact(n) {
        for l in 0..=(n - m) {
            let x = DVector::from_column_slice(&row[l..l + m]);
            r += &x * x.adjoint();
            count += 1.0;
        }
    }
    r /= Complex64::new(count, 0.0);
    if forward_backward {
        let j = DMatrix::<Complex64>::from_fn(m, m, |a, b| {
            if a + b == m - 1 {
                Complex64::new(1.0, 0.0)
            } else {
                ZERO
            }
        });
        let back = &j * r.conjugate() * &j;
        r = (r + back) * Complex64::new(0.5, 0.0);
    }
    r
}

/// Eigenvalues (descending) and the matching eigenvectors (columns) of a Hermitian matrix.
fn eigen_descending(r: DMatrix<Complex64>) -> (Vec<f64>, DMatrix<Complex64>) {
    let eig = nalgebra::SymmetricEigen::new(r);
    let mut order: Vec<usize> = (0..eig.eigenvalues.len()).collect();
    order.sort_by(|&a, &b| eig.eigenvalues[b].total_cmp(&eig.eigenvalues[a]));
    let values = order.iter().map(|&i| eig.eigenvalues[i]).collect();
    let vectors = DMatrix::from_fn(eig.eigenvectors.nrows(), order.len(), |row, col| {
        eig.eigenvectors[(row, order[col])]
    });
    (values, vectors)
}

/// Number of sources by the MDL criterion (Wax-Kailath) from descending eigenvalues and the
/// number of snapshots.
pub fn mdl_order(eigenvalues: &[f64], snapshots: usize) -> usize {
    let m = eigenvalues.len();
    let ns = snapshots as f64;
    (0..m)
        .map(|k| {
            let tail = &eigenvalues[k..];
            let len = tail.len() as f64;
            let tail: Vec<f64> = tail.iter().map(|v| v.max(1e-300)).collect();
            let geo = tail.iter().map(|v| v.ln()).sum::<f64>() / len;
            let ari = (tail.iter().sum::<f64>() / len).ln();
            let k_f = k as f64;
            let mdl = -ns * len * (geo - ari) + 0.5 * k_f * (2.0 * m as f64 - k_f) * ns.ln();
            (k, mdl)
        })
        .min_by(|a, b| a.1.total_cmp(&b.1))
        .map(|(k, _)| k)
        .unwrap_or(0)
}

/// What MUSIC-family estimators share: the signal subspace of the smoothed covariance.
pub struct Subspace {
    pub eigenvalues: Vec<f64>,
    pub signal: DMatrix<Complex64>,
    pub p: usize,
}

pub fn signal_subspace(
    idiv: &[Complex64],
    n: usize,
    m: usize,
    p: Option<usize>,
    forward_backward: bool,
) -> Result<Subspace, SimError> {
    if m < 2 || m > n {
        return Err(SimError::Param {
            field: "--m",
            reason: format!("M = {m}; allowed: 2..={n} (at most the number of subcarriers)"),
        });
    }
    let r = smoothed_covariance(idiv, n, m, forward_backward);
    let (eigenvalues, vectors) = eigen_descending(r);
    let snapshots = (idiv.len() / n) * (n - m + 1);
    let p = match p {
        Some(p) if p == 0 || p >= m => {
            return Err(SimError::Param {
                field: "--p",
                reason: format!("p = {p}; allowed: 1..{m} (below M)"),
            })
        }
        Some(p) => p,
        None => mdl_order(&eigenvalues, snapshots).clamp(1, m - 1),
    };
    let signal = vectors.columns(0, p).into_owned();
    Ok(Subspace {
        eigenvalues,
        signal,
        p,
    })
}

/// MUSIC pseudo-spectrum on the `grid`-point range grid of the zero-padded IFFT (same axis as the
/// Fourier profile): `P = 1 / (M - sum_signal |a^H q|^2)`, one FFT per signal eigenvector.
/// The amplitude returned is sqrt(P), so its dB scale is the pseudo-spectrum's 10 log10.
pub fn music_profile(sub: &Subspace, grid: usize, df_hz: f64) -> Profile {
    let m = sub.signal.nrows();
    let ifft = FftPlanner::new().plan_fft_inverse(grid);
    let mut signal_power = vec![0.0; grid];
    let mut buf = vec![ZERO; grid];
    for q in sub.signal.column_iter() {
        buf.fill(ZERO);
        for (i, v) in q.iter().enumerate() {
            buf[i] = *v;
        }
        // a(tau)[i] = exp(-j 2 pi i df tau); a^H q = sum q[i] exp(+j 2 pi i m / K) = IFFT (unscaled).
        ifft.process(&mut buf);
        for (s, v) in signal_power.iter_mut().zip(&buf) {
            *s += v.norm_sqr();
        }
    }
    let amplitude = signal_power
        .iter()
        .map(|s| 1.0 / ((m as f64 - s).max(1e-12 * m as f64)).sqrt())
        .collect();
    Profile {
        label: format!("MUSIC (M = {m}, p = {})", sub.p),
        axis: Axis {
            start: 0.0,
            step: C0 / (2.0 * grid as f64 * df_hz),
        },
        amplitude,
    }
}

/// ESPRIT: ranges from the rotation between the two shifted halves of the signal subspace,
/// `Phi = pinv(Es1) Es2`, eigenvalues `exp(-j 2 pi df tau)`.
pub fn esprit_ranges(sub: &Subspace, df_hz: f64) -> Result<Vec<f64>, SimError> {
    let m = sub.signal.nrows();
    let es1 = sub.signal.rows(0, m - 1).into_owned();
    let es2 = sub.signal.rows(1, m - 1).into_owned();
    let pinv = es1
        .clone()
        .pseudo_inverse(1e-12)
        .map_err(|e| SimError::Param {
            field: "--p",
            reason: format!("ESPRIT could not invert the signal subspace ({e}); try a smaller p"),
        })?;
    let phi = pinv * es2;
    let eig = nalgebra::Schur::new(phi)
        .eigenvalues()
        .ok_or_else(|| SimError::Param {
            field: "--p",
            reason: "ESPRIT eigenvalues did not converge; try a smaller p".into(),
        })?;
    let unambiguous = C0 / (2.0 * df_hz);
    let mut ranges: Vec<f64> = eig
        .iter()
        .map(|z| {
            let frac = (-z.arg() / (2.0 * PI)).rem_euclid(1.0);
            frac * unambiguous
        })
        .collect();
    ranges.sort_by(f64::total_cmp);
    Ok(ranges)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// I_div of point targets, one symbol: x[k] = sum a exp(-j 2 pi (k - N/2) df tau).
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
    fn music_and_esprit_find_noise_free_targets() {
        let df = 1e9 / 128.0;
        let idiv = synthetic_idiv(128, df, &[1.0, 1.06]);
        let sub = signal_subspace(&idiv, 128, 64, None, true).unwrap();
        assert_eq!(sub.p, 2, "MDL finds two sources");
        let ranges = esprit_ranges(&sub, df).unwrap();
        assert!(
            (ranges[0] - 1.0).abs() < 1e-6 && (ranges[1] - 1.06).abs() < 1e-6,
            "{ranges:?}"
        );
        let prof = music_profile(&sub, 1280, df);
        let db = prof.normalised_db();
        let peaks = crate::dsp::metrics::find_peaks(&db, 3.0);
        let mut top: Vec<_> = peaks.iter().collect();
        top.sort_by(|a, b| b.value.total_cmp(&a.value));
        let mut found: Vec<f64> = top[..2]
            .iter()
            .map(|p| prof.axis.at(p.index as f64))
            .collect();
        found.sort_by(f64::total_cmp);
        assert!(
            (found[0] - 1.0).abs() < 0.01 && (found[1] - 1.06).abs() < 0.01,
            "{found:?}"
        );
    }

    #[test]
    fn circular_decimator_keeps_a_band_limited_tone() {
        let n = 5000;
        let x: Vec<Complex64> = (0..n)
            .map(|i| Complex64::from_polar(1.0, 2.0 * PI * 10.0 * i as f64 / n as f64))
            .collect();
        let y = CircularDecimator::new(5).decimate(&x);
        for (m, v) in y.iter().enumerate() {
            assert!((v - x[5 * m]).norm() < 1e-3, "sample {m}");
        }
    }
}
