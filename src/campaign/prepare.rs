//! Everything a plan needs prepared before anything is connected: transmissions generated,
//! options checked, instrument settings planned against the catalog, pipelines built.

use super::error::CampaignError;
use super::plan::{BenchInfo, Plan, WaveformCost};
use crate::catalog::Catalog;
use crate::measure::capture::{self, Prepared};

/// (waveform, processing variant, algorithm, model order of the steps that set their own).
pub(super) type PreparedKey = (usize, usize, usize, Option<usize>);

/// Every (waveform, algorithm) prepared, every (waveform, processing variant, algorithm) the
/// steps that set their own window or algorithm need, and for `music_p = "targets"` every
/// (waveform, variant, subspace algorithm, model order): transmissions generated, options
/// checked, instrument settings planned against the catalog, pipelines built. Touches no
/// instrument.
pub struct PreparedSet {
    /// `[waveform][algorithm]` of the plan's own processing.
    pub base: Vec<Vec<Prepared>>,
    /// The others, by key.
    pub(super) more: Vec<(PreparedKey, Prepared)>,
}

impl PreparedSet {
    /// What the plan needs to know of each prepared waveform to estimate a step.
    pub fn costs(&self) -> Vec<WaveformCost> {
        self.base
            .iter()
            .map(|p| {
                let c = &p[0].plan;
                WaveformCost {
                    samples: c.period,
                    points: c.period * c.decimation,
                    capture_rate_hz: c.scope.sample_rate_hz,
                }
            })
            .collect()
    }

    /// The preparation for waveform `w`, variant `v`, algorithm `a` at a step whose model order
    /// is `p`.
    pub(super) fn get_mut(
        &mut self,
        w: usize,
        v: usize,
        a: usize,
        p: Option<usize>,
    ) -> &mut Prepared {
        let key = Self::key_in(&self.more, (w, v, a, p));
        match key.and_then(|k| self.more.iter().position(|(x, _)| *x == k)) {
            Some(i) => &mut self.more[i].1,
            None => &mut self.base[w][a],
        }
    }

    /// The key `want` is prepared under: itself, or without its model order; `None`: the base.
    fn key_in(more: &[(PreparedKey, Prepared)], want: PreparedKey) -> Option<PreparedKey> {
        let has = |k: PreparedKey| more.iter().any(|(x, _)| *x == k);
        if has(want) {
            return Some(want);
        }
        let (w, v, a, _) = want;
        has((w, v, a, None)).then_some((w, v, a, None))
    }
}

/// Prepares everything a plan needs (see `PreparedSet`).
pub async fn prepare_all(
    plan: &Plan,
    bench: &BenchInfo,
    catalog: &Catalog,
) -> Result<PreparedSet, CampaignError> {
    let planning = plan
        .bench
        .planning_bench(bench.file.as_ref().map(|(_, f)| f));
    let mut base = Vec::with_capacity(plan.waveforms.len());
    for w in 0..plan.waveforms.len() {
        let first = capture::prepare(&planning, catalog, &plan.request(w)).await?;
        let mut all = Vec::with_capacity(plan.processing.len());
        for o in &plan.processing[1..] {
            all.push(first.with_options(o.clone()).await?);
        }
        all.insert(0, first);
        base.push(all);
    }
    let mut more: Vec<(PreparedKey, Prepared)> = Vec::new();
    for step in &plan.steps {
        let (w, v) = (step.waveform, step.processing);
        for (a, o) in plan.processing_of(v).iter().enumerate() {
            if v != 0 && !more.iter().any(|(k, _)| *k == (w, v, a, None)) {
                let prepared = base[w][0].with_options(o.clone()).await?;
                more.push(((w, v, a, None), prepared));
            }
            let Some(p) = step.music_p else { continue };
            let key = (w, v, a, Some(p));
            if !o.algorithm.is_subspace() || more.iter().any(|(k, _)| *k == key) {
                continue;
            }
            let mut options = o.clone();
            options.music_p = Some(p);
            let prepared = base[w][0].with_options(options).await?;
            more.push((key, prepared));
        }
    }
    Ok(PreparedSet { base, more })
}
