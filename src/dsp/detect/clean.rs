//! The CLEAN detector ([`Method::Clean`]): subtract the strongest fitted target, repeat; then
//! the targets whose main lobe does not fit the model, and the pruning of targets that no longer
//! pass their threshold.

use super::*;

impl Detector {
    /// The CLEAN loop; returns whether it stopped at the target limit.
    pub(super) fn clean(&mut self, z: &[Complex64], fitw: &FitWindow, min_sep: f64) -> bool {
        let n = z.len();
        let max_iterations = 2 * self.options.max_targets + 8;
        for _ in 0..max_iterations {
            self.model.rebuild(self.psf.as_ref(), n);
            self.model.residual(z, &mut self.residual);
            self.thresholds(n);
            let best = self.best_candidate(min_sep);
            let Some(c) = best else {
                return false;
            };
            if self.model.comps.len() >= self.options.max_targets {
                return true;
            }
            let x_init = parabolic(&self.power, c);
            let psf = self.psf.as_ref();
            let newest = self.model.add(psf, z, x_init, fitw);
            self.model.refine(psf, z, fitw, MAX_SWEEPS);
            if self.merge_close(min_sep) {
                self.rejected.push(x_init);
                self.model.refine(self.psf.as_ref(), z, fitw, MAX_SWEEPS);
            } else if self.is_chain_echo(z, newest) {
                self.model.comps.remove(newest);
                self.rejected.push(x_init);
                self.model.refine(self.psf.as_ref(), z, fitw, MAX_SWEEPS);
            }
        }
        false
    }

    /// Whether the newest component lies under the chain floor of a stronger one whose main lobe,
    /// with the newest fitted, does not certify the model: that one then joins `mismatched` (its
    /// floor keeps its further echoes from being searched at all).
    pub(super) fn is_chain_echo(&mut self, z: &[Complex64], newest: usize) -> bool {
        let rho = 10f64.powf(self.options.chain_floor_db / 10.0);
        let new = self.model.comps[newest];
        let suspects: Vec<usize> = (0..self.model.comps.len())
            .filter(|&i| {
                let c = self.model.comps[i];
                i != newest
                    && (c.x - new.x).abs() <= 2.0 * self.chain_extent
                    && new.a.norm_sqr() < rho * c.a.norm_sqr()
                    && !self.mismatched.iter().any(|(x, _)| (x - c.x).abs() < 1.0)
            })
            .collect();
        if suspects.is_empty() {
            return false;
        }
        let n = z.len();
        self.model.rebuild(self.psf.as_ref(), n);
        self.model.residual(z, &mut self.residual);
        self.thresholds(n);
        let noise = self.noise_power();
        let mut echo = false;
        for i in suspects {
            let c = self.model.comps[i];
            if !self.certifies(c, noise) {
                self.mismatched.push((c.x, c.a.norm_sqr()));
                echo = true;
            }
        }
        echo && self.chain_floor(new.x, Some(new.x)) > new.a.norm_sqr()
    }

    /// After the CLEAN search, with every candidate fitted: adds the targets whose main lobe does
    /// not certify the model ([`Detector::certifies`]) to those the search found; around them the
    /// chain's echoes cannot be told from targets, and the chain floor stands.
    pub(super) fn find_mismatch(&mut self, z: &[Complex64]) {
        let n = z.len();
        self.model.rebuild(self.psf.as_ref(), n);
        self.model.residual(z, &mut self.residual);
        self.thresholds(n);
        let noise = self.noise_power();
        for i in 0..self.model.comps.len() {
            let c = self.model.comps[i];
            let known = self.mismatched.iter().any(|(x, _)| (x - c.x).abs() < 1.0);
            if !known && !self.certifies(c, noise) {
                self.mismatched.push((c.x, c.a.norm_sqr()));
            }
        }
    }

    /// Drops fitted targets that no longer pass their threshold (noise plus the others' floors)
    /// once everything is fitted, weakest first, re-fitting after each drop.
    pub(super) fn prune(&mut self, z: &[Complex64], fitw: &FitWindow) {
        let n = z.len();
        loop {
            self.model.rebuild(self.psf.as_ref(), n);
            self.model.residual(z, &mut self.residual);
            self.thresholds(n);
            let rho = 10f64.powf(self.options.model_floor_db / 10.0);
            let weakest_failing = (0..self.model.comps.len())
                .filter(|&i| {
                    let c = self.model.comps[i];
                    let cell = (c.x.round().max(0.0) as usize).min(n - 1);
                    c.a.norm_sqr() <= self.others_threshold(i, cell, rho)
                })
                .min_by(|&a, &b| {
                    self.model.comps[a]
                        .a
                        .norm()
                        .total_cmp(&self.model.comps[b].a.norm())
                });
            match weakest_failing {
                Some(i) => {
                    self.model.comps.remove(i);
                    self.model.refine(self.psf.as_ref(), z, fitw, MAX_SWEEPS);
                }
                None => return,
            }
        }
    }

    /// The strongest residual peak over its threshold, away from fitted and rejected targets.
    pub(super) fn best_candidate(&self, min_sep: f64) -> Option<usize> {
        let near = |c: usize, x: f64| (c as f64 - x).abs() < min_sep;
        (0..self.power.len())
            .filter(|&c| self.power[c] > self.threshold[c] && is_peak(&self.power, c))
            .filter(|&c| {
                !self.model.comps.iter().any(|k| near(c, k.x))
                    && !self.rejected.iter().any(|&x| near(c, x))
            })
            .max_by(|&a, &b| self.power[a].total_cmp(&self.power[b]))
    }

    /// Whether target `c`'s inner main lobe (within half the -3 dB width) certifies the model
    /// against the current residual: the residual there is under [`MISFIT_EXACT_DB`] of the
    /// target's energy, and the noise (per cell `noise`) would have let a misfit that size show.
    pub(super) fn certifies(&mut self, c: fit::Component, noise: f64) -> bool {
        let n = self.residual.len();
        let w = 0.5 * self.shape.width_3db;
        let lo = (c.x - w).ceil().max(0.0) as usize;
        let hi = ((c.x + w).floor().max(0.0) as usize).min(n - 1);
        if hi < lo {
            return true;
        }
        self.g.resize(hi + 1 - lo, Complex64::default());
        self.psf.response(c.x, lo as isize, &mut self.g);
        let left: f64 = self.residual[lo..=hi].iter().map(|v| v.norm_sqr()).sum();
        let own: f64 = self.g.iter().map(|v| (c.a * v).norm_sqr()).sum();
        let cells = (hi + 1 - lo) as f64;
        let exact = 10f64.powf(MISFIT_EXACT_DB / 10.0);
        left <= exact * own && MISFIT_NOISE_FACTOR * noise * cells <= exact * own
    }
}
