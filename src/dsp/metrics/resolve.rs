//! The "resolved" rule of thesis-notes.md: one peak with at least 3 dB prominence within +-s/2 of
//! each true range.

use super::axis::Axis;
use super::db::to_db;
use super::peaks::{find_peaks, interpolate_peak, Interpolation};

/// Whether a profile resolves a set of targets, and which peak stands for each target.
#[derive(Debug, Clone, PartialEq)]
pub struct Resolution {
    /// Every target has its own peak.
    pub resolved: bool,
    /// For each target (in the order given), the interpolated position of the highest qualifying
    /// peak in its window, in axis units (metres), or `None`.
    pub peaks: Vec<Option<f64>>,
}

/// Applies the rule to a linear-amplitude profile on `axis`.
///
/// A target's window is +-s/2 around it, s being the distance to its nearest neighbour among the
/// targets (the whole profile for a single target), so windows never overlap and a peak can count
/// for one target only. A peak qualifies when its prominence on the dB profile is at least
/// `min_prominence_db` (3 dB in the thesis). Positions are interpolated with `interpolation`.
pub fn resolve_targets(
    axis: Axis,
    amplitude: &[f64],
    targets: &[f64],
    min_prominence_db: f64,
    interpolation: Interpolation,
) -> Resolution {
    let mut db = vec![0.0; amplitude.len()];
    to_db(amplitude, &mut db);
    let peaks = find_peaks(&db, min_prominence_db);
    let found: Vec<Option<f64>> = targets
        .iter()
        .enumerate()
        .map(|(i, &r)| {
            let half = targets
                .iter()
                .enumerate()
                .filter(|&(j, _)| j != i)
                .map(|(_, &o)| (o - r).abs())
                .fold(f64::INFINITY, f64::min)
                / 2.0;
            peaks
                .iter()
                .filter(|p| {
                    let x = axis.at(p.index as f64);
                    x >= r - half && x < r + half
                })
                .max_by(|a, b| a.value.total_cmp(&b.value))
                .map(|p| axis.at(interpolate_peak(amplitude, p.index, interpolation).0))
        })
        .collect();
    Resolution {
        resolved: !targets.is_empty() && found.iter().all(Option::is_some),
        peaks: found,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn two_gaussians(a: f64, b: f64, width: f64) -> Vec<f64> {
        (0..400)
            .map(|i| {
                let x = i as f64 * 0.01;
                (-((x - a) / width).powi(2)).exp() + (-((x - b) / width).powi(2)).exp() + 1e-3
            })
            .collect()
    }

    #[test]
    fn separated_lobes_resolve_and_merged_ones_do_not() {
        let axis = Axis {
            start: 0.0,
            step: 0.01,
        };
        let wide = two_gaussians(1.0, 2.0, 0.2);
        let r = resolve_targets(axis, &wide, &[1.0, 2.0], 3.0, Interpolation::Parabolic);
        assert!(r.resolved);
        assert!((r.peaks[0].unwrap() - 1.0).abs() < 0.01);
        let merged = two_gaussians(1.0, 1.1, 0.2);
        let r = resolve_targets(axis, &merged, &[1.0, 1.1], 3.0, Interpolation::Parabolic);
        assert!(!r.resolved, "{r:?}");
    }
}
