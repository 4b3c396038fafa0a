//! A run's figures in the order the report shows them: the swept kinds' own (the kinds' table,
//! campaign/kind.rs, names them) around those every run gets (figures.rs draws both).

use super::figures::{self, is_resolution, resolution, single_target, Figure};
use crate::campaign::axis::SweepParameter;
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

/// A kind's own figures and where the report shows them.
#[derive(Clone, Copy)]
struct KindFigures {
    /// Before the figures every run gets (`true`), or after them.
    first: bool,
    draw: fn(&Manifest, &[&StepResult]) -> Vec<Figure>,
}

/// The figures of the steps swept in a kind; `None`: only the figures every run gets
/// (resolution for two targets, width and side lobes for one). The kinds' own table
/// (campaign/kind.rs) says which `results.json` metrics these read.
fn own_figures(p: SweepParameter) -> Option<KindFigures> {
    const LINK: KindFigures = KindFigures {
        first: false,
        draw: figures::link_figures,
    };
    match p {
        SweepParameter::Position => Some(KindFigures {
            first: true,
            draw: |m, s| figures::accuracy(m, s).into_iter().collect(),
        }),
        SweepParameter::Separation | SweepParameter::Bandwidth => None,
        SweepParameter::TxAttenuation | SweepParameter::Snr => Some(LINK),
        SweepParameter::Velocity => Some(KindFigures {
            first: false,
            draw: |m, s| figures::velocity(m, s).into_iter().collect(),
        }),
    }
}

/// The figures of every kind that has its own, for the steps swept in it, `first` or after.
fn kind_figures(manifest: &Manifest, steps: &[StepResult], first: bool) -> Vec<Figure> {
    let mut out = Vec::new();
    for p in SweepParameter::ALL {
        let Some(f) = own_figures(p).filter(|f| f.first == first) else {
            continue;
        };
        let mine: Vec<&StepResult> = steps
            .iter()
            .filter(|s| s.nominal.parameter == Some(p))
            .collect();
        if !mine.is_empty() {
            out.extend((f.draw)(manifest, &mine));
        }
    }
    out
}

/// Whether a step's kind has figures of its own.
fn has_own_figures(s: &StepResult) -> bool {
    s.nominal.parameter.and_then(own_figures).is_some()
}
