//! Test signals for the dsp tests, built here so the dsp tests do not depend on src/waveform:
//! random QPSK symbol matrices, the echo model of CONVENTIONS.md applied per subcarrier, and the
//! OFDM modulator of CONVENTIONS.md (ideal interpolation, 1/sqrt(N) scale, CP prepended).
#![allow(dead_code)]

use num_complex::Complex64;
use radbench::dsp::C0;
use radbench::rng::SplitMix64;
use rustfft::FftPlanner;
use std::f64::consts::PI;

pub const N: usize = 128;
pub const OS: usize = 16;
pub const B: f64 = 1e9;
pub const DF: f64 = B / N as f64;
pub const FC_PHYSICAL: f64 = 80e9;
pub const FC_THESIS: f64 = B / 2.0;

/// A target: range (m), amplitude, range rate (m/s).
#[derive(Clone, Copy, Debug)]
pub struct Target {
    pub range: f64,
    pub amp: f64,
    pub velocity: f64,
}

pub fn target(range: f64) -> Target {
    Target {
        range,
        amp: 1.0,
        velocity: 0.0,
    }
}

/// `symbols * n` Gray-QPSK symbols, symbol-major, from seeded bits.
pub fn qpsk(rng: &mut SplitMix64, symbols: usize, n: usize) -> Vec<Complex64> {
    let bits = rng.bits(2 * symbols * n);
    let r = std::f64::consts::FRAC_1_SQRT_2;
    bits.chunks_exact(2)
        .map(|b| Complex64::new((1.0 - 2.0 * b[0] as f64) * r, (1.0 - 2.0 * b[1] as f64) * r))
        .collect()
}

/// The received symbol matrix: `sum a exp(-j 2 pi (fc + f_k) tau_s) X[s][k]`, with
/// `tau_s = 2 (R + v s T) / C0` (Doppler within a symbol neglected).
pub fn echo_symbols(
    tx: &[Complex64],
    n: usize,
    df: f64,
    fc: f64,
    symbol_period: f64,
    targets: &[Target],
) -> Vec<Complex64> {
    let mut out = vec![Complex64::default(); tx.len()];
    for (s, (row_in, row_out)) in tx.chunks_exact(n).zip(out.chunks_exact_mut(n)).enumerate() {
        for t in targets {
            let tau = 2.0 * (t.range + t.velocity * s as f64 * symbol_period) / C0;
            for (k, (x, y)) in row_in.iter().zip(row_out.iter_mut()).enumerate() {
                let f = fc + (k as f64 - (n / 2) as f64) * df;
                *y += x * Complex64::from_polar(t.amp, -2.0 * PI * f * tau);
            }
        }
    }
    out
}

/// OFDM modulation per CONVENTIONS.md: subcarrier k in bin (k - n/2) mod (n os), IFFT, scale
/// 1/sqrt(n), the last `cp` samples prepended.
pub fn modulate(symbols: &[Complex64], n: usize, os: usize, cp: usize) -> Vec<Complex64> {
    let l = n * os;
    let ifft = FftPlanner::new().plan_fft_inverse(l);
    let scale = 1.0 / (n as f64).sqrt();
    let mut out = Vec::with_capacity(symbols.len() / n * (l + cp));
    let mut buf = vec![Complex64::default(); l];
    for row in symbols.chunks_exact(n) {
        buf.fill(Complex64::default());
        for (k, x) in row.iter().enumerate() {
            buf[(k + l - n / 2) % l] = x * scale;
        }
        ifft.process(&mut buf);
        out.extend_from_slice(&buf[l - cp..]);
        out.extend_from_slice(&buf);
    }
    out
}

/// Delays a whole (band-limited) signal by `tau` seconds exactly, by a phase ramp on its spectrum,
/// and multiplies it by `amp exp(-j 2 pi fc tau)`: the echo model of CONVENTIONS.md. The signal is
/// treated as periodic, so pad it with zeros first.
pub fn delay(signal: &[Complex64], fs: f64, tau: f64, fc: f64, amp: f64) -> Vec<Complex64> {
    let n = signal.len();
    let mut planner = FftPlanner::new();
    let mut buf = signal.to_vec();
    planner.plan_fft_forward(n).process(&mut buf);
    for (i, v) in buf.iter_mut().enumerate() {
        let f = if i <= n / 2 {
            i as f64
        } else {
            i as f64 - n as f64
        } * fs
            / n as f64;
        *v *= Complex64::from_polar(amp / n as f64, -2.0 * PI * (f + fc) * tau);
    }
    planner.plan_fft_inverse(n).process(&mut buf);
    buf
}

/// A frame's time signal with noise of power `10^(-snr_db/10)` per complex sample (None: no noise).
pub fn received_signal(
    rng: &mut SplitMix64,
    tx: &[Complex64],
    fc: f64,
    targets: &[Target],
    snr_db: Option<f64>,
) -> Vec<Complex64> {
    let period = (N * OS + N * OS / 4) as f64 / (B * OS as f64);
    let rx_sym = echo_symbols(tx, N, DF, fc, period, targets);
    let mut rx = modulate(&rx_sym, N, OS, N * OS / 4);
    if let Some(snr) = snr_db {
        rng.add_noise(&mut rx, 10f64.powf(-snr / 10.0));
    }
    rx
}
