//! The report of a detection, built from the final model.

use super::*;

impl Detector {
    /// The report for the final model (residual and thresholds are current).
    pub(super) fn report(
        &mut self,
        z: &[Complex64],
        axis: Axis,
        window: RangeInclusive<f64>,
        capped: bool,
    ) -> Detections {
        let n = z.len();
        let noise_power = global_noise(
            &self.power,
            &self.exclude,
            self.shape.noise_cells,
            self.options.pfa,
            &mut self.scratch,
        )
        .map(|(s2, _)| s2);
        let rho = 10f64.powf(self.options.model_floor_db / 10.0);
        let mut targets = Vec::new();
        let mut outside = Vec::new();
        for i in 0..self.model.comps.len() {
            let c = self.model.comps[i];
            let cell = (c.x.round().max(0.0) as usize).min(n - 1);
            let p = c.a.norm_sqr();
            // What the target had to pass: CLEAN's threshold less its own floors; the CFAR's.
            let others = match self.options.method {
                Method::Clean { .. } => self.others_threshold(i, cell, rho),
                Method::Cfar { .. } => self.noise_thr[cell],
            }
            .max(1e-300);
            let (width_3db_m, sidelobes) = self.own_metrics(i, noise_power, axis);
            let t = DetectedTarget {
                range_m: axis.at(c.x),
                cell: c.x,
                amplitude: c.a,
                level_db: 10.0 * p.max(1e-300).log10(),
                phase_deg: c.a.arg().to_degrees(),
                snr_db: noise_power
                    .filter(|&s| s > 0.0)
                    .map(|s| 10.0 * (p / s).log10()),
                above_threshold_db: 10.0 * (p / others).log10(),
                width_3db_m,
                sidelobes,
            };
            if window.contains(&t.range_m) {
                targets.push(t);
            } else {
                outside.push(t);
            }
        }
        targets.sort_by(|a, b| a.range_m.total_cmp(&b.range_m));
        outside.sort_by(|a, b| a.range_m.total_cmp(&b.range_m));
        Detections {
            targets,
            outside,
            threshold: self.threshold.iter().map(|t| t.max(0.0).sqrt()).collect(),
            noise_power,
            residual: self.residual.clone(),
            capped,
        }
    }

    /// -3 dB width (m) and side-lobes of target `i`'s own response.
    pub(super) fn own_metrics(
        &mut self,
        i: usize,
        noise: Option<f64>,
        axis: Axis,
    ) -> (Option<f64>, Sidelobes) {
        let n = self.residual.len();
        let c = self.model.comps[i];
        let span = self.shape.psl_span;
        let lo = (c.x - span).floor();
        let hi = (c.x + span).ceil();
        let at_edge = lo < 0.0 || hi > (n - 1) as f64;
        let lo = lo.max(0.0) as usize;
        let hi = (hi.min((n - 1) as f64)) as usize;
        if hi < lo + 2 {
            return (None, Sidelobes::AtEdge);
        }
        self.g.resize(hi + 1 - lo, Complex64::default());
        self.psf.response(c.x, lo as isize, &mut self.g);
        self.own.clear();
        self.own.extend(
            self.residual[lo..=hi]
                .iter()
                .zip(&self.g)
                .map(|(r, g)| (r + c.a * g).norm()),
        );
        let mut peak = ((c.x.round() as isize - lo as isize).clamp(0, (hi - lo) as isize)) as usize;
        // Climb to the local maximum (the fitted position is within a fraction of a cell of it).
        loop {
            let up = (peak + 1 < self.own.len() && self.own[peak + 1] > self.own[peak])
                .then(|| peak + 1);
            let down = (peak > 0 && self.own[peak - 1] > self.own[peak]).then(|| peak - 1);
            match up.or(down) {
                Some(p) => peak = p,
                None => break,
            }
        }
        let (_, height) = crate::dsp::interpolate_peak(&self.own, peak, Interpolation::ParabolicDb);
        let width = width_3db(&self.own, peak, height).map(|w| w * axis.step);
        let p = c.a.norm_sqr();
        let psl_lin = 10f64.powf(self.shape.psl_db / 10.0);
        if at_edge {
            return (width, Sidelobes::AtEdge);
        }
        if let Some(s) = noise {
            if p * psl_lin < 10.0 * s {
                return (
                    width,
                    Sidelobes::BelowNoise {
                        noise_db: 10.0 * (p / s).log10(),
                    },
                );
            }
        }
        let rho = 10f64.powf(self.options.model_floor_db / 10.0);
        let shared = self
            .model
            .comps
            .iter()
            .enumerate()
            .filter(|&(j, _)| j != i)
            .map(|(_, o)| {
                let d = ((o.x - c.x).abs() - span).max(0.0);
                (rho * o.a.norm_sqr() * self.shape.envelope_at(d), o)
            })
            .filter(|(u, _)| *u > p * psl_lin / 10.0)
            .max_by(|a, b| a.0.total_cmp(&b.0));
        if let Some((_, o)) = shared {
            return (
                width,
                Sidelobes::Shared {
                    with_range_m: axis.at(o.x),
                    stronger_db: 10.0 * (o.a.norm_sqr() / p).log10(),
                },
            );
        }
        let s = sidelobe_levels(&self.own, peak, Interpolation::ParabolicDb);
        (
            width,
            s.map_or(Sidelobes::Undefined, |s| Sidelobes::Measured {
                psl_db: s.psl_db,
                isl_db: s.isl_db,
            }),
        )
    }
}
