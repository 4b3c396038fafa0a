//! Everything a plan needs prepared before anything is connected: transmissions generated,
//! options checked, instrument settings planned against the catalog, pipelines built.

use super::plan::{BenchInfo, Plan};
use super::CampaignError;
use crate::catalog::Catalog;
use crate::measure::capture::{self, Prepared};

/// Every (waveform, algorithm) prepared, and for `music_p = "targets"` every (waveform,
/// subspace algorithm, model order) the steps need: transmissions generated, options checked,
/// instrument settings planned against the catalog, pipelines built. Touches no instrument.
pub struct PreparedSet {
    /// `[waveform][algorithm]`.
    pub base: Vec<Vec<Prepared>>,
    /// `(waveform, algorithm, p)` for the steps' own model orders.
    pub(super) ordered: Vec<((usize, usize, usize), Prepared)>,
}

impl PreparedSet {
    /// The preparation for waveform `w`, algorithm `a` at a step whose model order is `p`.
    pub(super) fn get_mut(&mut self, w: usize, a: usize, p: Option<usize>) -> &mut Prepared {
        if let Some(p) = p {
            if let Some(i) = self.ordered.iter().position(|(k, _)| *k == (w, a, p)) {
                return &mut self.ordered[i].1;
            }
        }
        &mut self.base[w][a]
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
    let mut ordered: Vec<((usize, usize, usize), Prepared)> = Vec::new();
    for step in &plan.steps {
        let Some(p) = step.music_p else { continue };
        for (a, o) in plan.processing.iter().enumerate() {
            let key = (step.waveform, a, p);
            if !o.algorithm.is_subspace() || ordered.iter().any(|(k, _)| *k == key) {
                continue;
            }
            let mut options = o.clone();
            options.music_p = Some(p);
            let prepared = base[step.waveform][0].with_options(options).await?;
            ordered.push((key, prepared));
        }
    }
    Ok(PreparedSet { base, ordered })
}
