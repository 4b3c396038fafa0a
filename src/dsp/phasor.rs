//! Phasors `e^{j w x}` over points `x` that are mostly evenly spaced (a spectrum's bins), by
//! recurrence: one complex product per point instead of a sine and a cosine, which were most of
//! a response calibration's search for chain echoes. Anchored afresh (an exact `from_polar`)
//! every [`ANCHOR_EVERY`] points and wherever the spacing breaks (a gap in a band, the jump
//! from positive to negative frequencies), so the products add under 1e-13 rad to the rounding
//! of the phase `w x` itself.

use num_complex::Complex64;

/// Points between exact anchors: 64 products add at most ~1e-14 of rounding.
const ANCHOR_EVERY: usize = 64;

/// Calls `each(i, e^{j w x_i})` for every `x_i` of `xs` in order; `unit` is their usual spacing.
pub(crate) fn for_each(
    xs: impl IntoIterator<Item = f64>,
    w: f64,
    unit: f64,
    mut each: impl FnMut(usize, Complex64),
) {
    let turn = Complex64::from_polar(1.0, w * unit);
    let tolerance = 1e-9 * unit.abs();
    let (mut phasor, mut previous) = (Complex64::new(1.0, 0.0), f64::NAN);
    for (i, x) in xs.into_iter().enumerate() {
        phasor = if i % ANCHOR_EVERY != 0 && ((x - previous) - unit).abs() <= tolerance {
            phasor * turn
        } else {
            Complex64::from_polar(1.0, w * x)
        };
        previous = x;
        each(i, phasor);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Against `from_polar` at every point, over evenly spaced points with gaps and a jump, at
    /// phase steps up to a large fraction of a turn.
    #[test]
    fn the_recurrence_matches_the_exact_phasor() {
        let mut xs: Vec<f64> = (0..5000).map(f64::from).collect();
        xs.extend((-5000..-100).map(f64::from));
        xs.retain(|x| (*x as i64) % 977 != 3);
        for w in [1e-6, 0.013, 1.7, -2.9] {
            // `w x` itself is rounded to a relative 1e-16: at thousands of radians, 1e-12 rad.
            let mut worst: f64 = 0.0;
            for_each(xs.iter().copied(), w, 1.0, |i, p| {
                let exact = Complex64::from_polar(1.0, w * xs[i]);
                let allowed = 1e-13 + 4.0 * f64::EPSILON * (w * xs[i]).abs();
                worst = worst.max((p - exact).norm() / allowed);
            });
            assert!(worst < 1.0, "w {w}: off by {worst} of what is allowed");
        }
    }
}
