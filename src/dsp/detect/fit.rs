//! Point targets fitted to a complex profile with a known point spread: sub-cell position and
//! complex amplitude by least squares, refined jointly (RELAX: each target in turn against the
//! profile minus all the others, until nothing moves).

use num_complex::Complex64;

use super::psf::PointSpread;

const ZERO: Complex64 = Complex64 { re: 0.0, im: 0.0 };

/// One fitted point target: position in (fractional) cells and complex amplitude.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) struct Component {
    pub x: f64,
    pub a: Complex64,
}

/// The fitted targets of one profile and the scratch to fit them.
#[derive(Debug, Default)]
pub(super) struct Model {
    pub comps: Vec<Component>,
    /// `sum_i a_i g(c - x_i)` over the profile (valid after [`Model::rebuild`]).
    pub model: Vec<Complex64>,
    data: Vec<Complex64>,
    g: Vec<Complex64>,
    full: Vec<Complex64>,
}

/// How a fit searches: cells each side of the target used, the bracket on the position, and the
/// positions allowed.
#[derive(Debug, Clone, Copy)]
pub(super) struct FitWindow {
    pub half_width: usize,
    pub bracket: f64,
    pub lowest: f64,
    pub highest: f64,
}

impl Model {
    pub(super) fn clear(&mut self) {
        self.comps.clear();
    }

    /// The data `z - sum_{j != skip} a_j g(c - x_j)` on cells `first..first + len` into `self.data`.
    fn window_data(
        &mut self,
        psf: &dyn PointSpread,
        z: &[Complex64],
        first: usize,
        len: usize,
        skip: Option<usize>,
    ) {
        self.data.clear();
        self.data.extend_from_slice(&z[first..first + len]);
        self.g.resize(len, ZERO);
        for (j, c) in self.comps.iter().enumerate() {
            if Some(j) == skip {
                continue;
            }
            psf.response(c.x, first as isize, &mut self.g);
            for (d, g) in self.data.iter_mut().zip(&self.g) {
                *d -= c.a * g;
            }
        }
    }

    /// Least-squares fit of one target to `self.data` (cells from `first`): maximises
    /// `|<g_x, d>|^2 / |g_x|^2` over `x` in the bracket by golden section, then `a = <g_x, d> /
    /// |g_x|^2`.
    fn fit_data(
        &mut self,
        psf: &dyn PointSpread,
        first: usize,
        x_init: f64,
        w: &FitWindow,
    ) -> Component {
        let len = self.data.len();
        self.g.resize(len, ZERO);
        let score = |x: f64, g: &mut Vec<Complex64>| -> (f64, Complex64) {
            psf.response(x, first as isize, g);
            let mut dot = ZERO;
            let mut norm = 0.0;
            for (gv, d) in g.iter().zip(&self.data) {
                dot += gv.conj() * d;
                norm += gv.norm_sqr();
            }
            if norm <= 0.0 {
                return (0.0, ZERO);
            }
            (dot.norm_sqr() / norm, dot / norm)
        };
        let mut g = std::mem::take(&mut self.g);
        let mut a = (x_init - w.bracket).max(w.lowest);
        let mut b = (x_init + w.bracket).min(w.highest);
        if b <= a {
            b = a + 1e-9;
        }
        let r = (5f64.sqrt() - 1.0) / 2.0;
        let mut c = b - r * (b - a);
        let mut d = a + r * (b - a);
        let (mut fc, mut fd) = (score(c, &mut g).0, score(d, &mut g).0);
        while b - a > 1e-5 {
            if fc > fd {
                b = d;
                d = c;
                fd = fc;
                c = b - r * (b - a);
                fc = score(c, &mut g).0;
            } else {
                a = c;
                c = d;
                fc = fd;
                d = a + r * (b - a);
                fd = score(d, &mut g).0;
            }
        }
        let x = 0.5 * (a + b);
        let (_, amp) = score(x, &mut g);
        self.g = g;
        Component { x, a: amp }
    }

    /// The cells of the fit window around `x` (clipped to the profile).
    fn span(x: f64, w: &FitWindow, n: usize) -> (usize, usize) {
        let centre = x.round() as isize;
        let lo = (centre - w.half_width as isize).clamp(0, n as isize - 1) as usize;
        let hi = (centre + w.half_width as isize).clamp(0, n as isize - 1) as usize;
        (lo, hi + 1 - lo)
    }

    /// Fits a new target near `x_init` against the profile minus the current ones and adds it.
    pub(super) fn add(
        &mut self,
        psf: &dyn PointSpread,
        z: &[Complex64],
        x_init: f64,
        w: &FitWindow,
    ) -> usize {
        let (first, len) = Self::span(x_init, w, z.len());
        self.window_data(psf, z, first, len, None);
        let c = self.fit_data(psf, first, x_init, w);
        self.comps.push(c);
        self.comps.len() - 1
    }

    /// RELAX: re-fits every target against the profile minus the others, sweep after sweep, until
    /// no position moves more than 1e-4 cells and no amplitude by more than 1e-5 relative (at most
    /// `max_sweeps`). Returns the sweeps made.
    pub(super) fn refine(
        &mut self,
        psf: &dyn PointSpread,
        z: &[Complex64],
        w: &FitWindow,
        max_sweeps: usize,
    ) -> usize {
        for sweep in 1..=max_sweeps {
            let mut moved = false;
            for i in 0..self.comps.len() {
                let old = self.comps[i];
                let (first, len) = Self::span(old.x, w, z.len());
                self.window_data(psf, z, first, len, Some(i));
                let new = self.fit_data(psf, first, old.x, w);
                if (new.x - old.x).abs() > 1e-4 || (new.a - old.a).norm() > 1e-5 * old.a.norm() {
                    moved = true;
                }
                self.comps[i] = new;
            }
            if !moved {
                return sweep;
            }
        }
        max_sweeps
    }

    /// Recomputes `self.model` over `n` cells.
    pub(super) fn rebuild(&mut self, psf: &dyn PointSpread, n: usize) {
        self.model.clear();
        self.model.resize(n, ZERO);
        self.full.resize(n, ZERO);
        for c in &self.comps {
            psf.response(c.x, 0, &mut self.full);
            for (m, g) in self.model.iter_mut().zip(&self.full) {
                *m += c.a * g;
            }
        }
    }

    /// `out = z - model` (after [`Model::rebuild`]).
    pub(super) fn residual(&self, z: &[Complex64], out: &mut Vec<Complex64>) {
        out.clear();
        out.extend(z.iter().zip(&self.model).map(|(a, b)| a - b));
    }
}
