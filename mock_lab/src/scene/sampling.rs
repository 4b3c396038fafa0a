//! The capture grid: what puts the transmitted segment on it, and the scope's sampling instants
//! when its timebase or its Q channel is off (timebase offset, Rx I/Q skew).

use num_complex::Complex64;

use super::chain::{cubic_at, ChainParams};

/// What puts the transmitted segment on the capture grid.
pub(super) struct ToGrid<'a> {
    pub(super) spectrum: &'a [Complex64],
    pub(super) fs_awg: f64,
    pub(super) up: usize,
    /// Segment time of the grid's first sample, seconds.
    pub(super) t0: f64,
    pub(super) gain: f64,
}

/// Where the scope samples the true signal: a scope timebase running `eps` fast against the
/// AWG's takes its sample `n` at true time `(a + n)(1 - eps)` samples after the trigger (`a` its
/// offset from the trigger in samples); an Rx skew takes Q `skew` samples later still.
pub(super) struct Warp {
    /// Grid start, samples after the trigger (integer).
    pub(super) start: f64,
    /// Grid length.
    pub(super) len: usize,
    points: usize,
    offset: f64,
    eps: f64,
    skew: f64,
}

impl Warp {
    pub(super) fn new(
        chain: &ChainParams,
        horiz_offset: f64,
        fs: f64,
        points: usize,
    ) -> Option<Warp> {
        let eps = chain.timebase_error();
        let skew = chain.rx_iq_skew_ps * 1e-12 * fs;
        if eps == 0.0 && skew == 0.0 {
            return None;
        }
        let offset = horiz_offset * fs;
        let ends = [offset * (1.0 - eps), (offset + points as f64) * (1.0 - eps)];
        let lo = ends[0].min(ends[1]) - skew.abs() - 3.0;
        let hi = ends[0].max(ends[1]) + skew.abs() + 3.0;
        let start = lo.floor();
        Some(Warp {
            start,
            len: (hi.ceil() - start) as usize + 1,
            points,
            offset,
            eps,
            skew,
        })
    }

    /// The scope's samples from the grid.
    pub(super) fn apply(&self, grid: &[Complex64], out: &mut Vec<Complex64>) {
        out.clear();
        if self.eps == 0.0 {
            // A skew alone: every sample is a fixed fractional shift, with fixed weights.
            let at = self.offset - self.start;
            let i_at = cubic_weights(at);
            let q_at = cubic_weights(at - self.skew);
            let tap = |(base, t, w): (isize, f64, [f64; 4]),
                       n: usize,
                       part: fn(Complex64) -> f64| {
                let k = base + n as isize;
                if k >= 1 && k as usize + 2 < grid.len() {
                    let g = &grid[k as usize - 1..k as usize + 3];
                    w[0] * part(g[0]) + w[1] * part(g[1]) + w[2] * part(g[2]) + w[3] * part(g[3])
                } else {
                    part(cubic_at(grid, k as f64 + t))
                }
            };
            out.extend(
                (0..self.points)
                    .map(|n| Complex64::new(tap(i_at, n, |v| v.re), tap(q_at, n, |v| v.im))),
            );
            return;
        }
        out.extend((0..self.points).map(|n| {
            let at = (self.offset + n as f64) * (1.0 - self.eps) - self.start;
            Complex64::new(cubic_at(grid, at).re, cubic_at(grid, at - self.skew).im)
        }));
    }
}

/// The integer base, the fraction and the four Catmull-Rom weights (for samples base-1 ..=
/// base+2) of the position `pos`, as [`cubic_at`] uses them.
fn cubic_weights(pos: f64) -> (isize, f64, [f64; 4]) {
    let base = pos.floor();
    let t = pos - base;
    let (t2, t3) = (t * t, t * t * t);
    let w = [
        0.5 * (-t + 2.0 * t2 - t3),
        0.5 * (2.0 - 5.0 * t2 + 3.0 * t3),
        0.5 * (t + 4.0 * t2 - 3.0 * t3),
        0.5 * (-t2 + t3),
    ];
    (base as isize, t, w)
}
