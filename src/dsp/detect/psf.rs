//! Point-spread functions: the complex response, on a profile's cell grid, of a unit point target.
//!
//! Every profile radbench detects on has the form `z[c] = sum_i a_i g(c - x_i) + noise`, with
//! `g(x) = sum_k S_k exp(j 2 pi nu_k x)` a sum of spectral lines (`nu_k` in cycles per cell):
//!
//! | profile | lines `nu_k` | weights `S_k` |
//! |---|---|---|
//! | correlation over one repetition of P samples | `k / P`, signed `k` | `|REF_k|^2 H_k`, normalised |
//! | OFDM Fourier, K = Z N points | `k / K`, `k = 0..N` (ascending frequency) | the window over its sum |
//!
//! (`H_k`: any extra response the capture went through, e.g. the decimator's pass band.) Weights are
//! normalised so `g(0) = 1`: a target of complex amplitude `a` peaks at `|a|` in the profile.
//!
//! [`SpectralLines`] evaluates `g` by direct summation (exact; cost one complex multiply-add per line
//! and cell). [`TabulatedPsf`] samples `g` once on a grid `1/U` of a cell fine (by FFTs for a DFT
//! spectrum, by direct sums for a few lines) and interpolates with a 4-point Lagrange cubic: a few
//! multiply-adds per cell whatever the number of lines, with `U` chosen from the spectrum so the
//! interpolation error stays below about 1e-6 of the peak (-120 dB).

use num_complex::Complex64;
use std::f64::consts::PI;

use crate::dsp::DspError;

const ZERO: Complex64 = Complex64 { re: 0.0, im: 0.0 };

/// The response of a unit point target on a profile's cell grid.
pub trait PointSpread: Send + Sync {
    /// `g(x)`: the response `x` cells from the target (`g(0) = 1` for a normalised spread).
    fn value(&self, x: f64) -> Complex64;

    /// `out[i] = g(first + i - x0)`: the response on cells `first..first + out.len()` of a unit
    /// target at fractional cell `x0`.
    fn response(&self, x0: f64, first: isize, out: &mut [Complex64]) {
        for (i, o) in out.iter_mut().enumerate() {
            *o = self.value((first + i as isize) as f64 - x0);
        }
    }

    /// The largest `|x|` (cells) at which the response is known; beyond it the spread is taken as
    /// zero. For a periodic spread, half its period.
    fn support(&self) -> f64;
}

/// A point spread given by its spectral lines, summed directly (exact).
#[derive(Debug, Clone)]
pub struct SpectralLines {
    nu: Vec<f64>,
    weight: Vec<Complex64>,
    support: f64,
}

impl SpectralLines {
    /// Lines at `nu` cycles per cell with complex weights `weight`, normalised so `g(0) = 1`.
    /// `support` is half the period for a circular profile, else how far the response matters.
    ///
    /// # Errors
    ///
    /// [`DspError::Param`] when `nu` and `weight` are empty or of different lengths, a value is not
    /// finite, the weights sum to zero, or `support` is below 1.
    pub fn new(nu: Vec<f64>, weight: Vec<Complex64>, support: f64) -> Result<Self, DspError> {
        if nu.is_empty() || nu.len() != weight.len() {
            return Err(DspError::Param(format!(
                "point spread: {} line frequencies and {} weights; give the same, non-zero number",
                nu.len(),
                weight.len()
            )));
        }
        let sum: Complex64 = weight.iter().sum();
        if !(sum.norm() > 0.0 && sum.norm().is_finite()) || nu.iter().any(|v| !v.is_finite()) {
            return Err(DspError::Param(
                "point spread: the weights sum to zero or are not finite, or a frequency is not \
                 finite; give finite weights with a non-zero sum"
                    .into(),
            ));
        }
        if !(support.is_finite() && support >= 1.0) {
            return Err(DspError::Param(format!(
                "point spread: support = {support} cells; allowed: at least 1"
            )));
        }
        let inv = sum.inv();
        Ok(Self {
            nu,
            weight: weight.into_iter().map(|w| w * inv).collect(),
            support,
        })
    }

    /// The Fourier profile of an OFDM receiver: `subcarriers` lines at `k / (zero_pad *
    /// subcarriers)` weighted by the window (`OfdmRadar::normalised_window`), period K cells.
    ///
    /// # Errors
    ///
    /// [`DspError::Param`] when `zero_pad` is 0, or `window` holds fewer than 2 subcarriers or
    /// weights that sum to zero or are not finite.
    pub fn ofdm(zero_pad: usize, window: &[f64]) -> Result<Self, DspError> {
        if zero_pad == 0 || window.len() < 2 {
            return Err(DspError::Param(format!(
                "OFDM point spread: zero_pad = {zero_pad}, {} subcarriers; allowed: zero_pad >= 1 \
                 and at least 2 subcarriers",
                window.len()
            )));
        }
        let k = (zero_pad * window.len()) as f64;
        Self::new(
            (0..window.len()).map(|i| i as f64 / k).collect(),
            window.iter().map(|&w| Complex64::new(w, 0.0)).collect(),
            k / 2.0,
        )
    }

    /// The lines (cycles per cell) and their normalised weights.
    pub fn lines(&self) -> (&[f64], &[Complex64]) {
        (&self.nu, &self.weight)
    }
}

impl PointSpread for SpectralLines {
    fn value(&self, x: f64) -> Complex64 {
        self.nu
            .iter()
            .zip(&self.weight)
            .map(|(&nu, &w)| w * Complex64::from_polar(1.0, 2.0 * PI * nu * x))
            .sum()
    }

    fn response(&self, x0: f64, first: isize, out: &mut [Complex64]) {
        out.fill(ZERO);
        // Per line: the phase at the first cell, then a rotation per cell.
        for (&nu, &w) in self.nu.iter().zip(&self.weight) {
            let mut ph = w * Complex64::from_polar(1.0, 2.0 * PI * nu * (first as f64 - x0));
            let step = Complex64::from_polar(1.0, 2.0 * PI * nu);
            for o in out.iter_mut() {
                *o += ph;
                ph *= step;
            }
        }
    }

    fn support(&self) -> f64 {
        self.support
    }
}

/// A point spread sampled `per_cell` times per cell and interpolated (4-point Lagrange).
#[derive(Debug, Clone)]
pub struct TabulatedPsf {
    /// `g(origin + j / per_cell)`.
    table: Vec<Complex64>,
    origin: f64,
    per_cell: usize,
    /// The table covers one period and wraps (circular profile).
    periodic: bool,
    /// Period of the underlying spread for a non-periodic table (arguments are reduced into
    /// `[-wrap/2, wrap/2)` first), or 0.
    wrap: f64,
    support: f64,
}

/// Largest interpolation step, in radians of the highest significant line, for a cubic error below
/// about 1e-6: the error of 4-point Lagrange on `exp(j w t)` is at most `0.0234 (w h)^4`.
const MAX_PHASE_STEP: f64 = 0.08;

/// The sub-cell sampling that keeps the interpolation error under ~1e-6 for lines up to `nu_max`.
fn per_cell_for(nu_max: f64) -> usize {
    ((2.0 * PI * nu_max / MAX_PHASE_STEP).ceil() as usize).clamp(2, 512)
}

/// The smallest `|nu|` beyond which the lines' weights add up to at most 1e-7 of the total.
fn significant_nu(nu: &[f64], weight: &[Complex64]) -> f64 {
    let total: f64 = weight.iter().map(|w| w.norm()).sum();
    let mut by_nu: Vec<(f64, f64)> = nu
        .iter()
        .zip(weight)
        .map(|(n, w)| (n.abs(), w.norm()))
        .collect();
    by_nu.sort_by(|a, b| b.0.total_cmp(&a.0));
    let mut tail = 0.0;
    for &(n, w) in &by_nu {
        tail += w;
        if tail > 1e-7 * total {
            return n;
        }
    }
    0.0
}

impl TabulatedPsf {
    /// The table and its parameters as bytes (little endian), for a cache on disk.
    pub(crate) fn to_bytes(&self) -> Vec<u8> {
        let mut out = Vec::with_capacity(48 + 16 * self.table.len());
        for v in [self.origin, self.wrap, self.support] {
            out.extend(v.to_le_bytes());
        }
        out.extend((self.per_cell as u64).to_le_bytes());
        out.extend(u64::from(self.periodic).to_le_bytes());
        out.extend((self.table.len() as u64).to_le_bytes());
        for z in &self.table {
            out.extend(z.re.to_le_bytes());
            out.extend(z.im.to_le_bytes());
        }
        out
    }

    /// The inverse of [`to_bytes`](Self::to_bytes); `None` for bytes it did not write (wrong
    /// length, values a table cannot hold).
    pub(crate) fn from_bytes(bytes: &[u8]) -> Option<Self> {
        let word = |k: usize| -> Option<[u8; 8]> { bytes.get(8 * k..8 * k + 8)?.try_into().ok() };
        let f = |k: usize| word(k).map(f64::from_le_bytes);
        let u = |k: usize| word(k).map(u64::from_le_bytes);
        let (origin, wrap, support) = (f(0)?, f(1)?, f(2)?);
        let (per_cell, periodic, len) = (u(3)?, u(4)?, u(5)?);
        let len = usize::try_from(len).ok()?;
        if bytes.len() != 48 + 16 * len
            || len == 0
            || per_cell == 0
            || periodic > 1
            || ![origin, wrap, support].iter().all(|v| v.is_finite())
        {
            return None;
        }
        let table: Vec<Complex64> = bytes[48..]
            .chunks_exact(16)
            .map(|c| {
                let (re, im) = c.split_at(8);
                Complex64::new(
                    f64::from_le_bytes(re.try_into().expect("8 bytes")),
                    f64::from_le_bytes(im.try_into().expect("8 bytes")),
                )
            })
            .collect();
        if !table.iter().all(|z| z.re.is_finite() && z.im.is_finite()) {
            return None;
        }
        Some(Self {
            table,
            origin,
            per_cell: usize::try_from(per_cell).ok()?,
            periodic: periodic == 1,
            wrap,
            support,
        })
    }

    /// Tabulates `lines` by direct sums: over one period of `period_cells` cells (a circular
    /// profile, e.g. the OFDM Fourier profile's K) when given, else over `|x| <= lines.support()`.
    ///
    /// # Errors
    ///
    /// [`DspError::Param`] when `period_cells` is below 2.
    pub fn from_lines(
        lines: &SpectralLines,
        period_cells: Option<usize>,
    ) -> Result<Self, DspError> {
        let per_cell = per_cell_for(significant_nu(&lines.nu, &lines.weight));
        let (origin, len, periodic) = match period_cells {
            Some(k) if k >= 2 => (0.0, k * per_cell, true),
            Some(k) => {
                return Err(DspError::Param(format!(
                    "point spread: period = {k} cells; allowed: at least 2"
                )))
            }
            None => {
                let span = lines.support.ceil() as usize + 2;
                (-(span as f64), 2 * span * per_cell + 1, false)
            }
        };
        let h = 1.0 / per_cell as f64;
        let mut table = vec![ZERO; len];
        for (&nu, &w) in lines.nu.iter().zip(&lines.weight) {
            let mut ph = w * Complex64::from_polar(1.0, 2.0 * PI * nu * origin);
            let step = Complex64::from_polar(1.0, 2.0 * PI * nu * h);
            for (j, t) in table.iter_mut().enumerate() {
                *t += ph;
                ph *= step;
                // Re-anchor now and then so rounding in the recursion cannot build up.
                if j % 4096 == 4095 {
                    let x = origin + (j + 1) as f64 * h;
                    ph = w * Complex64::from_polar(1.0, 2.0 * PI * nu * x);
                }
            }
        }
        Ok(Self {
            table,
            origin,
            per_cell,
            periodic,
            wrap: 0.0,
            support: if periodic {
                period_cells.unwrap_or(0) as f64 / 2.0
            } else {
                lines.support
            },
        })
    }

    /// Tabulates the spread of a DFT spectrum: bin `k` of `spectrum` (length P) is the line at
    /// `signed(k) / P` cycles per cell (`signed(k) = k - P` above P/2). The spread has period P; it
    /// is tabulated over `|x| <= span_cells` (the longest profile it will be used on) and taken as
    /// zero beyond. Cost: `U` inverse FFTs of P points, U the sub-cell sampling.
    pub(crate) fn from_dft_spectrum(
        spectrum: &[Complex64],
        span_cells: usize,
    ) -> Result<Self, DspError> {
        let p = spectrum.len();
        if p < 4 || span_cells == 0 || span_cells >= p / 2 {
            return Err(DspError::Param(format!(
                "point spread: {p}-point spectrum over +-{span_cells} cells; allowed: at least 4 \
                 points and 1 <= span < P/2"
            )));
        }
        let signed = |k: usize| {
            if k <= p / 2 {
                k as f64
            } else {
                k as f64 - p as f64
            }
        };
        let nu: Vec<f64> = (0..p).map(|k| signed(k) / p as f64).collect();
        let sum: Complex64 = spectrum.iter().sum();
        if !(sum.norm() > 0.0 && sum.norm().is_finite()) {
            return Err(DspError::Param(
                "point spread: the spectrum sums to zero or is not finite".into(),
            ));
        }
        let inv = sum.inv();
        let per_cell = per_cell_for(significant_nu(&nu, spectrum));
        let span = span_cells + 2;
        let len = 2 * span * per_cell + 1;
        let mut table = vec![ZERO; len];
        let ifft = crate::dsp::plans::inverse(p);
        let mut buf = vec![ZERO; p];
        let mut scratch = vec![ZERO; ifft.get_inplace_scratch_len()];
        // Shift by f / U cell for the table's points at x = m + f / U: the phasors
        // exp(j 2 pi nu f / U), advanced by one multiply per bin and step.
        let step: Vec<Complex64> = nu
            .iter()
            .map(|&n| Complex64::from_polar(1.0, 2.0 * PI * n / per_cell as f64))
            .collect();
        let mut rot: Vec<Complex64> = spectrum.iter().map(|s| s * inv).collect();
        for f in 0..per_cell {
            buf.copy_from_slice(&rot);
            for (r, st) in rot.iter_mut().zip(&step) {
                *r *= st;
            }
            ifft.process_with_scratch(&mut buf, &mut scratch);
            for m in -(span as isize)..=(span as isize) {
                let j = (m + span as isize) as usize * per_cell + f;
                if j < len {
                    table[j] = buf[m.rem_euclid(p as isize) as usize];
                }
            }
        }
        Ok(Self {
            table,
            origin: -(span as f64),
            per_cell,
            periodic: false,
            wrap: p as f64,
            support: span_cells as f64,
        })
    }

    /// The spread of a correlation profile (`crate::dsp::CorrelationProfiler`) taken
    /// circularly over one repetition: lines `|REF_k|^2 H(nu_k)`, with `reference` the P samples
    /// correlated against and `response(nu)` any extra complex response of the capture at `nu`
    /// cycles per sample in [-0.5, 0.5) (the decimator's pass band on the bench; `None`: flat).
    /// Tabulated over `|x| <= span_cells` lags (at least the profile's length).
    ///
    /// # Errors
    ///
    /// [`DspError::Param`] when the reference is shorter than 4 samples, `span_cells` is not in
    /// `1..P/2`, or the filtered spectrum sums to zero or is not finite.
    pub fn correlation(
        reference: &[Complex64],
        response: Option<&dyn Fn(f64) -> Complex64>,
        span_cells: usize,
    ) -> Result<Self, DspError> {
        let p = reference.len();
        let mut spectrum = reference.to_vec();
        crate::dsp::plans::forward(p.max(1)).process(&mut spectrum);
        for (k, s) in spectrum.iter_mut().enumerate() {
            let power = s.norm_sqr();
            *s = Complex64::new(power, 0.0);
            if let Some(h) = response {
                let nu = if k <= p / 2 {
                    k as f64
                } else {
                    k as f64 - p as f64
                } / p as f64;
                *s *= h(nu);
            }
        }
        Self::from_dft_spectrum(&spectrum, span_cells)
    }

    /// Table points per cell.
    pub fn per_cell(&self) -> usize {
        self.per_cell
    }

    /// Lagrange weights for the fractional position `f` in [0, 1) between points 0 and 1.
    fn weights(f: f64) -> [f64; 4] {
        let (a, b, c, d) = (f + 1.0, f, f - 1.0, f - 2.0);
        [
            -b * c * d / 6.0,
            a * c * d / 2.0,
            -a * b * d / 2.0,
            a * b * c / 6.0,
        ]
    }

    /// Table point `j` (wrapped for a periodic table, zero outside otherwise).
    #[inline]
    fn point(&self, j: isize) -> Complex64 {
        let n = self.table.len() as isize;
        if self.periodic {
            self.table[j.rem_euclid(n) as usize]
        } else if (0..n).contains(&j) {
            self.table[j as usize]
        } else {
            ZERO
        }
    }

    /// `x` reduced into the period around 0 for a non-periodic table of a periodic spread.
    #[inline]
    fn reduce(&self, x: f64) -> f64 {
        if self.wrap > 0.0 {
            x - self.wrap * (x / self.wrap).round()
        } else {
            x
        }
    }
}

impl PointSpread for TabulatedPsf {
    fn value(&self, x: f64) -> Complex64 {
        let t = (self.reduce(x) - self.origin) * self.per_cell as f64;
        let i = t.floor();
        let w = Self::weights(t - i);
        let i = i as isize;
        (0..4).map(|m| self.point(i - 1 + m as isize) * w[m]).sum()
    }

    fn response(&self, x0: f64, first: isize, out: &mut [Complex64]) {
        // Every cell shares the same fractional table position: one set of weights.
        let u = self.per_cell as isize;
        let t = (self.reduce(first as f64 - x0) - self.origin) * self.per_cell as f64;
        let i = t.floor();
        let w = Self::weights(t - i);
        let mut j = i as isize - 1;
        let n = self.table.len() as isize;
        for o in out.iter_mut() {
            *o = if !self.periodic && j >= 0 && j + 3 < n {
                let s = &self.table[j as usize..j as usize + 4];
                s[0] * w[0] + s[1] * w[1] + s[2] * w[2] + s[3] * w[3]
            } else {
                (0..4).map(|m| self.point(j + m as isize) * w[m]).sum()
            };
            j += u;
        }
    }

    fn support(&self) -> f64 {
        self.support
    }
}

/// What a detector needs to know about a spread, measured from it once.
#[derive(Debug, Clone)]
pub struct PsfShape {
    /// Distance from the peak to the first null (local minimum of `|g|`), cells, the larger side.
    pub first_null: f64,
    /// Main-lobe width at -3 dB, cells.
    pub width_3db: f64,
    /// The resolution cell, cells: the -3 dB width over 0.886 (c0 / 2B for a flat spectrum; wider
    /// with a window, as the resolution is).
    pub resolution: f64,
    /// Peak side-lobe level of the spread itself, dB.
    pub psl_db: f64,
    /// Profile cells per independent noise sample: `sum_x |g(x)|^2 / |g(0)|^2` over whole cells.
    pub noise_cells: f64,
    /// `envelope[d]`: the highest `|g(x)|^2` at `|x| >= d` cells, 1 within the main lobe
    /// (`d <= first_null`). Beyond its end, its last value.
    pub envelope: Vec<f64>,
    /// Half-width (cells) of the region where a target's PSL is measured: three resolution cells,
    /// or farther if the spread's envelope is still within 3 dB of its PSL there. (Farther lobes
    /// can be nearly as high, e.g. the -19 dB plateau of the 128-bit MSK-LFM out to 6 m; a PSL over
    /// the whole profile would rarely be free of other targets.)
    pub psl_span: f64,
}

/// The PSL is looked for within this many resolution cells of a target at most.
const PSL_SPAN_RESOLUTIONS: f64 = 6.0;

impl PsfShape {
    /// Measures `psf` over `|x| <= min(support, max_cells)`, in steps of 1/8 cell.
    ///
    /// # Errors
    ///
    /// [`DspError::Param`] when the response at the target is zero or not finite.
    pub fn measure(psf: &dyn PointSpread, max_cells: usize) -> Result<Self, DspError> {
        let d_max = (psf.support().floor() as usize).min(max_cells).max(2);
        const SUB: usize = 8;
        let h = 1.0 / SUB as f64;
        let g0 = psf.value(0.0).norm_sqr();
        if !(g0 > 0.0 && g0.is_finite()) {
            return Err(DspError::Param(
                "point spread: zero or non-finite response at the target".into(),
            ));
        }
        // |g|^2 / |g0|^2 at +-(j h), j = 0 ..= d_max SUB.
        let samples = d_max * SUB + 1;
        let mut pos = vec![0.0; samples];
        let mut neg = vec![0.0; samples];
        let mut buf = vec![ZERO; d_max + 1];
        for s in 0..SUB {
            let off = s as f64 * h;
            psf.response(-off, 0, &mut buf);
            for (d, v) in buf.iter().enumerate() {
                let j = d * SUB + s;
                if j < samples {
                    pos[j] = v.norm_sqr() / g0;
                }
            }
            psf.response(off, -(d_max as isize), &mut buf);
            for (i, v) in buf.iter().enumerate() {
                // Cell i - d_max minus off = -(d_max - i + off).
                let j = (d_max - i) * SUB + s;
                if j < samples {
                    neg[j] = v.norm_sqr() / g0;
                }
            }
        }
        let null_of = |v: &[f64]| {
            let mut j = 1;
            while j < v.len() && v[j] < v[j - 1] {
                j += 1;
            }
            (j - 1) as f64 * h
        };
        let first_null = null_of(&pos).max(null_of(&neg));
        let half_of = |v: &[f64]| {
            let j = v.iter().position(|&p| p < 0.5).unwrap_or(v.len() - 1);
            let (a, b) = (v[j - 1], v[j]);
            (j - 1) as f64 * h + h * (a - 0.5) / (a - b).max(1e-300)
        };
        let width_3db = half_of(&pos) + half_of(&neg);
        let resolution = width_3db / 0.886;
        // Envelope per whole cell, from the outside in.
        let mut envelope = vec![0.0; d_max + 1];
        let mut running: f64 = 0.0;
        for d in (0..=d_max).rev() {
            for s in 0..SUB {
                let j = d * SUB + s;
                if j < samples {
                    running = running.max(pos[j]).max(neg[j]);
                }
            }
            envelope[d] = running;
        }
        let null_cell = first_null.ceil() as usize;
        let psl = envelope.get(null_cell).copied().unwrap_or(0.0).max(1e-30);
        for e in envelope.iter_mut().take(null_cell) {
            *e = 1.0;
        }
        let psl_db = 10.0 * psl.log10();
        // Where the envelope first drops 3 dB under the PSL: the highest side-lobes lie inside.
        let limit = psl * 10f64.powf(-0.3);
        let span_cells = envelope.iter().position(|&e| e <= limit).unwrap_or(d_max) as f64;
        // Equiripple side-lobes (Dolph-Chebyshev) never fall off: their PSL is that of the
        // first few, so the span is capped rather than running off every profile.
        let psl_span = span_cells
            .min(PSL_SPAN_RESOLUTIONS * resolution)
            .max(3.0 * resolution)
            .min(d_max as f64);
        let noise_cells = 1.0 + 2.0 * envelope_sum(&pos, &neg, SUB);
        Ok(Self {
            first_null,
            width_3db,
            resolution,
            psl_db,
            noise_cells,
            envelope,
            psl_span,
        })
    }

    /// The envelope at distance `d` cells (see [`PsfShape::envelope`]).
    pub fn envelope_at(&self, d: f64) -> f64 {
        let i = d.abs().floor() as usize;
        self.envelope
            .get(i)
            .or(self.envelope.last())
            .copied()
            .unwrap_or(0.0)
    }
}

/// `sum_{x = 1, 2, ...} (|g(x)|^2 + |g(-x)|^2) / 2` from the sampled powers.
fn envelope_sum(pos: &[f64], neg: &[f64], sub: usize) -> f64 {
    let mut s = 0.0;
    let mut j = sub;
    while j < pos.len() {
        s += 0.5 * (pos[j] + neg[j]);
        j += sub;
    }
    s
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A table through its bytes (the cache on disk) is the same table, bit for bit; bytes it did
    /// not write are refused.
    #[test]
    fn a_table_through_its_bytes_is_the_same_table() {
        let spectrum: Vec<Complex64> = (0..64)
            .map(|k| Complex64::from_polar(1.0 + 0.01 * k as f64, 0.3 * k as f64))
            .collect();
        let table = TabulatedPsf::from_dft_spectrum(&spectrum, 9).unwrap();
        let bytes = table.to_bytes();
        let back = TabulatedPsf::from_bytes(&bytes).unwrap();
        assert_eq!(back.to_bytes(), bytes);
        let (mut a, mut b) = (vec![ZERO; 40], vec![ZERO; 40]);
        for x0 in [0.0, 0.37, -3.5] {
            table.response(x0, -20, &mut a);
            back.response(x0, -20, &mut b);
            assert_eq!(a, b);
        }
        assert!(TabulatedPsf::from_bytes(&bytes[..bytes.len() - 1]).is_none());
        let mut nan = bytes.clone();
        nan[48..56].copy_from_slice(&f64::NAN.to_le_bytes());
        assert!(TabulatedPsf::from_bytes(&nan).is_none());
    }

    #[test]
    fn table_matches_direct_sum() {
        let w: Vec<f64> = (0..16).map(|k| 1.0 + 0.1 * k as f64).collect();
        let lines = SpectralLines::ofdm(10, &w).unwrap();
        let table = TabulatedPsf::from_lines(&lines, Some(160)).unwrap();
        let mut a = vec![ZERO; 200];
        let mut b = vec![ZERO; 200];
        for x0 in [0.0, 3.37, 77.91, 159.5] {
            lines.response(x0, -20, &mut a);
            table.response(x0, -20, &mut b);
            for (i, (p, q)) in a.iter().zip(&b).enumerate() {
                assert!((p - q).norm() < 2e-6, "x0 {x0} cell {i}: {p} vs {q}");
            }
        }
        assert!((lines.value(0.0) - Complex64::new(1.0, 0.0)).norm() < 1e-12);
    }

    #[test]
    fn dft_table_matches_its_lines() {
        // A small "correlation" spectrum: random powers on the lowest bins of a 400-point DFT.
        let p = 400;
        let mut spectrum = vec![ZERO; p];
        for (k, s) in spectrum.iter_mut().enumerate() {
            let signed = if k <= p / 2 {
                k as isize
            } else {
                k as isize - p as isize
            };
            if signed.abs() <= 25 {
                *s = Complex64::new(1.0 + ((k * 7919) % 13) as f64 / 13.0, 0.0);
            }
        }
        let table = TabulatedPsf::from_dft_spectrum(&spectrum, 150).unwrap();
        let nu: Vec<f64> = (0..p)
            .map(|k| if k <= p / 2 { k as f64 } else { k as f64 - p as f64 } / p as f64)
            .collect();
        let lines = SpectralLines::new(nu, spectrum, 150.0).unwrap();
        for x in [-149.3, -10.0, -0.26, 0.0, 0.5, 7.77, 120.01, 399.5 - 400.0] {
            let (a, b) = (lines.value(x), table.value(x));
            assert!((a - b).norm() < 2e-6, "x {x}: {a} vs {b}");
        }
        // Periodic reduction: a target one period away looks the same.
        assert!((table.value(3.2 + 400.0) - table.value(3.2)).norm() < 1e-9);
        assert_eq!(table.value(190.0), ZERO);
    }

    #[test]
    fn shape_of_a_sinc() {
        // 128 flat lines, zero padding 10: sinc-like with nulls every 10 cells.
        let lines = SpectralLines::ofdm(10, &[1.0; 128]).unwrap();
        let shape = PsfShape::measure(&lines, 640).unwrap();
        assert!((shape.first_null - 10.0).abs() < 0.2, "{shape:?}");
        assert!((shape.width_3db - 8.86).abs() < 0.05, "{}", shape.width_3db);
        assert!((shape.resolution - 10.0).abs() < 0.06);
        assert!((shape.psl_db + 13.26).abs() < 0.05, "{}", shape.psl_db);
        assert!(
            (shape.noise_cells - 10.0).abs() < 0.1,
            "{}",
            shape.noise_cells
        );
        assert_eq!(shape.envelope[5], 1.0);
        assert!(shape.envelope[30] < 10f64.powf(-1.9));
    }
}
