//! Eigen-decomposition of a complex Hermitian matrix: all eigenvalues, and the eigenvectors of the
//! largest few only (all MUSIC needs: the signal subspace, and every eigenvalue for MDL/AIC).
//!
//! Householder reduction to a tridiagonal matrix (complex off-diagonals made real by a diagonal
//! unitary scaling), implicit QL with Wilkinson shifts for the eigenvalues, inverse iteration on the
//! real tridiagonal for the wanted eigenvectors, and back-transformation. This is the LAPACK
//! zhetrd/dsterf/dstein route; it does about a third of the work of a full decomposition
//! (nalgebra's `SymmetricEigen`, which tests/dsp/dsp_music.rs uses as the reference), and works in
//! preallocated storage.

use crate::dsp::DspError;
use num_complex::Complex64;

/// Workspace for matrices of one size.
#[derive(Debug, Clone)]
pub struct HermitianEigen {
    n: usize,
    /// The matrix being reduced, real and imaginary parts (row-major).
    a_re: Vec<f64>,
    a_im: Vec<f64>,
    /// The tridiagonal result: diagonal and sub-diagonal entries.
    a: Vec<Complex64>,
    v_re: Vec<f64>,
    v_im: Vec<f64>,
    p_re: Vec<f64>,
    p_im: Vec<f64>,
    /// Householder vectors (unit norm), one per step, each of length n (zeros above its start).
    reflectors: Vec<Complex64>,
    diag: Vec<f64>,
    off: Vec<f64>,
    /// Phases of the diagonal scaling that makes the off-diagonal real.
    phase: Vec<Complex64>,
    /// Eigenvalues, descending.
    values: Vec<f64>,
    /// Eigenvectors of the largest eigenvalues, column j at `vectors[j*n..(j+1)*n]`.
    vectors: Vec<Complex64>,
    work: Vec<f64>,
    /// The scale applied to the last matrix (1 / its largest entry).
    unit: f64,
    tri: TridiagonalSolver,
    y: Vec<Vec<f64>>,
}

impl HermitianEigen {
    pub fn new(n: usize) -> Self {
        let z = Complex64::default();
        Self {
            n,
            a: vec![z; n * n],
            a_re: vec![0.0; n * n],
            a_im: vec![0.0; n * n],
            v_re: vec![0.0; n],
            v_im: vec![0.0; n],
            p_re: vec![0.0; n],
            p_im: vec![0.0; n],
            reflectors: vec![z; n * n],
            diag: vec![0.0; n],
            off: vec![0.0; n],
            phase: vec![z; n],
            values: vec![0.0; n],
            vectors: Vec::with_capacity(n * n),
            work: vec![0.0; n],
            unit: 1.0,
            tri: TridiagonalSolver::new(n),
            y: Vec::new(),
        }
    }

    pub fn size(&self) -> usize {
        self.n
    }

    /// Decomposes the Hermitian `matrix` (row-major n x n; both triangles are read, so it must be
    /// Hermitian to rounding) and computes the eigenvectors of the `vectors` largest eigenvalues.
    ///
    /// # Errors
    ///
    /// [`DspError::Param`] when `matrix` is not n x n or `vectors` is above n;
    /// [`DspError::Processing`] when it holds NaN or infinite values or the QL iteration does not
    /// converge (a matrix far from Hermitian).
    pub fn decompose(&mut self, matrix: &[Complex64], vectors: usize) -> Result<(), DspError> {
        let n = self.n;
        if matrix.len() != n * n || vectors > n {
            return Err(DspError::Param(format!(
                "Hermitian eigen-decomposition: got {} values and {vectors} wanted vectors for a \
                 {n} x {n} matrix",
                matrix.len()
            )));
        }
        if matrix
            .iter()
            .any(|v| !v.re.is_finite() || !v.im.is_finite())
        {
            return Err(DspError::Processing(
                "covariance matrix holds NaN or infinite values: check the input for NaN samples"
                    .into(),
            ));
        }
        // Work on the matrix scaled to a largest entry of 1, so no square in the QL sweeps can
        // overflow or underflow whatever the input's units; eigenvalues are scaled back.
        let largest = matrix
            .iter()
            .fold(0.0f64, |m, v| m.max(v.re.abs()).max(v.im.abs()));
        let unit = if largest > 0.0 { 1.0 / largest } else { 1.0 };
        for ((r, i), v) in self.a_re.iter_mut().zip(&mut self.a_im).zip(matrix) {
            *r = v.re * unit;
            *i = v.im * unit;
        }
        self.tridiagonalise();
        self.values.copy_from_slice(&self.diag);
        self.work.copy_from_slice(&self.off);
        ql_implicit(&mut self.values, &mut self.work)?;
        self.values.sort_by(|a, b| b.total_cmp(a));
        self.eigenvectors(vectors);
        for v in &mut self.values {
            *v /= unit;
        }
        self.unit = unit;
        Ok(())
    }

    /// Recomputes the eigenvectors of the `count` largest eigenvalues of the matrix of the last
    /// [`HermitianEigen::decompose`] without reducing it again (for when the order is only known
    /// after looking at the eigenvalues).
    pub(crate) fn compute_vectors(&mut self, count: usize) {
        let count = count.min(self.n);
        for v in &mut self.values {
            *v *= self.unit;
        }
        self.eigenvectors(count);
        for v in &mut self.values {
            *v /= self.unit;
        }
    }

    /// All eigenvalues, descending.
    pub fn values(&self) -> &[f64] {
        &self.values
    }

    /// Eigenvector `j` (of the j-th largest eigenvalue), unit norm.
    pub fn vector(&self, j: usize) -> &[Complex64] {
        &self.vectors[j * self.n..(j + 1) * self.n]
    }

    /// Number of eigenvectors computed by the last [`HermitianEigen::decompose`].
    pub(crate) fn vector_count(&self) -> usize {
        self.vectors.len() / self.n.max(1)
    }

    /// Householder reduction of `a_re + j a_im` (full storage) to Hermitian tridiagonal form.
    ///
    /// Real and imaginary parts live in separate arrays and every O(n^2) loop is an element-wise
    /// update over contiguous rows (no reductions), so the compiler vectorises them.
    fn tridiagonalise(&mut self) {
        #[cfg(target_arch = "x86_64")]
        {
            if std::arch::is_x86_feature_detected!("avx2")
                && std::arch::is_x86_feature_detected!("fma")
            {
                // SAFETY: the CPU supports the features the function is compiled for.
                unsafe { self.tridiagonalise_avx2() };
                return;
            }
        }
        self.tridiagonalise_generic();
    }

    /// The same code compiled for AVX2 + FMA (4-wide f64), chosen at run time: the generic
    /// x86-64 target only has 2-wide SSE2.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2,fma")]
    unsafe fn tridiagonalise_avx2(&mut self) {
        self.tridiagonalise_generic();
    }

    #[inline(always)]
    fn tridiagonalise_generic(&mut self) {
        let n = self.n;
        let z = Complex64::default();
        self.reflectors.fill(z);
        let (ar, ai) = (&mut self.a_re, &mut self.a_im);
        let (vr, vi, pr, pi) = (
            &mut self.v_re,
            &mut self.v_im,
            &mut self.p_re,
            &mut self.p_im,
        );
        for k in 0..n.saturating_sub(2) {
            let m0 = k + 1;
            // x = A[k+1.., k] = conj(A[k, k+1..]) (row k is contiguous).
            let row_r = &ar[k * n + m0..k * n + n];
            let row_i = &ai[k * n + m0..k * n + n];
            let norm2: f64 = row_r.iter().zip(row_i).map(|(r, i)| r * r + i * i).sum();
            let x0 = Complex64::new(row_r[0], -row_i[0]);
            if norm2 - x0.norm_sqr() <= f64::MIN_POSITIVE {
                // Already tridiagonal in this column: identity reflector.
                continue;
            }
            let norm = norm2.sqrt();
            let unit = if x0.norm() > 0.0 {
                x0 / x0.norm()
            } else {
                Complex64::new(1.0, 0.0)
            };
            let alpha = -unit * norm;
            vr.fill(0.0);
            vi.fill(0.0);
            for (j, (r, i)) in row_r.iter().zip(row_i).enumerate() {
                vr[m0 + j] = *r;
                vi[m0 + j] = -*i;
            }
            vr[m0] -= alpha.re;
            vi[m0] -= alpha.im;
            let vnorm = (m0..n)
                .map(|i| vr[i] * vr[i] + vi[i] * vi[i])
                .sum::<f64>()
                .sqrt();
            for i in m0..n {
                vr[i] /= vnorm;
                vi[i] /= vnorm;
            }
            // p = A v = sum_j v_j conj(row j) (A Hermitian): a sum of scaled rows.
            pr.fill(0.0);
            pi.fill(0.0);
            for j in m0..n {
                let (a, b) = (vr[j], vi[j]);
                let rr = &ar[j * n + m0..j * n + n];
                let ri = &ai[j * n + m0..j * n + n];
                for (((p_r, p_i), x), y) in pr[m0..n].iter_mut().zip(&mut pi[m0..n]).zip(rr).zip(ri)
                {
                    *p_r += x * a + y * b;
                    *p_i += x * b - y * a;
                }
            }
            // w = 2 p - 2 (v^H p) v, v^H p real.
            let vhp: f64 = (m0..n).map(|i| vr[i] * pr[i] + vi[i] * pi[i]).sum();
            for i in m0..n {
                pr[i] = 2.0 * pr[i] - 2.0 * vhp * vr[i];
                pi[i] = 2.0 * pi[i] - 2.0 * vhp * vi[i];
            }
            // A -= v w^H + w v^H on the trailing block.
            for i in m0..n {
                let (v_r, v_i, w_r, w_i) = (vr[i], vi[i], pr[i], pi[i]);
                let rr = &mut ar[i * n + m0..i * n + n];
                let ri = &mut ai[i * n + m0..i * n + n];
                let cols = vr[m0..n]
                    .iter()
                    .zip(&vi[m0..n])
                    .zip(pr[m0..n].iter().zip(&pi[m0..n]));
                for ((x, y), ((c_vr, c_vi), (c_wr, c_wi))) in
                    rr.iter_mut().zip(ri.iter_mut()).zip(cols)
                {
                    // v_i conj(w_j) + w_i conj(v_j)
                    *x -= v_r * c_wr + v_i * c_wi + w_r * c_vr + w_i * c_vi;
                    *y -= v_i * c_wr - v_r * c_wi + w_i * c_vr - w_r * c_vi;
                }
            }
            // Column k (and row k) now hold alpha e1.
            for j in m0..n {
                ar[k * n + j] = 0.0;
                ai[k * n + j] = 0.0;
                ar[j * n + k] = 0.0;
                ai[j * n + k] = 0.0;
            }
            ar[m0 * n + k] = alpha.re;
            ai[m0 * n + k] = alpha.im;
            ar[k * n + m0] = alpha.re;
            ai[k * n + m0] = -alpha.im;
            let refl = &mut self.reflectors[k * n..(k + 1) * n];
            for (i, r) in refl.iter_mut().enumerate().skip(m0) {
                *r = Complex64::new(vr[i], vi[i]);
            }
        }
        for k in 0..n {
            self.a[k * n + k] = Complex64::new(ar[k * n + k], 0.0);
            if k + 1 < n {
                self.a[(k + 1) * n + k] = Complex64::new(ar[(k + 1) * n + k], ai[(k + 1) * n + k]);
            }
        }
        // Real tridiagonal T_r = D^H T D with d_0 = 1, d_{k+1} = d_k e_k / |e_k|.
        self.phase[0] = Complex64::new(1.0, 0.0);
        for k in 0..n {
            self.diag[k] = self.a[k * n + k].re;
        }
        for k in 0..n.saturating_sub(1) {
            let e = self.a[(k + 1) * n + k];
            let mag = e.norm();
            self.off[k] = mag;
            self.phase[k + 1] = if mag > 0.0 {
                self.phase[k] * e / mag
            } else {
                self.phase[k]
            };
        }
        if n > 0 {
            self.off[n - 1] = 0.0;
        }
    }

    /// Inverse iteration on T_r for the `count` largest eigenvalues, then u = Q D y.
    fn eigenvectors(&mut self, count: usize) {
        let n = self.n;
        self.vectors.clear();
        if count == 0 {
            return;
        }
        let scale = self
            .values
            .iter()
            .fold(0.0f64, |m, v| m.max(v.abs()))
            .max(f64::MIN_POSITIVE);
        self.y.resize_with(count, || vec![0.0; n]);
        for j in 0..count {
            let lambda = self.values[j];
            // Start from a fixed vector with no symmetry, so it is not orthogonal to the answer.
            let mut y = std::mem::take(&mut self.y[j]);
            y.resize(n, 0.0);
            for (i, yi) in y.iter_mut().enumerate() {
                *yi = 1.0 + ((i * 7919) % 97) as f64 / 97.0;
            }
            self.tri.factor(&self.diag, &self.off, lambda, scale);
            for _ in 0..3 {
                self.tri.solve(&mut y);
                // Orthogonalise against vectors of earlier eigenvalues in the same cluster.
                for (prev, &value) in self.y[..j].iter().zip(&self.values) {
                    if (value - lambda).abs() < 1e-6 * scale {
                        let d: f64 = prev.iter().zip(&y).map(|(a, b)| a * b).sum();
                        for (yi, pi) in y.iter_mut().zip(prev) {
                            *yi -= d * pi;
                        }
                    }
                }
                let norm = y.iter().map(|v| v * v).sum::<f64>().sqrt();
                for yi in &mut y {
                    *yi /= norm;
                }
            }
            self.y[j] = y;
        }
        // Back-transform: u = H_0 H_1 ... H_{n-3} D y.
        for j in 0..count {
            let start = self.vectors.len();
            self.vectors
                .extend(self.y[j].iter().zip(&self.phase).map(|(y, d)| d * y));
            let u = &mut self.vectors[start..start + n];
            for k in (0..n.saturating_sub(2)).rev() {
                let v = &self.reflectors[k * n..(k + 1) * n];
                let mut vhu = Complex64::default();
                for i in k + 1..n {
                    vhu += v[i].conj() * u[i];
                }
                if vhu == Complex64::default() {
                    continue;
                }
                let f = vhu * 2.0;
                for i in k + 1..n {
                    u[i] -= v[i] * f;
                }
            }
        }
    }
}

/// Eigenvalues of the symmetric tridiagonal (diag `d`, off-diagonal `e[i]` between i and i+1,
/// `e[n-1]` unused) by implicit QL with Wilkinson-type shifts (Numerical Recipes' tqli, without
/// vectors). `d` is overwritten with the eigenvalues, unsorted.
fn ql_implicit(d: &mut [f64], e: &mut [f64]) -> Result<(), DspError> {
    let n = d.len();
    if n == 0 {
        return Ok(());
    }
    e[n - 1] = 0.0;
    // Deflate when an off-diagonal is below rounding of the whole matrix (LAPACK's absolute
    // criterion): a purely relative test never converges on clusters of near-zero eigenvalues,
    // which a noise-free covariance has.
    let norm = d
        .iter()
        .zip(e.iter())
        .fold(0.0f64, |m, (a, b)| m.max(a.abs() + 2.0 * b.abs()));
    for l in 0..n {
        let mut iterations = 0;
        loop {
            let mut m = l;
            while m + 1 < n {
                let dd = d[m].abs() + d[m + 1].abs();
                if e[m].abs() <= f64::EPSILON * (dd + norm) {
                    break;
                }
                m += 1;
            }
            if m == l {
                break;
            }
            iterations += 1;
            if iterations > 60 {
                return Err(DspError::Processing(
                    "Hermitian eigen-decomposition did not converge in 60 QL iterations; the \
                     covariance matrix is probably not Hermitian or holds extreme values"
                        .into(),
                ));
            }
            let mut g = (d[l + 1] - d[l]) / (2.0 * e[l]);
            let mut r = (g * g + 1.0).sqrt();
            g = d[m] - d[l] + e[l] / (g + r.copysign(g));
            let (mut s, mut c, mut p) = (1.0, 1.0, 0.0);
            let mut i = m;
            let mut underflow = false;
            while i > l {
                i -= 1;
                let f = s * e[i];
                let b = c * e[i];
                // Plain sqrt, not hypot (5x slower in libm): covariance entries are far from
                // the 1e154 where squaring would overflow.
                r = (f * f + g * g).sqrt();
                e[i + 1] = r;
                if r == 0.0 {
                    d[i + 1] -= p;
                    e[m] = 0.0;
                    underflow = true;
                    break;
                }
                s = f / r;
                c = g / r;
                g = d[i + 1] - p;
                r = (d[i] - g) * s + 2.0 * c * b;
                p = s * r;
                d[i + 1] = g + p;
                g = c * r - b;
            }
            if underflow {
                continue;
            }
            d[l] -= p;
            e[l] = g;
            e[m] = 0.0;
        }
    }
    Ok(())
}

/// LU factorisation with partial pivoting of `T - lambda I` (T symmetric tridiagonal), for inverse
/// iteration; zero pivots are replaced by a tiny multiple of the matrix scale (the standard trick:
/// `lambda` is an eigenvalue, so the shifted matrix is singular to rounding).
#[derive(Debug, Clone)]
struct TridiagonalSolver {
    /// U's diagonal and two super-diagonals.
    u0: Vec<f64>,
    u1: Vec<f64>,
    u2: Vec<f64>,
    /// L's multipliers and whether rows i and i+1 were swapped.
    l: Vec<f64>,
    swapped: Vec<bool>,
}

impl TridiagonalSolver {
    fn new(n: usize) -> Self {
        Self {
            u0: vec![0.0; n],
            u1: vec![0.0; n],
            u2: vec![0.0; n],
            l: vec![0.0; n],
            swapped: vec![false; n],
        }
    }

    fn factor(&mut self, d: &[f64], e: &[f64], lambda: f64, scale: f64) {
        let n = d.len();
        let tiny = f64::EPSILON * scale;
        // Current row being eliminated: (a, b, c) at columns (i, i+1, i+2).
        let mut a = d[0] - lambda;
        let mut b = if n > 1 { e[0] } else { 0.0 };
        let mut c = 0.0;
        for i in 0..n {
            if i + 1 == n {
                self.u0[i] = if a.abs() < tiny { tiny } else { a };
                self.u1[i] = 0.0;
                self.u2[i] = 0.0;
                self.swapped[i] = false;
                break;
            }
            // Next row: (sub, diag, super) = (e[i], d[i+1]-lambda, e[i+1]).
            let (na, nb, nc) = (
                e[i],
                d[i + 1] - lambda,
                if i + 2 < n { e[i + 1] } else { 0.0 },
            );
            if na.abs() > a.abs() {
                // Swap: pivot row is the next row.
                self.swapped[i] = true;
                self.u0[i] = na;
                self.u1[i] = nb;
                self.u2[i] = nc;
                let m = a / na;
                self.l[i] = m;
                a = b - m * nb;
                b = c - m * nc;
                c = 0.0;
            } else {
                self.swapped[i] = false;
                let piv = if a.abs() < tiny { tiny } else { a };
                self.u0[i] = piv;
                self.u1[i] = b;
                self.u2[i] = c;
                let m = na / piv;
                self.l[i] = m;
                a = nb - m * b;
                b = nc - m * c;
                c = 0.0;
            }
        }
    }

    fn solve(&self, y: &mut [f64]) {
        let n = y.len();
        // Forward: apply the row swaps and L.
        for i in 0..n.saturating_sub(1) {
            if self.swapped[i] {
                y.swap(i, i + 1);
            }
            y[i + 1] -= self.l[i] * y[i];
        }
        // Back substitution with U (bandwidth 2).
        for i in (0..n).rev() {
            let mut s = y[i];
            if i + 1 < n {
                s -= self.u1[i] * y[i + 1];
            }
            if i + 2 < n {
                s -= self.u2[i] * y[i + 2];
            }
            y[i] = s / self.u0[i];
        }
    }
}
