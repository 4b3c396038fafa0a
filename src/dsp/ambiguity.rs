//! The delay-Doppler (cross-)ambiguity function of a waveform, and the figures read from it.
//!
//! For a reference `s` and a signal `x` (the reference itself for the ambiguity function, a
//! capture for the cross-ambiguity), both sampled at `fs`:
//!
//! ```text
//! A(m, nu) = sum_n x[n] exp(j 2 pi nu n / fs) conj(s[n - m]) / sum_n |s[n]|^2
//! ```
//!
//! the matched filter's output at lag `m` for an echo shifted by `nu` Hz. `Periodic` takes the
//! shift circularly over the reference's length (what the radar sees: the AWG loops the segment
//! and the receiver correlates one repetition circularly); `Aperiodic` pads with zeros (one
//! isolated pulse, the textbook's ambiguity function). One Doppler cut is two FFTs.
//!
//! For a plain LFM pulse of duration `T` and chirp rate `k = B / T` the aperiodic function is
//! `|A(tau, nu)| = (1 - |tau| / T) |sinc((nu + k tau)(T - |tau|))|` for `|tau| <= T`
//! (`sinc(x) = sin(pi x) / (pi x)`): a ridge along `nu = -k tau`, so a Doppler shift `nu` moves
//! the peak by `-nu / k` and lowers it only to `1 - |nu| / B`.

use num_complex::Complex64;
use rustfft::{Fft, FftPlanner};
use std::sync::Arc;

/// How the delay wraps.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Wrap {
    /// Circular over the reference's length (a looped segment).
    Periodic,
    /// Zero-padded (one isolated pulse).
    Aperiodic,
}

/// The FFTs and spectra of one reference, reused for every Doppler cut.
pub(crate) struct Ambiguity {
    fs: f64,
    n: usize,
    len: usize,
    x: Vec<Complex64>,
    s_spectrum: Vec<Complex64>,
    energy: f64,
    forward: Arc<dyn Fft<f64>>,
    inverse: Arc<dyn Fft<f64>>,
    scratch: Vec<Complex64>,
}

impl Ambiguity {
    /// The (cross-)ambiguity of `x` against the reference `s` (equal lengths are not needed: `x`
    /// is cut or zero-padded to the reference's), sampled at `fs`. `None` when the reference is
    /// empty or has no energy.
    pub(crate) fn new(x: &[Complex64], s: &[Complex64], fs: f64, wrap: Wrap) -> Option<Ambiguity> {
        let n = s.len();
        let energy: f64 = s.iter().map(|v| v.norm_sqr()).sum();
        if n == 0 || !(energy > 0.0 && energy.is_finite()) || fs.is_nan() || fs <= 0.0 {
            return None;
        }
        let len = match wrap {
            Wrap::Periodic => n,
            Wrap::Aperiodic => 2 * n,
        };
        let mut planner = FftPlanner::new();
        let forward = planner.plan_fft_forward(len);
        let inverse = planner.plan_fft_inverse(len);
        let scratch = vec![
            Complex64::new(0.0, 0.0);
            forward
                .get_inplace_scratch_len()
                .max(inverse.get_inplace_scratch_len())
        ];
        let mut s_spectrum = vec![Complex64::new(0.0, 0.0); len];
        s_spectrum[..n].copy_from_slice(s);
        let mut a = Ambiguity {
            fs,
            n,
            len,
            x: x.iter().copied().take(n).collect(),
            s_spectrum: Vec::new(),
            energy,
            forward,
            inverse,
            scratch,
        };
        a.x.resize(n, Complex64::new(0.0, 0.0));
        a.forward
            .process_with_scratch(&mut s_spectrum, &mut a.scratch);
        a.s_spectrum = s_spectrum;
        Some(a)
    }

    /// Lags of one cut (`n` periodic, `2n` aperiodic); lag index `m` is the delay `m / fs` for
    /// `m < len / 2`, else `(m - len) / fs`.
    pub(crate) fn lags(&self) -> usize {
        self.len
    }

    /// The delay of lag index `m`, seconds.
    pub(crate) fn delay_s(&self, m: usize) -> f64 {
        let m = m as f64;
        let len = self.len as f64;
        if m < len / 2.0 {
            m / self.fs
        } else {
            (m - len) / self.fs
        }
    }

    /// The cut at Doppler `nu` Hz: `A(m, nu)` for every lag index.
    pub(crate) fn cut(&mut self, nu: f64) -> Vec<Complex64> {
        let mut buf = vec![Complex64::new(0.0, 0.0); self.len];
        let step = 2.0 * std::f64::consts::PI * nu / self.fs;
        for (k, (b, x)) in buf.iter_mut().zip(&self.x).enumerate() {
            *b = x * Complex64::from_polar(1.0, step * k as f64);
        }
        self.forward
            .process_with_scratch(&mut buf, &mut self.scratch);
        for (b, s) in buf.iter_mut().zip(&self.s_spectrum) {
            *b *= s.conj();
        }
        self.inverse
            .process_with_scratch(&mut buf, &mut self.scratch);
        let scale = 1.0 / (self.len as f64 * self.energy);
        for b in &mut buf {
            *b *= scale;
        }
        buf
    }

    /// The cut's largest magnitude and its lag index.
    pub(crate) fn peak(&mut self, nu: f64) -> (f64, usize) {
        self.cut(nu)
            .iter()
            .enumerate()
            .map(|(m, v)| (v.norm(), m))
            .fold((0.0, 0), |best, c| if c.0 > best.0 { c } else { best })
    }

    /// The smallest Doppler shift (Hz, positive) at which the cut's largest magnitude has fallen
    /// `loss_db` under the zero-Doppler one; `None` when it never does up to `fs / 2`.
    pub(crate) fn doppler_for_loss(&mut self, loss_db: f64) -> Option<f64> {
        let (p0, _) = self.peak(0.0);
        if p0 <= 0.0 {
            return None;
        }
        let target = p0 * 10f64.powf(-loss_db / 20.0);
        let mut lo = 0.0;
        // The first step: a hundredth of the reference's Doppler resolution.
        let mut hi = self.fs / self.n as f64 * 0.01;
        loop {
            if self.peak(hi).0 <= target {
                break;
            }
            lo = hi;
            hi *= 2.0;
            if hi > self.fs / 2.0 {
                return None;
            }
        }
        for _ in 0..40 {
            let mid = 0.5 * (lo + hi);
            if self.peak(mid).0 <= target {
                hi = mid;
            } else {
                lo = mid;
            }
            if hi - lo <= 1e-6 * hi {
                break;
            }
        }
        Some(0.5 * (lo + hi))
    }
}

/// What the zero-Doppler cut shows about the main lobe and the side-lobes.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct CutFigures {
    /// The peak's magnitude (1 for a reference against itself).
    pub peak: f64,
    /// The peak's delay, seconds.
    pub peak_delay_s: f64,
    /// Main-lobe width at -3 dB, seconds (linear interpolation between lags).
    pub width_3db_s: f64,
    /// The highest side-lobe (outside the main lobe, bounded by its first minima) under the
    /// peak, dB.
    pub psl_db: f64,
    /// Energy outside the main lobe over the main lobe's, dB.
    pub isl_db: f64,
}

/// The figures of one cut (`cut[m]` at lag index `m`, circular), `delay` mapping an index to
/// seconds. `None` when the cut is empty or flat.
pub(crate) fn cut_figures(cut: &[Complex64], delay: impl Fn(usize) -> f64) -> Option<CutFigures> {
    let len = cut.len();
    if len < 3 {
        return None;
    }
    let mag: Vec<f64> = cut.iter().map(|v| v.norm()).collect();
    let (k, &peak) = mag.iter().enumerate().max_by(|a, b| a.1.total_cmp(b.1))?;
    if peak.is_nan() || peak <= 0.0 {
        return None;
    }
    let at = |i: isize| mag[i.rem_euclid(len as isize) as usize];
    let k = k as isize;
    // The main lobe: down both sides while the magnitude falls.
    let mut right = k;
    while right - k < len as isize / 2 && at(right + 1) < at(right) {
        right += 1;
    }
    let mut left = k;
    while k - left < len as isize / 2 && at(left - 1) < at(left) {
        left -= 1;
    }
    let half = peak / 2f64.sqrt();
    let cross = |dir: isize| -> f64 {
        let mut i = k;
        while at(i + dir) > half && (i - k).abs() < len as isize / 2 {
            i += dir;
        }
        let (a, b) = (at(i), at(i + dir));
        let f = if a > b { (a - half) / (a - b) } else { 0.0 };
        (i - k) as f64 + dir as f64 * f
    };
    let width_lags = cross(1) - cross(-1);
    let lag_s = (delay(1) - delay(0)).abs();
    let mut main = 0.0;
    let mut side = 0.0;
    let mut highest: f64 = 0.0;
    for (i, m) in mag.iter().enumerate() {
        let rel = (i as isize - k).rem_euclid(len as isize);
        let inside = rel <= right - k || rel >= len as isize - (k - left);
        if inside {
            main += m * m;
        } else {
            side += m * m;
            highest = highest.max(*m);
        }
    }
    Some(CutFigures {
        peak,
        peak_delay_s: delay(k as usize),
        width_3db_s: width_lags * lag_s,
        psl_db: 20.0 * (highest.max(1e-300) / peak).log10(),
        isl_db: 10.0 * (side.max(1e-300) / main).log10(),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A plain LFM pulse: `T` seconds, `B` Hz, centred on 0 Hz.
    fn lfm(fs: f64, t: f64, b: f64) -> Vec<Complex64> {
        let n = (t * fs).round() as usize;
        let k = b / t;
        (0..n)
            .map(|i| {
                let tt = i as f64 / fs - t / 2.0;
                Complex64::from_polar(1.0, std::f64::consts::PI * k * tt * tt)
            })
            .collect()
    }

    fn sinc(x: f64) -> f64 {
        if x.abs() < 1e-12 {
            1.0
        } else {
            (std::f64::consts::PI * x).sin() / (std::f64::consts::PI * x)
        }
    }

    #[test]
    fn a_plain_lfm_matches_its_closed_form() {
        let (fs, t, b) = (16e9, 1e-6, 1e9);
        let s = lfm(fs, t, b);
        let k = b / t;
        let mut a = Ambiguity::new(&s, &s, fs, Wrap::Aperiodic).unwrap();
        let mut worst: f64 = 0.0;
        for nu in [0.0, 0.3e6, 2.5e6, 20e6, -45e6, 150e6] {
            let cut = a.cut(nu);
            for m in (0..a.lags()).step_by(97) {
                let tau = a.delay_s(m);
                if tau.abs() > t {
                    continue;
                }
                let closed = (1.0 - tau.abs() / t) * sinc((nu + k * tau) * (t - tau.abs())).abs();
                worst = worst.max((cut[m].norm() - closed).abs());
            }
        }
        assert!(
            worst < 5e-3,
            "largest difference to the closed form {worst}"
        );
        // Zero-Doppler cut: PSL of the sinc (-13.26 dB), the 3 dB width 0.886 / B.
        let f = cut_figures(&a.cut(0.0), |m| a.delay_s(m)).unwrap();
        assert!((f.psl_db + 13.26).abs() < 0.1, "{f:?}");
        assert!((f.width_3db_s * b - 0.886).abs() < 0.01, "{f:?}");
        assert!((f.peak - 1.0).abs() < 1e-9 && f.peak_delay_s == 0.0);
        // The peak falls as 1 - nu / B along the ridge: 1 dB at nu = (1 - 10^(-1/20)) B.
        let nu = a.doppler_for_loss(1.0).unwrap();
        let expected = (1.0 - 10f64.powf(-1.0 / 20.0)) * b;
        assert!(
            (nu - expected).abs() < 0.01 * expected,
            "{nu} vs {expected}"
        );
        // ... with the peak moved to tau = -nu / k.
        let (_, m) = a.peak(50e6);
        assert!(
            (a.delay_s(m) + 50e6 / k).abs() < 1.0 / fs,
            "{}",
            a.delay_s(m)
        );
    }

    #[test]
    fn periodic_and_cross_ambiguity() {
        let (fs, t, b) = (16e9, 0.5e-6, 1e9);
        let s = lfm(fs, t, b);
        // An echo 37 samples late and attenuated: the cross-ambiguity peaks there, at 0.25.
        let n = s.len();
        let x: Vec<Complex64> = (0..n).map(|i| 0.25 * s[(i + n - 37) % n]).collect();
        let mut a = Ambiguity::new(&x, &s, fs, Wrap::Periodic).unwrap();
        assert_eq!(a.lags(), n);
        let f = cut_figures(&a.cut(0.0), |m| a.delay_s(m)).unwrap();
        assert!((f.peak - 0.25).abs() < 1e-9, "{f:?}");
        assert!((f.peak_delay_s - 37.0 / fs).abs() < 1e-15);
        assert!(Ambiguity::new(&x, &[], fs, Wrap::Periodic).is_none());
    }
}
