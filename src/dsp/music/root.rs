//! Root-MUSIC: ranges from the roots of the MUSIC polynomial (grid-free), using the signal
//! subspace of the last `Music::estimate` call.

use super::eigen::HermitianEigen;
use crate::dsp::{DspError, C0};
use nalgebra::DMatrix;
use num_complex::Complex64;
use std::f64::consts::PI;

const ZERO: Complex64 = Complex64 { re: 0.0, im: 0.0 };

/// Root-MUSIC ranges from the signal subspace in `eigen` (`p` vectors) of a `subarray`-sized
/// covariance.
///
/// With `a(w)[i] = w^i`, `w = exp(-j 2 pi df tau)`, the inverse pseudo-spectrum
/// `a^H (I - Es Es^H) a` is the Laurent polynomial `sum_d c_d w^d`, `c_d` the sum of the d-th
/// diagonal of the noise projector. Its roots pair up as (z, 1/z*); the p roots inside the unit
/// circle closest to it give the ranges, `R = -arg(z) / (2 pi df) * c0 / 2` modulo the unambiguous
/// range. The roots are the eigenvalues of the companion matrix.
pub(super) fn ranges(
    eigen: &HermitianEigen,
    subarray: usize,
    p: usize,
    df_hz: f64,
) -> Result<Vec<f64>, DspError> {
    let m = subarray;
    if p == 0 || p > eigen.vector_count() {
        return Err(DspError::Param(format!(
            "root-MUSIC: p = {p}; allowed: 1..={} signal vectors",
            eigen.vector_count()
        )));
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
        return Err(DspError::Processing(
            "root-MUSIC: the polynomial is degenerate; use music or esprit".into(),
        ));
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
        .ok_or_else(|| {
            DspError::Processing(
                "root-MUSIC: the polynomial roots did not converge; use music or esprit".into(),
            )
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
    use crate::dsp::{ModelOrder, Music, MusicConfig, MusicSpectrum};

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
        let ranges = ranges(music.eigen(), music.config().subarray, 2, df).unwrap();
        assert!(
            (ranges[0] - 1.0).abs() < 1e-5 && (ranges[1] - 1.06).abs() < 1e-5,
            "{ranges:?}"
        );
    }
}
