//! Spatially smoothed (and optionally forward-backward averaged) covariance of I_div vectors.
//!
//! For one vector x of N subcarriers and sub-vector length M there are L = N - M + 1 sub-vectors
//! `x_l = x[l..l+M]`; the smoothed covariance is `R = (1/L) sum_l x_l x_l^H`, i.e.
//! `R[i][j] = (1/L) sum_{l<L} x[l+i] conj(x[l+j])`. Sliding by one sub-vector changes each entry by
//! one term in and one out, so along every diagonal
//! `R[i+1][j+1] = R[i][j] + x[L+i] conj(x[L+j]) - x[i] conj(x[j])`: the first row costs M L
//! products and the rest M^2 (instead of M^2 L), a rank-two update per step down the diagonal.

use num_complex::Complex64;

/// Adds `sum_l x_l x_l^H` of one vector to the row-major M x M accumulator `acc`, using `row` as
/// scratch for one row. `x.len() >= m`.
pub(crate) fn accumulate_smoothed(
    x: &[Complex64],
    m: usize,
    acc: &mut [Complex64],
    row: &mut [Complex64],
) {
    let n = x.len();
    let l = n - m + 1;
    // First row: R[0][j] = sum_l x[l] conj(x[l+j]).
    for (j, r) in row.iter_mut().enumerate().take(m) {
        let mut s = Complex64::default();
        for (a, b) in x[..l].iter().zip(&x[j..j + l]) {
            s += a * b.conj();
        }
        *r = s;
    }
    // Rows i >= 1 from row i-1 shifted down the diagonal; column 0 from Hermitian symmetry.
    // `row` holds the previous row's unscaled values while we build the next one in place from
    // the right (j descending) so row[j-1] is still the previous row's value.
    for (j, r) in row.iter().enumerate().take(m) {
        acc[j] += r;
    }
    for i in 1..m {
        let (xi_out, xi_in) = (x[i - 1], x[l + i - 1]);
        for j in (1..m).rev() {
            let v = row[j - 1] + xi_in * x[l + j - 1].conj() - xi_out * x[j - 1].conj();
            row[j] = v;
        }
        // R[i][0] = conj(R[0][i]): recompute directly to keep the recursion's rounding local.
        let mut s = Complex64::default();
        for (a, b) in x[i..i + l].iter().zip(&x[..l]) {
            s += a * b.conj();
        }
        row[0] = s;
        let out = &mut acc[i * m..(i + 1) * m];
        for (o, r) in out.iter_mut().zip(row.iter()) {
            *o += r;
        }
    }
}

/// `R <- (R + J conj(R) J) / 2` in place (J the exchange matrix): forward-backward averaging.
pub(crate) fn forward_backward(r: &mut [Complex64], m: usize) {
    for i in 0..m {
        for j in 0..m {
            let (a, b) = (i * m + j, (m - 1 - i) * m + (m - 1 - j));
            if a < b {
                let avg_a = (r[a] + r[b].conj()) * 0.5;
                let avg_b = (r[b] + r[a].conj()) * 0.5;
                r[a] = avg_a;
                r[b] = avg_b;
            } else if a == b {
                r[a] = Complex64::new(r[a].re, 0.0);
            }
        }
    }
}
