//! Noise estimates and thresholds on a power profile, with cells near detected targets excluded.
//!
//! All thresholds here are for complex Gaussian noise: the power `|z|^2` of a noise cell is
//! exponential with mean `sigma^2`, so `P(|z|^2 > alpha sigma^2) = exp(-alpha)`. Noise in a profile
//! is correlated over `PsfShape::noise_cells` cells (`dsp::detect`) (the axis is oversampled); estimates
//! count independent samples, and the local (CFAR) windows take their training cells that far
//! apart so the classical formulas, derived for independent cells, hold.
//!
//! The one sliding-window CFAR of the crate: `dsp::detect` runs it with exclusions and strided
//! training cells, [`super::CaCfar`] with adjacent cells and an oversampling count.

use crate::dsp::DspError;

/// How a sliding-window CFAR combines its training cells.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum CfarKind {
    /// Cell averaging over both sides.
    Ca,
    /// Greatest-of the two sides' means: robust at clutter edges, masks more.
    Go,
    /// Smallest-of the two sides' means: a target on one side does not raise the threshold.
    So,
    /// Ordered statistic: the `rank` fraction (0.75 typical) of the sorted training cells; up to
    /// `(1 - rank)` of them may hold targets without raising the threshold.
    Os { rank: f64 },
}

impl CfarKind {
    /// A short name for reports: `ca`, `go`, `so`, `os(0.75)`.
    pub fn name(&self) -> String {
        match self {
            CfarKind::Ca => "ca".into(),
            CfarKind::Go => "go".into(),
            CfarKind::So => "so".into(),
            CfarKind::Os { rank } => format!("os({rank})"),
        }
    }
}

/// Finds `t` with `pfa_of(t) = pfa` for a decreasing `pfa_of` (bisection on log t).
fn solve(pfa: f64, pfa_of: impl Fn(f64) -> f64) -> f64 {
    let (mut lo, mut hi) = (1e-9f64, 1.0f64);
    while pfa_of(hi) > pfa && hi < 1e12 {
        hi *= 2.0;
    }
    for _ in 0..200 {
        let mid = (lo * hi).sqrt();
        if pfa_of(mid) > pfa {
            lo = mid;
        } else {
            hi = mid;
        }
        if hi / lo < 1.0 + 1e-12 {
            break;
        }
    }
    hi
}

/// CA-CFAR over a mean of `samples` independent noise samples (fractional when oversampled
/// cells are counted, at least one): `alpha = n (pfa^(-1/n) - 1)`.
pub(crate) fn alpha_ca_samples(pfa: f64, samples: f64) -> f64 {
    let n = samples.max(1.0);
    n * (pfa.powf(-1.0 / n) - 1.0)
}

/// `sum_{k<n} C(n-1+k, k) (2+t)^-(n+k)`, the common term of the GO/SO false-alarm formulas.
fn go_so_sum(t: f64, n: usize) -> f64 {
    let mut total = 0.0;
    let mut log_c = 0.0; // log C(n-1+k, k)
    for k in 0..n {
        if k > 0 {
            log_c += ((n - 1 + k) as f64).ln() - (k as f64).ln();
        }
        total += (log_c - (n + k) as f64 * (2.0 + t).ln()).exp();
    }
    total
}

/// GO-CFAR with `n` cells per side: `t` such that `T = t * max(sum_left, sum_right)` has the
/// false-alarm probability `pfa` (Hansen and Sawyers):
/// `Pfa = 2 (1+t)^-n - 2 sum_{k<n} C(n-1+k, k) (2+t)^-(n+k)`.
pub(crate) fn alpha_go(pfa: f64, n: usize) -> f64 {
    let n = n.max(1);
    solve(pfa, |t| {
        2.0 * (1.0 + t).powi(-(n as i32)) - 2.0 * go_so_sum(t, n)
    })
}

/// SO-CFAR with `n` cells per side, `T = t * min(sum_left, sum_right)`:
/// `Pfa = 2 sum_{k<n} C(n-1+k, k) (2+t)^-(n+k)`.
pub(crate) fn alpha_so(pfa: f64, n: usize) -> f64 {
    let n = n.max(1);
    solve(pfa, |t| 2.0 * go_so_sum(t, n))
}

/// OS-CFAR, `T = t * X_(k)` with `X_(k)` the k-th smallest of `n` training cells:
/// `Pfa = prod_{i<k} (n - i) / (n - i + t)`.
pub(crate) fn alpha_os(pfa: f64, n: usize, k: usize) -> f64 {
    let n = n.max(1);
    let k = k.clamp(1, n);
    solve(pfa, |t| {
        (0..k)
            .map(|i| (n - i) as f64 / ((n - i) as f64 + t))
            .product::<f64>()
    })
}

/// The global, robust noise estimate: `median(|z|^2) / ln 2` over the cells not excluded, and the
/// threshold factor that keeps the false-alarm probability per cell at `pfa` for an estimate from
/// that many independent samples (the median has about 0.48 times the efficiency of the mean).
/// Returns `(sigma^2, alpha)`, or `None` when fewer than 4 independent samples remain.
pub(crate) fn global_noise(
    power: &[f64],
    exclude: &[bool],
    noise_cells: f64,
    pfa: f64,
    scratch: &mut Vec<f64>,
) -> Option<(f64, f64)> {
    scratch.clear();
    scratch.extend(
        power
            .iter()
            .zip(exclude)
            .filter(|(_, &x)| !x)
            .map(|(&p, _)| p),
    );
    let independent = scratch.len() as f64 / noise_cells.max(1.0);
    if independent < 4.0 {
        return None;
    }
    let mid = scratch.len() / 2;
    let (_, median, _) = scratch.select_nth_unstable_by(mid, f64::total_cmp);
    let sigma2 = *median / std::f64::consts::LN_2;
    let n_eq = (0.48 * independent).max(1.0);
    let alpha = n_eq * (pfa.powf(-1.0 / n_eq) - 1.0);
    Some((sigma2, alpha))
}

/// A sliding-window CFAR over a power profile whose training cells skip excluded cells.
#[derive(Debug, Clone)]
pub(crate) struct LocalCfar {
    kind: CfarKind,
    /// Cells skipped on each side of the cell under test.
    guard: usize,
    /// Independent training samples wanted per side.
    train: usize,
    /// Distance between training cells (cells per independent noise sample).
    stride: usize,
    pfa: f64,
    /// Neighbouring training cells that count as one independent sample in the CA factor (the
    /// zero-padding factor when training cells are taken next to each other, `stride` 1).
    cells_per_sample: usize,
    /// Threshold factors per number of training cells (CA, OS: total; GO, SO: per side).
    alphas: Vec<f64>,
    left: Vec<f64>,
    right: Vec<f64>,
    sorted: Vec<f64>,
}

impl LocalCfar {
    /// `train` independent samples per side, `stride` cells apart, after `guard` cells.
    pub(crate) fn new(
        kind: CfarKind,
        guard: usize,
        train: usize,
        stride: usize,
        pfa: f64,
    ) -> Result<Self, DspError> {
        if train == 0 {
            return Err(DspError::Param(
                "CFAR: training = 0; allowed: at least 1 independent training sample per side \
                 (8 is typical)"
                    .into(),
            ));
        }
        if let CfarKind::Os { rank } = kind {
            if !(rank > 0.0 && rank <= 1.0) {
                return Err(DspError::Param(format!(
                    "OS-CFAR: rank = {rank}; allowed: a fraction in (0, 1] (0.75 is typical)"
                )));
            }
        }
        let mut cfar = Self {
            kind,
            guard,
            train,
            stride: stride.max(1),
            pfa,
            cells_per_sample: 1,
            alphas: Vec::new(),
            left: Vec::with_capacity(train),
            right: Vec::with_capacity(train),
            sorted: Vec::with_capacity(2 * train),
        };
        cfar.tabulate();
        Ok(cfar)
    }

    /// Counts `factor` (at least 1) neighbouring training cells as one independent noise sample
    /// in the CA factor: for a zero-padded profile trained on adjacent cells (`stride` 1).
    pub(crate) fn with_cells_per_sample(mut self, factor: usize) -> Self {
        self.cells_per_sample = factor.max(1);
        self.tabulate();
        self
    }

    /// The CA factor for a mean over `n` training cells.
    pub(crate) fn alpha_ca(&self, n: usize) -> f64 {
        alpha_ca_samples(self.pfa, n as f64 / self.cells_per_sample as f64)
    }

    fn tabulate(&mut self) {
        let (pfa, train) = (self.pfa, self.train);
        self.alphas = match self.kind {
            CfarKind::Ca => (0..=2 * train).map(|n| self.alpha_ca(n)).collect(),
            CfarKind::Go => (0..=train).map(|n| alpha_go(pfa, n)).collect(),
            CfarKind::So => (0..=train).map(|n| alpha_so(pfa, n)).collect(),
            CfarKind::Os { rank } => (0..=2 * train)
                .map(|n| alpha_os(pfa, n, Self::os_rank(rank, n)))
                .collect(),
        };
    }

    fn os_rank(rank: f64, n: usize) -> usize {
        ((rank * n as f64).ceil() as usize).clamp(1, n.max(1))
    }

    /// Writes the threshold (power) of every cell into `out`. Training cells are taken every
    /// `stride` cells outward from `guard` cells off the cell under test, skipping excluded cells,
    /// looking at most twice the window's reach; a cell without any training cell gets +inf.
    pub(crate) fn thresholds(&mut self, power: &[f64], exclude: &[bool], out: &mut [f64]) {
        let n = power.len() as isize;
        let reach = 2 * self.train;
        for (c, t) in out.iter_mut().enumerate() {
            let c = c as isize;
            self.left.clear();
            self.right.clear();
            for (side, dir) in [(&mut self.left, -1isize), (&mut self.right, 1)] {
                for s in 0..reach {
                    if side.len() == self.train {
                        break;
                    }
                    let i = c + dir * (self.guard as isize + 1 + (s * self.stride) as isize);
                    if i < 0 || i >= n {
                        break;
                    }
                    if !exclude[i as usize] {
                        side.push(power[i as usize]);
                    }
                }
            }
            *t = self.combine();
        }
    }

    fn combine(&mut self) -> f64 {
        let (nl, nr) = (self.left.len(), self.right.len());
        if nl + nr == 0 {
            return f64::INFINITY;
        }
        let mean = |v: &[f64]| v.iter().sum::<f64>() / v.len().max(1) as f64;
        let kind = match self.kind {
            // With one side empty, GO and SO fall back to averaging the other.
            CfarKind::Go | CfarKind::So if nl == 0 || nr == 0 => CfarKind::Ca,
            k => k,
        };
        match kind {
            CfarKind::Ca => {
                let all = self.left.iter().chain(&self.right).sum::<f64>() / (nl + nr) as f64;
                let alpha = match self.kind {
                    CfarKind::Ca => self.alphas[nl + nr],
                    _ => self.alpha_ca(nl + nr),
                };
                alpha * all
            }
            CfarKind::Go | CfarKind::So => {
                // Unequal sides (exclusions, profile ends): the formula for the shorter side,
                // applied to the means, which errs on the safe side.
                let m = nl.min(nr);
                let (a, b) = (mean(&self.left), mean(&self.right));
                let pick = if kind == CfarKind::Go {
                    a.max(b)
                } else {
                    a.min(b)
                };
                self.alphas[m] * m as f64 * pick
            }
            CfarKind::Os { rank } => {
                self.sorted.clear();
                self.sorted.extend_from_slice(&self.left);
                self.sorted.extend_from_slice(&self.right);
                let n = self.sorted.len();
                let k = Self::os_rank(rank, n);
                let (_, kth, _) = self.sorted.select_nth_unstable_by(k - 1, f64::total_cmp);
                self.alphas[n] * *kth
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::rng::SplitMix64;

    fn exp_noise(rng: &mut SplitMix64, n: usize) -> Vec<f64> {
        (0..n)
            .map(|_| rng.complex_gaussian(1.0).norm_sqr())
            .collect()
    }

    #[test]
    fn formulas_match_simulation() {
        // Monte-Carlo false-alarm rates at pfa = 1e-2 with independent cells.
        let mut rng = SplitMix64::new(42);
        let trials = 100_000;
        let pfa = 1e-2;
        let n = 8;
        let (go, so, os) = (alpha_go(pfa, n), alpha_so(pfa, n), alpha_os(pfa, 2 * n, 12));
        let mut hits = [0usize; 3];
        for _ in 0..trials {
            let l = exp_noise(&mut rng, n);
            let r = exp_noise(&mut rng, n);
            let cut = rng.complex_gaussian(1.0).norm_sqr();
            let (sl, sr): (f64, f64) = (l.iter().sum(), r.iter().sum());
            hits[0] += usize::from(cut > go * sl.max(sr));
            hits[1] += usize::from(cut > so * sl.min(sr));
            let mut all: Vec<f64> = l.iter().chain(&r).copied().collect();
            all.sort_by(f64::total_cmp);
            hits[2] += usize::from(cut > os * all[11]);
        }
        for (h, name) in hits.iter().zip(["GO", "SO", "OS"]) {
            let rate = *h as f64 / trials as f64;
            // 1000 expected, standard deviation about 31.
            assert!((rate - pfa).abs() < 1.5e-3, "{name}: {rate}");
        }
    }

    #[test]
    fn excluded_cells_do_not_train() {
        // A strong target 5 cells from the cell under test would raise a CA threshold; excluded,
        // it does not.
        let mut power = vec![1.0; 64];
        power[37] = 1e6;
        let mut exclude = vec![false; 64];
        let mut cfar = LocalCfar::new(CfarKind::Ca, 1, 8, 1, 1e-3).unwrap();
        let mut t = vec![0.0; 64];
        cfar.thresholds(&power, &exclude, &mut t);
        assert!(t[32] > 1e4);
        exclude[37] = true;
        cfar.thresholds(&power, &exclude, &mut t);
        assert!(
            (t[32] - alpha_ca_samples(1e-3, 16.0)).abs() < 1e-9,
            "{}",
            t[32]
        );
    }

    #[test]
    fn global_estimate_and_bad_parameters() {
        let mut rng = SplitMix64::new(7);
        let power = exp_noise(&mut rng, 20_000);
        let exclude = vec![false; power.len()];
        let (s2, alpha) = global_noise(&power, &exclude, 1.0, 1e-6, &mut Vec::new()).unwrap();
        assert!((s2 - 1.0).abs() < 0.05, "{s2}");
        assert!(alpha > 6f64.ln() * 2.0 && alpha < 14.5, "{alpha}");
        assert!(global_noise(&power[..3], &exclude[..3], 1.0, 1e-6, &mut Vec::new()).is_none());
        assert!(LocalCfar::new(CfarKind::Ca, 1, 0, 1, 1e-3).is_err());
        assert!(LocalCfar::new(CfarKind::Os { rank: 0.0 }, 1, 4, 1, 1e-3).is_err());
    }
}
