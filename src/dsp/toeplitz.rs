//! Hermitian Toeplitz systems by Levinson's recursion: `O(L^2)` where a factorisation is
//! `O(L^3)`. The chain estimator's normal equations are one (the autocorrelation of the
//! transmitted waveform over the lags of its gate).

use num_complex::Complex64;

/// Solves `T x = b` for the Hermitian Toeplitz `T` whose first column is `t`
/// (`T[i][j] = t[i - j]` for `i >= j`, `conj(t[j - i])` above the diagonal). `None` when a
/// leading minor is singular (or the input is not finite): `T` positive definite never is.
pub(crate) fn solve_hermitian(t: &[Complex64], b: &[Complex64]) -> Option<Vec<Complex64>> {
    let l = b.len();
    if t.len() < l || l == 0 || !(t[0].norm() > 0.0 && t[0].is_finite()) {
        return None;
    }
    let one = Complex64::new(1.0, 0.0);
    // Forward and backward vectors: T_n f = e_0, T_n g = e_{n-1}.
    let mut f = vec![one / t[0]];
    let mut g = vec![one / t[0]];
    let mut x = vec![b[0] / t[0]];
    for n in 1..l {
        // The new row's product with f (last element) and the new column's with g (first).
        let ef: Complex64 = (0..n).map(|i| t[n - i] * f[i]).sum();
        let eg: Complex64 = (0..n).map(|i| t[i + 1].conj() * g[i]).sum();
        let d = one - ef * eg;
        if !(d.norm() > 1e-300 && d.is_finite()) {
            return None;
        }
        let mut f_next = Vec::with_capacity(n + 1);
        let mut g_next = Vec::with_capacity(n + 1);
        for i in 0..=n {
            let fi = if i < n { f[i] } else { Complex64::default() };
            let gi = if i > 0 {
                g[i - 1]
            } else {
                Complex64::default()
            };
            f_next.push((fi - ef * gi) / d);
            g_next.push((gi - eg * fi) / d);
        }
        f = f_next;
        g = g_next;
        let ex: Complex64 = (0..n).map(|i| t[n - i] * x[i]).sum();
        x.push(Complex64::default());
        let c = b[n] - ex;
        for (xi, gi) in x.iter_mut().zip(&g) {
            *xi += c * gi;
        }
    }
    x.iter().all(|v| v.is_finite()).then_some(x)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::rng::SplitMix64;
    use nalgebra::DMatrix;

    fn random(rng: &mut SplitMix64) -> Complex64 {
        Complex64::new(rng.uniform() - 0.5, rng.uniform() - 0.5)
    }

    #[test]
    fn levinson_matches_a_dense_solve() {
        let mut rng = SplitMix64::new(5);
        for l in [1, 2, 3, 8, 31] {
            // A positive definite Hermitian Toeplitz: the autocorrelation of a random sequence,
            // with a little on the diagonal.
            let s: Vec<Complex64> = (0..l + 40).map(|_| random(&mut rng)).collect();
            let t: Vec<Complex64> = (0..l)
                .map(|d| {
                    let r: Complex64 = (0..s.len() - d).map(|i| s[i + d] * s[i].conj()).sum();
                    r + if d == 0 {
                        Complex64::new(0.1, 0.0)
                    } else {
                        Complex64::default()
                    }
                })
                .collect();
            let b: Vec<Complex64> = (0..l).map(|_| random(&mut rng)).collect();
            let dense =
                DMatrix::from_fn(l, l, |i, j| if i >= j { t[i - j] } else { t[j - i].conj() });
            let x = solve_hermitian(&t, &b).unwrap();
            let back = &dense * nalgebra::DVector::from_vec(x.clone());
            for i in 0..l {
                assert!(
                    (back[i] - b[i]).norm() < 1e-9,
                    "L {l}, row {i}: {} vs {}",
                    back[i],
                    b[i]
                );
            }
        }
    }

    #[test]
    fn a_singular_or_empty_system_is_refused() {
        let z = Complex64::default();
        assert!(solve_hermitian(&[z, z], &[z, z]).is_none());
        assert!(solve_hermitian(&[], &[]).is_none());
        let one = Complex64::new(1.0, 0.0);
        // [[1, 1], [1, 1]]: the second minor is singular.
        assert!(solve_hermitian(&[one, one], &[one, one]).is_none());
    }
}
