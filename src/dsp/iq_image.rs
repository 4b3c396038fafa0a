//! The I/Q errors of both ends of the chain: the transmitter's gain and phase imbalance and skew,
//! the receiver's skew; told apart in the image response one reference measures, and undone
//! (on receive) or pre-distorted (on transmit).
//!
//! The model, per bin of one period's spectrum, `I = (Y + Y~) / 2` and `Q = (Y - Y~) / 2j` with
//! `Y~(f) = conj(Y(-f))`:
//! - the transmitter makes `Q' = g e^{-j w t_tx} (Q cos phi - I sin phi)` of its input (Q late by
//!   `t_tx`, `w = 2 pi f`), I unchanged;
//! - the receiver samples Q `t_rx` late; its gain and phase imbalance (measured apart, from its
//!   noise) is undone sample by sample before anything here.
//!
//! To first order the image response relative to the direct one is then
//! `rho(f) = alpha(f) + beta(f) u(f)`: the transmitter's `alpha = a + j pi f t_tx` (`a` from `g`
//! and `phi`), the receiver's `beta = j pi f t_rx`, and `u(f) = conj(D(-f)) / D(f)` of the
//! measured direct response `D`. The receiver's image turns with `u`, whose phase holds the
//! carrier's phase of the reference's echo (twice it); the transmitter's does not. So one
//! reference separates the two skews unless `u` is nearly real over the band (the echo's carrier
//! phase a multiple of 90 degrees): then only their sum or difference is seen, and moving the
//! reference by a fraction of a millimetre separates them.

use nalgebra::{Matrix2, Matrix4, Vector4};
use num_complex::Complex64;
use std::f64::consts::PI;

/// Signed frequency of bin `k` of `n` at `fs`.
fn freq(k: usize, n: usize, fs: f64) -> f64 {
    let s = if k <= n / 2 {
        k as f64
    } else {
        k as f64 - n as f64
    };
    s * fs / n as f64
}

/// Applies `map(f, I, Q) -> (I', Q')` to the I and Q parts of a spectrum, bin pair by bin pair
/// (in place: bins `k` and `n - k` are read before either is written).
fn map_iq(
    spectrum: &mut [Complex64],
    fs: f64,
    map: impl Fn(f64, Complex64, Complex64) -> (Complex64, Complex64),
) {
    let n = spectrum.len();
    // The Nyquist bin is its own mirror: a real signal holds no delay there.
    map_iq_bins(spectrum, |k, i, q| {
        map(if 2 * k == n { 0.0 } else { freq(k, n, fs) }, i, q)
    });
}

/// [`map_iq`] with the bin's index instead of its frequency.
fn map_iq_bins(
    spectrum: &mut [Complex64],
    map: impl Fn(usize, Complex64, Complex64) -> (Complex64, Complex64),
) {
    let n = spectrum.len();
    let one = |k: usize, own: Complex64, mirror: Complex64| {
        let mirror = mirror.conj();
        let i = (own + mirror) * 0.5;
        let q = (own - mirror) * Complex64::new(0.0, -0.5);
        let (i, q) = map(k, i, q);
        i + Complex64::i() * q
    };
    for k in 0..=n / 2 {
        let m = (n - k) % n;
        let (a, b) = (spectrum[k], spectrum[m]);
        spectrum[k] = one(k, a, b);
        if m != k {
            spectrum[m] = one(m, b, a);
        }
    }
}

/// The transmitter's I/Q errors.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct TxIq {
    /// Q's gain relative to I (linear).
    pub gain: f64,
    /// Q's phase error (radians).
    pub phase: f64,
    /// Q late by this (s).
    pub skew_s: f64,
}

impl TxIq {
    /// What the transmitter makes of a period's spectrum (in place).
    pub(crate) fn apply(&self, spectrum: &mut [Complex64], fs: f64) {
        let (s, c) = self.phase.sin_cos();
        map_iq(spectrum, fs, |f, i, q| {
            let late = Complex64::from_polar(1.0, -2.0 * PI * f * self.skew_s);
            (i, (q * c - i * s) * self.gain * late)
        });
    }

    /// The spectrum the transmitter must be given to make this one (in place): its exact inverse.
    pub(crate) fn undo(&self, spectrum: &mut [Complex64], fs: f64) {
        let (s, c) = self.phase.sin_cos();
        map_iq(spectrum, fs, |f, i, q| {
            let early = Complex64::from_polar(1.0, 2.0 * PI * f * self.skew_s);
            (i, (q * early / self.gain + i * s) / c)
        });
    }

    /// Its direct response at `f`: `(1 + g e^{-j(phi + w t)}) / 2`.
    pub(crate) fn direct(&self, f: f64) -> Complex64 {
        (1.0 + Complex64::from_polar(self.gain, -(self.phase + 2.0 * PI * f * self.skew_s))) * 0.5
    }

    /// Its image response at `f`: `(1 - g e^{j(phi - w t)}) / 2`.
    fn image(&self, f: f64) -> Complex64 {
        (1.0 - Complex64::from_polar(self.gain, self.phase - 2.0 * PI * f * self.skew_s)) * 0.5
    }

    /// The gain and phase that leave the image `alpha` (relative to the direct) at 0 Hz: the
    /// exact inverse of `alpha = (1 - z) / (1 + conj z)`, `z = g e^{j phi}`.
    fn from_image_at_dc(alpha: Complex64, skew_s: f64) -> TxIq {
        // z + alpha conj(z) = 1 - alpha, in the real and imaginary parts p, q of z.
        let (ar, ai) = (alpha.re, alpha.im);
        let m = nalgebra::Matrix2::new(1.0 + ar, ai, ai, 1.0 - ar);
        let rhs = nalgebra::Vector2::new(1.0 - ar, -ai);
        let z = m
            .lu()
            .solve(&rhs)
            .unwrap_or(nalgebra::Vector2::new(1.0, 0.0));
        let z = Complex64::new(z[0], z[1]);
        TxIq {
            gain: z.norm(),
            phase: z.arg(),
            skew_s,
        }
    }
}

/// The receiver's direct response with Q sampled `skew_s` late: `(1 + e^{-j w t}) / 2`.
pub(crate) fn rx_skew_direct(f: f64, skew_s: f64) -> Complex64 {
    (1.0 + Complex64::from_polar(1.0, -2.0 * PI * f * skew_s)) * 0.5
}

/// Takes a receiver's Q skew out of a period's spectrum (in place): Q advanced by `skew_s`.
/// The reference [`undo_rx_skew_by_turns`] must equal.
#[cfg(test)]
pub(crate) fn undo_rx_skew(spectrum: &mut [Complex64], fs: f64, skew_s: f64) {
    if skew_s == 0.0 {
        return;
    }
    map_iq(spectrum, fs, |f, i, q| (i, q * rx_skew_advance(f, skew_s)));
}

/// What advances Q by `skew_s` at `f`.
fn rx_skew_advance(f: f64, skew_s: f64) -> Complex64 {
    Complex64::from_polar(1.0, 2.0 * PI * f * skew_s)
}

/// The turn of Q that takes a receiver's skew out, for each bin of periods of `n` samples at
/// `fs`: made once for a correction applied to many periods, so a period costs no trigonometry.
pub(crate) fn rx_skew_turns(n: usize, fs: f64, skew_s: f64) -> Vec<Complex64> {
    (0..n)
        .map(|k| rx_skew_advance(if 2 * k == n { 0.0 } else { freq(k, n, fs) }, skew_s))
        .collect()
}

/// Takes a receiver's Q skew out of a period's spectrum (in place) with the turns
/// [`rx_skew_turns`] made: Q advanced, as `undo_rx_skew` (kept for the tests) does bin by bin.
pub(crate) fn undo_rx_skew_by_turns(spectrum: &mut [Complex64], turns: &[Complex64]) {
    debug_assert_eq!(spectrum.len(), turns.len());
    map_iq_bins(spectrum, |k, i, q| (i, q * turns[k]));
}

/// The two ends' I/Q errors as one reference's image shows them.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct IqSplit {
    pub tx: TxIq,
    pub rx_skew_s: f64,
    /// Standard errors of the two skews (s), from the fit's residual.
    pub tx_skew_sd_s: f64,
    pub rx_skew_sd_s: f64,
    /// Correlation of the two skews' estimates: near +-1, only their sum or difference is seen.
    pub skew_correlation: f64,
}

/// Above this correlation the two skews are not told apart (the echo's carrier phase within
/// about 18 degrees of a multiple of 90).
pub(crate) const SKEW_CORRELATION_LIMIT: f64 = 0.95;

impl IqSplit {
    /// Whether the transmitter's and the receiver's skews were told apart.
    pub(crate) fn skews_separated(&self) -> bool {
        self.skew_correlation.abs() < SKEW_CORRELATION_LIMIT
    }
}

/// Fits the model of the module docs to the image ratio `rho` at frequencies `freq_hz`, with `u`
/// (`conj(D(-f)) / D(f)`) and weights `w` (zero leaves a bin out). `None` with fewer than 8
/// weighted bins or a singular fit.
pub(crate) fn split_image(
    freq_hz: &[f64],
    rho: &[Complex64],
    u: &[Complex64],
    w: &[f64],
) -> Option<IqSplit> {
    // Unknowns: Re a, Im a, t_tx, t_rx (in ps, for a well-scaled system). Two real rows per bin.
    let rows = |k: usize| {
        let pf = PI * freq_hz[k] * 1e-12;
        ([1.0, 0.0, 0.0, -pf * u[k].im], [0.0, 1.0, pf, pf * u[k].re])
    };
    let (mut ata, mut atb) = (Matrix4::<f64>::zeros(), Vector4::<f64>::zeros());
    let mut used = 0usize;
    for k in (0..freq_hz.len()).filter(|&k| w[k] > 0.0) {
        let (re, im) = rows(k);
        for (row, y) in [(re, rho[k].re), (im, rho[k].im)] {
            let r = Vector4::from(row);
            ata += w[k] * r * r.transpose();
            atb += w[k] * y * r;
        }
        used += 1;
    }
    if used < 8 {
        return None;
    }
    // A whisker of ridge on the skews: with `u` exactly real the two are one unknown, and the
    // correlation (not a failed inverse) says so.
    let ridge = 1e-9 * ata.trace();
    ata[(2, 2)] += ridge;
    ata[(3, 3)] += ridge;
    let inverse = ata.try_inverse()?;
    let p = inverse * atb;
    let (mut rss, mut wsum) = (0.0, 0.0);
    for k in (0..freq_hz.len()).filter(|&k| w[k] > 0.0) {
        let (re, im) = rows(k);
        for (row, y) in [(re, rho[k].re), (im, rho[k].im)] {
            rss += w[k] * (y - Vector4::from(row).dot(&p)).powi(2);
        }
        wsum += 2.0 * w[k];
    }
    // Residual variance per unit weight; the bins' noise is taken as independent.
    let dof = (2 * used).saturating_sub(4).max(1) as f64;
    let sigma2 = rss / dof * (2 * used) as f64 / wsum;
    let cov = inverse * sigma2 * (wsum / (2 * used) as f64);
    let sd = |i: usize| cov[(i, i)].max(0.0).sqrt() * 1e-12;
    let corr = inverse[(2, 3)] / (inverse[(2, 2)] * inverse[(3, 3)]).sqrt();
    Some(IqSplit {
        tx: TxIq::from_image_at_dc(Complex64::new(p[0], p[1]), p[2] * 1e-12),
        rx_skew_s: p[3] * 1e-12,
        tx_skew_sd_s: sd(2),
        rx_skew_sd_s: sd(3),
        skew_correlation: if corr.is_finite() { corr } else { 1.0 },
    })
}

/// A widely linear map at one frequency pair, acting on `(X(f), conj X(-f))`.
type Pair = Matrix2<Complex64>;

/// `[[a(f), b(f)], [conj b(-f), conj a(-f)]]`.
fn pair(a: impl Fn(f64) -> Complex64, b: impl Fn(f64) -> Complex64, f: f64) -> Pair {
    Matrix2::new(a(f), b(f), b(-f).conj(), a(-f).conj())
}

/// The two ends' I/Q errors from the direct and image responses `direct`, `image` (per bin of a
/// period at `fs`, unnormalised) over the bins of weight `w[k] > 0` (their mirrors must be
/// measured too). The first-order fit of [`split_image`] is refined twice: the errors found are
/// taken out of the measured pair exactly (a 2 x 2 widely linear inverse per frequency) and what
/// is left is fitted again, so products of the errors do not bias the skews. `span` is how many
/// adjacent bins each estimate's noise spans (a gated estimate's are correlated over about
/// `1 / gate`): the standard errors count independent bins only.
pub(crate) fn split_measured(
    direct: &[Complex64],
    image: &[Complex64],
    w: &[f64],
    fs: f64,
    span: f64,
) -> Option<IqSplit> {
    let n = direct.len();
    let bins: Vec<usize> = (0..n).filter(|&k| w[k] > 0.0 && 2 * k != n).collect();
    let f: Vec<f64> = bins.iter().map(|&k| freq(k, n, fs)).collect();
    let wb: Vec<f64> = bins.iter().map(|&k| w[k]).collect();
    let fit = |d: &dyn Fn(usize) -> Complex64, m: &dyn Fn(usize) -> Complex64| {
        let rho: Vec<Complex64> = bins.iter().map(|&k| m(k) / d(k)).collect();
        let u: Vec<Complex64> = bins.iter().map(|&k| d((n - k) % n).conj() / d(k)).collect();
        split_image(&f, &rho, &u, &wb)
    };
    let mut split = fit(&|k| direct[k], &|k| image[k])?;
    for _ in 0..2 {
        let (tx, rx_skew) = (split.tx, split.rx_skew_s);
        let rx_image = |f: f64| Complex64::new(1.0, 0.0) - rx_skew_direct(f, rx_skew);
        // What is left once both ends are taken out: the measured pair is R H T.
        let left: Vec<(Complex64, Complex64)> = (0..n)
            .map(|k| {
                let fk = freq(k, n, fs);
                let m = (n - k) % n;
                let measured = Matrix2::new(direct[k], image[k], image[m].conj(), direct[m].conj());
                let t = pair(|f| tx.direct(f), |f| tx.image(f), fk);
                let r = pair(|f| rx_skew_direct(f, rx_skew), rx_image, fk);
                match (r.try_inverse(), t.try_inverse()) {
                    (Some(ri), Some(ti)) => {
                        let h = ri * measured * ti;
                        (h[(0, 0)], h[(0, 1)])
                    }
                    _ => (direct[k], image[k]),
                }
            })
            .collect();
        let more = fit(&|k| left[k].0, &|k| left[k].1)?;
        split = IqSplit {
            tx: TxIq {
                gain: tx.gain * more.tx.gain,
                phase: tx.phase + more.tx.phase,
                skew_s: tx.skew_s + more.tx.skew_s,
            },
            rx_skew_s: rx_skew + more.rx_skew_s,
            ..more
        };
    }
    let inflate = span.max(1.0).sqrt();
    split.tx_skew_sd_s *= inflate;
    split.rx_skew_sd_s *= inflate;
    Some(split)
}

#[cfg(test)]
mod tests {
    use super::*;
    use rustfft::FftPlanner;

    fn noise(n: usize, seed: u64) -> Vec<Complex64> {
        let mut rng = crate::rng::SplitMix64::new(seed);
        (0..n).map(|_| rng.complex_gaussian(1.0)).collect()
    }

    /// The turns made once give exactly what the per-call undo gives, Nyquist bin included.
    #[test]
    fn the_receivers_skew_by_turns_is_the_same_undo() {
        for n in [512, 511] {
            let (fs, skew) = (16e9, 3e-12);
            let mut a = noise(n, 5);
            let mut b = a.clone();
            undo_rx_skew(&mut a, fs, skew);
            undo_rx_skew_by_turns(&mut b, &rx_skew_turns(n, fs, skew));
            assert_eq!(a, b);
        }
    }

    #[test]
    fn the_transmitters_inverse_undoes_it() {
        let fs = 16e9;
        let tx = TxIq {
            gain: 10f64.powf(0.4 / 20.0),
            phase: 3f64.to_radians(),
            skew_s: 2e-12,
        };
        let x = noise(512, 7);
        let mut y = x.clone();
        tx.undo(&mut y, fs);
        tx.apply(&mut y, fs);
        for (a, b) in x.iter().zip(&y) {
            assert!((a - b).norm() < 1e-12, "{a} vs {b}");
        }
    }

    /// Through a transmitter, a delay with a carrier phase, and a receiver with a skew: the fit
    /// recovers both ends, and the receiver's skew undone leaves only the transmitter's image.
    #[test]
    fn one_reference_tells_the_two_skews_apart() {
        let (n, fs) = (4096, 16e9);
        let mut fft = FftPlanner::new();
        let fwd = fft.plan_fft_forward(n);
        let tx = TxIq {
            gain: 10f64.powf(0.4 / 20.0),
            phase: 3f64.to_radians(),
            skew_s: 2e-12,
        };
        let rx_skew = 3e-12;
        // Probe the chain with a real-valued input and an imaginary one: the responses to X and
        // to its image follow from the two.
        let through = |x: &[Complex64], carrier: f64| {
            let mut s = x.to_vec();
            fwd.process(&mut s);
            tx.apply(&mut s, fs);
            for v in s.iter_mut() {
                *v *= Complex64::from_polar(1.0, carrier);
            }
            // The receiver samples Q late.
            map_iq(&mut s, fs, |f, i, q| {
                (i, q * Complex64::from_polar(1.0, -2.0 * PI * f * rx_skew))
            });
            s
        };
        for carrier_deg in [30.0f64, 60.0, 120.0] {
            let carrier = carrier_deg.to_radians();
            let mut x = noise(n, 3);
            let y = through(&x, carrier);
            fwd.process(&mut x);
            let xt: Vec<Complex64> = (0..n).map(|k| x[(n - k) % n].conj()).collect();
            // With X random, D and M per bin from two inputs: X and j X.
            let mut xj = noise(n, 3);
            xj.iter_mut().for_each(|v| *v *= Complex64::i());
            let yj = through(&xj, carrier);
            fwd.process(&mut xj);
            let xjt: Vec<Complex64> = (0..n).map(|k| xj[(n - k) % n].conj()).collect();
            let (mut d, mut m) = (
                vec![Complex64::new(0.0, 0.0); n],
                vec![Complex64::new(0.0, 0.0); n],
            );
            for k in 0..n {
                // y = D x + M xt, yj = D xj + M xjt.
                let det = x[k] * xjt[k] - xt[k] * xj[k];
                d[k] = (y[k] * xjt[k] - xt[k] * yj[k]) / det;
                m[k] = (x[k] * yj[k] - y[k] * xj[k]) / det;
            }
            let w: Vec<f64> = (0..n)
                .map(|k| f64::from(freq(k, n, fs).abs() < 0.5e9))
                .collect();
            let s = split_measured(&d, &m, &w, fs, 1.0).unwrap();
            assert!(s.skews_separated(), "{s:?} at {carrier_deg} degrees");
            assert!((s.rx_skew_s - rx_skew).abs() < 0.01e-12, "{s:?}");
            assert!((s.tx.skew_s - tx.skew_s).abs() < 0.01e-12, "{s:?}");
            assert!((s.tx.gain / tx.gain - 1.0).abs() < 1e-5, "{s:?}");
            assert!(
                (s.tx.phase - tx.phase).abs() < 0.001f64.to_radians(),
                "{s:?}"
            );
        }
    }

    #[test]
    fn an_echo_at_a_quarter_turn_does_not_separate_them() {
        let n = 256;
        let f: Vec<f64> = (0..n).map(|k| freq(k, n, 16e9)).collect();
        let u = vec![Complex64::new(1.0, 0.0); n];
        let rho: Vec<Complex64> = f
            .iter()
            .map(|f| Complex64::new(0.0, PI * f * 5e-12))
            .collect();
        let w: Vec<f64> = f.iter().map(|f| f64::from(f.abs() < 4e9)).collect();
        let s = split_image(&f, &rho, &u, &w).unwrap();
        assert!(!s.skews_separated(), "{s:?}");
    }
}
