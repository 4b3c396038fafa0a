//! The CFAR detector ([`Method::Cfar`]): peaks over a sliding-window threshold, twice.
//! A peak under a stronger one's side-lobe envelope, or under the calibration's residual
//! profile around it ([`DetectOptions::residual_floor`]), is that one's, not a target.

use super::*;

impl Detector {
    /// Peaks over a CFAR threshold, twice (training cells near the first pass's peaks excluded
    /// the second time), side-lobes masked by the envelope; then fitted jointly. Returns whether
    /// the target limit cut the list.
    pub(super) fn cfar(&mut self, z: &[Complex64], fitw: &FitWindow, min_sep: f64) -> bool {
        let n = z.len();
        self.residual.clear();
        self.residual.extend_from_slice(z);
        self.power.clear();
        self.power.extend(z.iter().map(|v| v.norm_sqr()));
        self.exclude.clear();
        self.exclude.resize(n, false);
        self.noise_thr.resize(n, 0.0);
        let guard = self.shape.first_null;
        let local = self.local.as_mut().expect("a CFAR method has its CFAR");
        let mut peaks: Vec<usize> = Vec::new();
        for pass in 0..2 {
            if pass == 1 {
                for &p in &peaks {
                    mark(&mut self.exclude, p as f64, guard);
                }
            }
            local.thresholds(&self.power, &self.exclude, &mut self.noise_thr);
            peaks.clear();
            peaks.extend(
                (0..n).filter(|&c| is_peak(&self.power, c) && self.power[c] > self.noise_thr[c]),
            );
        }
        peaks.sort_by(|&a, &b| self.power[b].total_cmp(&self.power[a]));
        let margin = 10f64.powf(self.options.sidelobe_margin_db / 10.0);
        let mut kept: Vec<usize> = Vec::new();
        for &c in &peaks {
            let masked = kept.iter().any(|&k| {
                let d = (c as f64 - k as f64).abs();
                let mask = self.shape.envelope_at(d) * margin + self.residual_at(c, k);
                d < min_sep || self.power[c] < self.power[k] * mask
            });
            if !masked {
                kept.push(c);
            }
        }
        let capped = kept.len() > self.options.max_targets;
        kept.truncate(self.options.max_targets);
        let psf = self.psf.as_ref();
        for &c in &kept {
            let x_init = parabolic(&self.power, c);
            self.model.add(psf, z, x_init, fitw);
        }
        self.model.refine(psf, z, fitw, MAX_SWEEPS);
        self.merge_close(min_sep);
        // The reported threshold: the CFAR's, raised to the side-lobe mask of the kept peaks
        // (and the calibration's residual around them, where there is one).
        self.threshold.clear();
        self.threshold.extend_from_slice(&self.noise_thr);
        for &k in &kept {
            for c in 0..n {
                let d = (c as f64 - k as f64).abs();
                if d >= 1.0 {
                    let mask = self.shape.envelope_at(d) * margin + self.residual_at(c, k);
                    self.threshold[c] = self.threshold[c].max(self.power[k] * mask);
                }
            }
        }
        // Residual, its power and the cells near targets, for the noise estimate of the report.
        self.model.rebuild(self.psf.as_ref(), n);
        self.model.residual(z, &mut self.residual);
        self.power.clear();
        self.power
            .extend(self.residual.iter().map(|v| v.norm_sqr()));
        self.exclude.fill(false);
        for c in &self.model.comps {
            mark(&mut self.exclude, c.x, self.shape.first_null);
        }
        capped
    }
}
