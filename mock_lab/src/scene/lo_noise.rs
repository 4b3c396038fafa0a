//! Residual phase noise when the Tx and the Rx share one LO.
//!
//! With one LO of phase `phi(t)`, the Tx sends `x(t) e^{-j phi(t)}` and the Rx mixes each echo
//! back with `e^{j phi(t)}`: a path of delay `tau` keeps `phi(t) - phi(t - tau)`, the LO's noise
//! decorrelated over the round trip (tens of ns), not a drift over the whole record. That is
//! synthesised as it happens: the transmitted signal on the record's grid times the LO's noise,
//! every path applied as one transfer function (one FFT pair over the record), and the Rx's LO.

use num_complex::Complex64;
use std::f64::consts::PI;

use super::sampling::ToGrid;
use super::{add_transfer, Path, Synthesizer};

/// Samples kept between the kept window and the FFT's wrap, each side: the fractional delays'
/// interpolation rings from the wrap's step, and 4096 samples later it is below -80 dB.
const GUARD: usize = 4096;

impl Synthesizer {
    /// Adds every path to `y` (grid at `fs` starting at `tx.t0`) with the shared LO's phase noise
    /// of Lorentzian `linewidth` (Hz).
    pub(super) fn render_lo_noise(
        &mut self,
        y: &mut [Complex64],
        tx: &ToGrid<'_>,
        fs: f64,
        paths: &[Path],
        linewidth: f64,
    ) {
        let len = y.len();
        let longest = paths.iter().map(|p| p.delay_s).fold(0.0, f64::max);
        let pre = (longest * fs).ceil() as usize + GUARD;
        let nfft = smooth_len(pre + len + GUARD);
        // The transmitted signal from `pre` samples before the window: one period, tiled.
        let unit = Path {
            delay_s: 0.0,
            amplitude: 1.0,
            carrier_hz: 0.0,
            doppler_hz: 0.0,
            phase_rad: 0.0,
        };
        let start = tx.t0 - pre as f64 / fs;
        self.render(tx.spectrum, tx.fs_awg, tx.up, start, &[&unit], tx.gain);
        // The LO's phasor, advanced by each Gaussian phase step (steps of ~1e-3 rad: the
        // second-order expansion is exact to 1e-10, and renormalising every few thousand samples
        // keeps its magnitude at 1) instead of one sincos per sample.
        let step = (2.0 * PI * linewidth / fs).sqrt();
        let mut lo = std::mem::take(&mut self.lo_phase);
        lo.clear();
        let mut at = Complex64::new(1.0, 0.0);
        for m in 0..nfft {
            let d = step * self.rng.gaussian();
            at *= Complex64::new(1.0 - 0.5 * d * d, d);
            if m % 4096 == 0 {
                at /= at.norm();
            }
            lo.push(at);
        }
        let mut u = std::mem::take(&mut self.lo_tx);
        u.clear();
        let period = &self.period;
        u.extend(
            lo.iter()
                .enumerate()
                .map(|(m, p)| period[m % period.len()] * p.conj()),
        );
        self.fft_in_place(&mut u, false);
        let df = fs / nfft as f64;
        let (still, moving): (Vec<&Path>, Vec<&Path>) =
            paths.iter().partition(|p| p.doppler_hz == 0.0);
        let mut groups: Vec<Vec<&Path>> = moving.into_iter().map(|p| vec![p]).collect();
        if !still.is_empty() {
            groups.push(still);
        }
        let mut v = std::mem::take(&mut self.lo_rx);
        for group in &groups {
            v.clear();
            v.resize(nfft, Complex64::new(0.0, 0.0));
            // Delays count from the grid's start, so the reference time is 0.
            add_transfer(&mut v, df, group, 0.0);
            for (h, x) in v.iter_mut().zip(&u) {
                *h *= x / nfft as f64;
            }
            self.fft_in_place(&mut v, true);
            let doppler = group[0].doppler_hz;
            let mut rot = Complex64::from_polar(1.0, 2.0 * PI * doppler * tx.t0);
            let turn = Complex64::from_polar(1.0, 2.0 * PI * doppler / fs);
            for (n, out) in y.iter_mut().enumerate() {
                let m = pre + n;
                *out += if doppler == 0.0 {
                    v[m] * lo[m]
                } else {
                    let r = rot;
                    rot *= turn;
                    v[m] * lo[m] * r
                };
            }
        }
        self.lo_phase = lo;
        self.lo_tx = u;
        self.lo_rx = v;
    }

    fn fft_in_place(&mut self, x: &mut [Complex64], inverse: bool) {
        let fft = self.plan(x.len(), inverse);
        let need = fft.get_inplace_scratch_len();
        if self.scratch.len() < need {
            self.scratch.resize(need, Complex64::new(0.0, 0.0));
        }
        fft.process_with_scratch(x, &mut self.scratch[..need]);
    }
}

/// The smallest length >= `n` whose only factors are 2, 3 and 5 (fast for rustfft).
fn smooth_len(n: usize) -> usize {
    let mut best = n.next_power_of_two();
    let mut p5 = 1usize;
    while p5 < best {
        let mut p3 = p5;
        while p3 < best {
            let mut p2 = p3;
            while p2 < n {
                p2 *= 2;
            }
            best = best.min(p2);
            p3 *= 3;
        }
        p5 *= 5;
    }
    best
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn smooth_lengths() {
        assert_eq!(smooth_len(1), 1);
        assert_eq!(smooth_len(7), 8);
        assert_eq!(smooth_len(1_300_000), 1_310_720);
        for n in [17, 1000, 99_999, 1_288_193] {
            let s = smooth_len(n);
            let mut r = s;
            for p in [2, 3, 5] {
                while r % p == 0 {
                    r /= p;
                }
            }
            assert!(s >= n && r == 1, "{n} -> {s}");
        }
    }
}
