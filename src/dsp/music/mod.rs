//! MUSIC super-resolution over OFDM subcarriers (thesis 3.2.3) and a grid-free ESPRIT estimator.
//!
//! Input: `I_div` values, symbol-major with subcarriers in ascending frequency
//! (`ofdm_radar::IDiv::as_slice`). A target at delay `tau` contributes the geometric sequence
//! `x_k ~ exp(-j 2 pi k df tau)` over subcarriers.
//!
//! 1. Covariance: M x M by spatial smoothing over all L = N - M + 1 sub-vectors of each symbol's
//!    vector, averaged over the symbols (the literal one-column `R = X X^H` has rank one and cannot
//!    separate two targets); optional forward-backward averaging `(R + J R* J) / 2`, which also
//!    decorrelates coherent echoes. Scaled by 1/(L S).
//! 2. Hermitian eigen-decomposition ([`HermitianEigen`]): all eigenvalues, eigenvectors of the p
//!    largest only. p is given or estimated from the eigenvalues with MDL or AIC (`order`).
//! 3. Pseudo-spectrum in the signal-subspace form on a grid of G points over the unambiguous range:
//!    `P(tau) = 1 / (M - sum_{signal q} |a(tau)^H q|^2)` (the noise projection, since the
//!    eigenvectors are orthonormal and `|a|^2 = M`); `a^H q` on the grid is one zero-padded inverse
//!    FFT of q, so p FFTs of size G instead of M - p. Grid point g is at `R = g C0 / (2 G df)`;
//!    with G = 1280 the grid matches the 1280-point Fourier profile. P is in linear units,
//!    at least 1/M (far from any target) and unbounded at a perfect match.
//! 4. Peaks: the p highest local maxima of P, each refined off the grid by a golden-section search
//!    of the exact pseudo-spectrum within one grid step.
//!
//! [`Music::esprit`] estimates the same ranges from the same signal subspace without any grid.

mod covariance;
mod eigen;
mod esprit;
pub(crate) mod order;
mod root;

pub use eigen::HermitianEigen;
pub(crate) use order::estimate_order;
pub use order::OrderCriterion;

use super::metrics::local_maxima;
use super::{DspError, C0};
use num_complex::Complex64;
use rustfft::{Fft, FftPlanner};
use std::sync::Arc;

/// How many components (targets) the signal subspace has.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ModelOrder {
    /// Known in advance (the thesis' assumption): 1 <= p < M.
    Fixed(usize),
    /// Estimated from the eigenvalues with an information criterion.
    Estimated(OrderCriterion),
}

/// Parameters of the MUSIC / ESPRIT estimators.
#[derive(Debug, Clone, PartialEq)]
pub struct MusicConfig {
    /// Subcarriers N per symbol (128).
    pub subcarriers: usize,
    /// Sub-vector length M, the covariance size (64): larger resolves closer targets, costs M^3.
    pub subarray: usize,
    pub order: ModelOrder,
    /// Forward-backward averaging of the covariance.
    pub forward_backward: bool,
    /// Pseudo-spectrum grid points G over the unambiguous range (1280).
    pub grid_points: usize,
    /// Occupied bandwidth B = N df, Hz (1e9).
    pub bandwidth_hz: f64,
}

impl Default for MusicConfig {
    fn default() -> Self {
        Self {
            subcarriers: 128,
            subarray: 64,
            order: ModelOrder::Fixed(2),
            forward_backward: true,
            grid_points: 1280,
            bandwidth_hz: 1e9,
        }
    }
}

impl MusicConfig {
    pub(crate) fn subcarrier_spacing_hz(&self) -> f64 {
        self.bandwidth_hz / self.subcarriers as f64
    }

    /// Grid step of the pseudo-spectrum, m.
    pub(crate) fn grid_step_m(&self) -> f64 {
        C0 / (2.0 * self.grid_points as f64 * self.subcarrier_spacing_hz())
    }

    /// Checks every field; the message names the field and what is allowed.
    pub(crate) fn validate(&self) -> Result<(), DspError> {
        let (n, m) = (self.subcarriers, self.subarray);
        let param = |s: String| Err(DspError::Param(s));
        if n < 2 {
            return param(format!(
                "MUSIC: subcarriers = {n}; allowed: at least 2 (128 in the thesis)"
            ));
        }
        if m < 2 || m > n {
            return param(format!(
                "MUSIC: M = {m}; allowed: 2 <= M <= N = {n} subcarriers (the thesis uses 16, 32, 64)"
            ));
        }
        if let ModelOrder::Fixed(p) = self.order {
            if p < 1 || p >= m {
                return param(format!(
                    "MUSIC: p = {p}; allowed: 1 <= p < M = {m} (the number of targets; at least one \
                     noise eigenvector must remain)"
                ));
            }
        }
        if self.grid_points < m {
            return param(format!(
                "MUSIC: grid_points = {}; allowed: at least M = {m} (1280 matches the Fourier profile)",
                self.grid_points
            ));
        }
        if !(self.bandwidth_hz.is_finite() && self.bandwidth_hz > 0.0) {
            return param(format!(
                "MUSIC: bandwidth_hz = {}; allowed: a positive frequency (1e9 in the thesis)",
                self.bandwidth_hz
            ));
        }
        Ok(())
    }
}

/// A MUSIC estimate.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct MusicSpectrum {
    /// Grid ranges, m (G points from 0).
    pub range_m: Vec<f64>,
    /// Pseudo-spectrum P on the grid (linear; >= 1/M).
    pub pseudo_spectrum: Vec<f64>,
    /// Covariance eigenvalues, descending.
    pub eigenvalues: Vec<f64>,
    /// The order used (given, or estimated and at least 1).
    pub order: usize,
    /// The criterion's raw estimate when the order was estimated (0 = "noise only").
    pub estimated_order: Option<usize>,
    /// The `order` strongest peaks, refined off the grid, ascending range (m). Fewer when the
    /// spectrum has fewer local maxima.
    pub peaks_m: Vec<f64>,
}

/// MUSIC / ESPRIT estimator: the covariance, eigen workspace and FFT plan are made once.
pub struct Music {
    config: MusicConfig,
    covariance: Vec<Complex64>,
    row: Vec<Complex64>,
    eigen: HermitianEigen,
    ifft: Arc<dyn Fft<f64>>,
    fft_buf: Vec<Complex64>,
    fft_scratch: Vec<Complex64>,
    projection: Vec<f64>,
    peak_scratch: Vec<usize>,
}

impl Music {
    /// A MUSIC estimator for `config`, with its buffers allocated once.
    ///
    /// # Errors
    ///
    /// [`DspError::Param`] when a field of `config` is out of range; the message names it.
    pub fn new(config: MusicConfig) -> Result<Self, DspError> {
        config.validate()?;
        let m = config.subarray;
        let g = config.grid_points;
        let ifft = FftPlanner::new().plan_fft_inverse(g);
        let z = Complex64::default();
        Ok(Self {
            covariance: vec![z; m * m],
            row: vec![z; m],
            eigen: HermitianEigen::new(m),
            fft_buf: vec![z; g],
            fft_scratch: vec![z; ifft.get_inplace_scratch_len()],
            projection: vec![0.0; g],
            peak_scratch: Vec::with_capacity(g / 2),
            ifft,
            config,
        })
    }

    pub fn config(&self) -> &MusicConfig {
        &self.config
    }

    /// The smoothed covariance of the last call, row-major M x M.
    pub fn covariance(&self) -> &[Complex64] {
        &self.covariance
    }

    /// Number of smoothing snapshots for `symbols` symbols: (N - M + 1) S.
    pub(crate) fn snapshots(&self, symbols: usize) -> usize {
        (self.config.subcarriers - self.config.subarray + 1) * symbols
    }

    /// The snapshot count given to MDL/AIC for `symbols` symbols: `S * floor(N / M)` (at least 1),
    /// the number of *non-overlapping* sub-vectors. Overlapping sub-vectors share their noise
    /// samples; counting all L S of them (or 2 L S with forward-backward) overstates the evidence
    /// that the slightly unequal noise eigenvalues of a smoothed covariance differ, and AIC then
    /// over-estimates the order by several (measured: 10 instead of 3 in tests/dsp/dsp_music.rs).
    pub(crate) fn order_snapshots(&self, symbols: usize) -> usize {
        (symbols * (self.config.subcarriers / self.config.subarray)).max(1)
    }

    /// Builds the covariance of `idiv` (symbol-major, `S * N` values) into [`Music::covariance`].
    ///
    /// # Errors
    ///
    /// [`DspError::Param`] when `idiv` is empty or not a whole number of symbols.
    pub fn build_covariance(&mut self, idiv: &[Complex64]) -> Result<usize, DspError> {
        let (n, m) = (self.config.subcarriers, self.config.subarray);
        if idiv.is_empty() || idiv.len() % n != 0 {
            return Err(DspError::Param(format!(
                "MUSIC: I_div has {} values; allowed: a whole, non-zero number of symbols of N = {n} \
                 subcarriers",
                idiv.len()
            )));
        }
        let symbols = idiv.len() / n;
        self.covariance.fill(Complex64::default());
        for x in idiv.chunks_exact(n) {
            covariance::accumulate_smoothed(x, m, &mut self.covariance, &mut self.row);
        }
        let scale = 1.0 / self.snapshots(symbols) as f64;
        for v in &mut self.covariance {
            *v *= scale;
        }
        if self.config.forward_backward {
            covariance::forward_backward(&mut self.covariance, m);
        }
        Ok(symbols)
    }

    /// Covariance, eigen-decomposition and order: the signal subspace of `idiv`.
    fn subspace(&mut self, idiv: &[Complex64]) -> Result<(usize, Option<usize>), DspError> {
        let symbols = self.build_covariance(idiv)?;
        let m = self.config.subarray;
        match self.config.order {
            ModelOrder::Fixed(p) => {
                self.eigen.decompose(&self.covariance, p)?;
                Ok((p, None))
            }
            ModelOrder::Estimated(criterion) => {
                self.eigen.decompose(&self.covariance, 0)?;
                let k = estimate_order(
                    self.eigen.values(),
                    self.order_snapshots(symbols),
                    criterion,
                );
                let p = k.clamp(1, m - 1);
                self.eigen.compute_vectors(p);
                Ok((p, Some(k)))
            }
        }
    }

    /// MUSIC pseudo-spectrum and peaks of `idiv` into `out`.
    ///
    /// # Errors
    ///
    /// [`DspError::Param`] when `idiv` is empty or not a whole number of symbols;
    /// [`DspError::Processing`] when the covariance holds NaN or infinite values or its
    /// eigen-decomposition does not converge.
    pub fn estimate(
        &mut self,
        idiv: &[Complex64],
        out: &mut MusicSpectrum,
    ) -> Result<(), DspError> {
        let (p, estimated) = self.subspace(idiv)?;
        let m = self.config.subarray;
        let g = self.config.grid_points;
        // sum over signal vectors of |a^H q|^2 on the grid: a^H q = unnormalised inverse FFT of q.
        self.projection.fill(0.0);
        for j in 0..p {
            self.fft_buf.fill(Complex64::default());
            self.fft_buf[..m].copy_from_slice(self.eigen.vector(j));
            self.ifft
                .process_with_scratch(&mut self.fft_buf, &mut self.fft_scratch);
            for (s, v) in self.projection.iter_mut().zip(&self.fft_buf) {
                *s += v.norm_sqr();
            }
        }
        let floor = m as f64 * 1e-12;
        out.pseudo_spectrum.resize(g, 0.0);
        for (o, s) in out.pseudo_spectrum.iter_mut().zip(&self.projection) {
            *o = 1.0 / (m as f64 - s).max(floor);
        }
        let step = self.config.grid_step_m();
        if out.range_m.len() != g {
            out.range_m.clear();
            out.range_m.extend((0..g).map(|i| i as f64 * step));
        }
        out.eigenvalues.clear();
        out.eigenvalues.extend_from_slice(self.eigen.values());
        out.order = p;
        out.estimated_order = estimated;
        out.peaks_m.clear();
        // The p highest local maxima (kept in `peak_scratch`, sorted by height).
        self.peak_scratch.clear();
        self.peak_scratch.extend(local_maxima(&out.pseudo_spectrum));
        let spectrum = &out.pseudo_spectrum;
        self.peak_scratch
            .sort_unstable_by(|&a, &b| spectrum[b].total_cmp(&spectrum[a]));
        for &index in self.peak_scratch.iter().take(p) {
            out.peaks_m.push(self.refine(index as f64 * step, step));
        }
        out.peaks_m.sort_by(f64::total_cmp);
        Ok(())
    }

    /// Exact pseudo-spectrum at one range (direct evaluation, no grid).
    pub(crate) fn pseudo_spectrum_at(&self, range_m: f64) -> f64 {
        let m = self.config.subarray;
        let p = self.eigen.vector_count();
        let tau = 2.0 * range_m / C0;
        let step = Complex64::from_polar(
            1.0,
            2.0 * std::f64::consts::PI * self.config.subcarrier_spacing_hz() * tau,
        );
        let mut s = 0.0;
        for j in 0..p {
            let mut ph = Complex64::new(1.0, 0.0);
            let mut acc = Complex64::default();
            for q in self.eigen.vector(j) {
                acc += q * ph;
                ph *= step;
            }
            s += acc.norm_sqr();
        }
        1.0 / (m as f64 - s).max(m as f64 * 1e-12)
    }

    fn refine(&self, guess: f64, step: f64) -> f64 {
        crate::dsp::ofdm_radar::golden_section_max(
            |r| self.pseudo_spectrum_at(r),
            guess - step,
            guess + step,
            step * 1e-6,
        )
    }

    /// LS-ESPRIT ranges (ascending, metres) from the same covariance and order: grid-free.
    ///
    /// # Errors
    ///
    /// Those of [`Music::estimate`], and [`DspError::Processing`] when the signal subspace is
    /// rank-deficient or ESPRIT's eigenvalues do not converge.
    pub fn esprit(&mut self, idiv: &[Complex64]) -> Result<Vec<f64>, DspError> {
        self.subspace(idiv)?;
        self.esprit_of_last()
    }

    /// LS-ESPRIT on the signal subspace of the last [`Music::estimate`] or [`Music::esprit`]
    /// call, without building and decomposing the covariance again.
    ///
    /// # Errors
    ///
    /// [`DspError::Processing`] when no call has built a signal subspace yet, the subspace is
    /// rank-deficient, or ESPRIT's eigenvalues do not converge.
    pub fn esprit_of_last(&self) -> Result<Vec<f64>, DspError> {
        let p = self.eigen.vector_count();
        if p == 0 {
            return Err(DspError::Processing(
                "ESPRIT: no signal subspace yet; call Music::estimate or Music::esprit first"
                    .into(),
            ));
        }
        let eigen = &self.eigen;
        esprit::esprit_ranges(
            |j| eigen.vector(j),
            self.config.subarray,
            p,
            self.config.subcarrier_spacing_hz(),
        )
    }

    /// The eigen-decomposition of the last call (eigenvalues; eigenvectors of the signal subspace).
    pub fn eigen(&self) -> &HermitianEigen {
        &self.eigen
    }
}

/// Root-MUSIC ranges from the signal subspace of the last [`Music::estimate`] call (`p` vectors).
pub(crate) fn root_music_ranges(music: &Music, p: usize, df_hz: f64) -> Result<Vec<f64>, DspError> {
    root::ranges(music.eigen(), music.config().subarray, p, df_hz)
}
