//! A run's figures in the order the report shows them: the swept kinds' own (the kinds' table,
//! campaign/kind.rs, names them) around those every run gets (figures.rs draws both).

use super::figures::{is_resolution, resolution, single_target, Figure};
use crate::campaign::kind::{has_own_figures, kind_figures};
use crate::campaign::manifest::Manifest;
use crate::campaign::results::{Results, StepResult};

/// The figures of a run, in the order the report shows them.
pub fn figures(manifest: &Manifest, results: &Results) -> Vec<Figure> {
    let steps = &results.steps;
    // The swept kinds' own figures (campaign/kind.rs names them), around those every run gets.
    let mut out = kind_figures(manifest, steps, true);
    let pick = |f: fn(&StepResult) -> bool| steps.iter().filter(|s| f(s)).collect::<Vec<_>>();
    let res = pick(is_resolution);
    if !res.is_empty() {
        out.extend(resolution(&res));
    }
    let single = pick(is_single);
    if !single.is_empty() {
        out.extend(single_target(manifest, &single));
    }
    out.extend(kind_figures(manifest, steps, false));
    out
}

/// One target, swept in a parameter without figures of its own (campaign/kind.rs).
pub(crate) fn is_single(s: &StepResult) -> bool {
    s.nominal.targets.len() == 1 && !has_own_figures(s)
}
