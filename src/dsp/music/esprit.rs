//! LS-ESPRIT: ranges straight from the signal subspace, no grid.
//!
//! The steering vector over subcarriers is a geometric sequence, `a_i = z^i` with
//! `z = exp(-j 2 pi df tau)`, so the signal subspace `Es` (M x p) satisfies `Es2 = Es1 Phi` with
//! `Es1`, `Es2` its first and last M-1 rows and Phi having eigenvalues `z_1..z_p`. Phi is solved in
//! the least-squares sense, its eigenvalues give `tau = -arg(z) / (2 pi df)` in `[0, 1/df)`, so
//! ranges in `[0, C0 / (2 df))`.

use crate::dsp::{DspError, C0};
use nalgebra::DMatrix;
use num_complex::Complex64;

/// Ranges (ascending, metres) of the `p` components whose subspace is given by `vector(j)`,
/// `j < p`, each of length `m`.
pub(crate) fn esprit_ranges<'a>(
    vector: impl Fn(usize) -> &'a [Complex64],
    m: usize,
    p: usize,
    subcarrier_spacing_hz: f64,
) -> Result<Vec<f64>, DspError> {
    let es1 = DMatrix::from_fn(m - 1, p, |i, j| vector(j)[i]);
    let es2 = DMatrix::from_fn(m - 1, p, |i, j| vector(j)[i + 1]);
    let gram = es1.adjoint() * &es1;
    let rhs = es1.adjoint() * &es2;
    let phi = gram.lu().solve(&rhs).ok_or_else(|| {
        DspError::Processing(
            "ESPRIT: the signal subspace is rank-deficient (p larger than the number of targets \
             the data supports?); lower p or use MDL"
                .into(),
        )
    })?;
    let schur = nalgebra::linalg::Schur::try_new(phi, f64::EPSILON, 1000).ok_or_else(|| {
        DspError::Processing("ESPRIT: the eigenvalues of Phi did not converge".into())
    })?;
    let (_, t) = schur.unpack();
    let unambiguous = C0 / (2.0 * subcarrier_spacing_hz);
    let mut ranges: Vec<f64> = (0..p)
        .map(|i| {
            let z = t[(i, i)];
            let turns = (-z.arg() / (2.0 * std::f64::consts::PI)).rem_euclid(1.0);
            turns * unambiguous
        })
        .collect();
    ranges.sort_by(f64::total_cmp);
    Ok(ranges)
}
