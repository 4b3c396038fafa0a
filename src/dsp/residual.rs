//! What a response correction leaves on its reference pillar, seen through a range window: the
//! **residual profile** a detector's floor follows near strong targets (issue 38).
//!
//! A calibration fits the chain `H0` to the reference's relative spectrum `Z`; a capture corrected
//! with it keeps, on every path, `Z / (X H0) - 1` of what the fit did not explain (the gate's
//! taper, the chain echoes' estimation error, the noise of the reference). Through a window `W`
//! over the band that is, by lag, `r(t) = sum_k W_k R_k e^{j 2 pi f_k t} / sum_k W_k`: relative
//! to the pillar's own peak (the `1` it came with), what lies `t` behind (or ahead of) every
//! target once the target's fitted response is subtracted. [`profile`] samples it at least 8
//! times per range resolution cell and keeps the largest `|r|^2` per bin of range offset.

use super::window::Window;
use super::{DspError, C0};
use num_complex::Complex64;

/// Levels under this are written as this, dB.
pub(crate) const LOWEST_DB: f64 = -150.0;

/// Lags evaluated per range resolution cell (`c / 2B` of the weighted band) at least: a
/// residue's peak between two is then not missed by more than about 0.2 dB. A spectrum sampled
/// that finely already (a bench's 16 GSa/s for 1 GHz) is not zero padded; others up to 4 times.
const LAGS_PER_CELL: f64 = 8.0;
const MOST_UPSAMPLE: usize = 4;

/// One window's residual profile: the largest `|r|^2` relative to the pillar's peak, dB, in bins
/// of `bin_m` of range offset (bin `j` covers `[j bin_m, (j + 1) bin_m)`) behind the pillar and
/// ahead of it.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct Residual {
    pub(crate) bin_m: f64,
    pub(crate) behind_db: Vec<f64>,
    pub(crate) ahead_db: Vec<f64>,
}

/// The weights a range window puts on the spectrum's bins: `window`'s coefficients over the bins
/// whose frequency (`frequency_hz(k)`, Hz) lies in `band_hz`, ascending (as the windowed
/// correlation and the OFDM window weigh them); for [`Window::Rectangular`] the matched filter's
/// own weight, `power` (the transmitted power per bin). Zero elsewhere.
pub(crate) fn window_weights(
    window: &Window,
    power: &[f64],
    frequency_hz: impl Fn(usize) -> f64,
    band_hz: [f64; 2],
) -> Result<Vec<f64>, DspError> {
    let n = power.len();
    if *window == Window::Rectangular {
        return Ok(power.to_vec());
    }
    let mut band: Vec<usize> = (0..n)
        .filter(|&k| (band_hz[0]..=band_hz[1]).contains(&frequency_hz(k)))
        .collect();
    band.sort_by(|&a, &b| frequency_hz(a).total_cmp(&frequency_hz(b)));
    // The window is smooth across the band: taken at no more than WINDOW_POINTS points and
    // interpolated (within 1e-5 of the window at every bin; the test below).
    let points = band.len().min(WINDOW_POINTS);
    let coeffs = window.coefficients(points)?;
    let mut w = vec![0.0; n];
    let last = (band.len().max(2) - 1) as f64;
    for (i, &k) in band.iter().enumerate() {
        let t = i as f64 / last * (points.max(1) - 1) as f64;
        let j = (t.floor() as usize).min(points.saturating_sub(2));
        let f = t - j as f64;
        w[k] = match points {
            0 => 0.0,
            1 => coeffs[0],
            _ => coeffs[j] * (1.0 - f) + coeffs[j + 1] * f,
        };
    }
    Ok(w)
}

/// Most points a window is computed at for [`window_weights`] (interpolated between).
const WINDOW_POINTS: usize = 1025;

/// The residual profile of `ratio` (per bin of an `n`-point spectrum at `fs`: what the fit left,
/// `Z / (X H0) - 1`, zero where it is not measured) through `weight` (per bin,
/// [`window_weights`]), in bins of `bin_m` out to `reach_m` each side.
///
/// # Errors
///
/// [`DspError::Param`] when the lengths differ, the weights sum to zero or the bins are not
/// positive.
pub(crate) fn profile(
    ratio: &[Complex64],
    weight: &[f64],
    fs: f64,
    bin_m: f64,
    reach_m: f64,
) -> Result<Residual, DspError> {
    let n = ratio.len();
    let total: f64 = weight.iter().sum();
    if n < 4 || weight.len() != n || !(total > 0.0 && total.is_finite()) {
        return Err(DspError::Param(format!(
            "residual profile: {n} bins, {} weights summing to {total}; give as many weights as \
             bins, with a positive sum",
            weight.len()
        )));
    }
    if !(bin_m > 0.0 && reach_m >= bin_m && fs > 0.0) {
        return Err(DspError::Param(format!(
            "residual profile: bins of {bin_m} m out to {reach_m} m at {fs} Sa/s; allowed: \
             0 < bin <= reach, rate > 0"
        )));
    }
    // Zero padded: bin k of the spectrum at its signed place in m = upsample n points.
    let signed = |k: usize| {
        if k <= n / 2 {
            k as f64
        } else {
            k as f64 - n as f64
        }
    };
    let (lo, hi) = (0..n)
        .filter(|&k| weight[k] != 0.0)
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), k| {
            (lo.min(signed(k)), hi.max(signed(k)))
        });
    let span_hz = (hi - lo).max(1.0) * fs / n as f64;
    let upsample = ((LAGS_PER_CELL * span_hz / fs).ceil() as usize).clamp(1, MOST_UPSAMPLE);
    let m = upsample * n;
    let mut lags = vec![Complex64::new(0.0, 0.0); m];
    for k in 0..n {
        let at = if k <= n / 2 { k } else { k + m - n };
        lags[at] = ratio[k] * (weight[k] / total);
    }
    super::plans::inverse(m).process(&mut lags);
    let bins = (reach_m / bin_m).ceil() as usize;
    let (mut behind, mut ahead) = (vec![0.0f64; bins], vec![0.0f64; bins]);
    let metres_per_lag = C0 / 2.0 / (fs * upsample as f64);
    for (j, v) in lags.iter().enumerate() {
        let (side, lag) = if j <= m / 2 {
            (&mut behind, j)
        } else {
            (&mut ahead, m - j)
        };
        let b = (lag as f64 * metres_per_lag / bin_m) as usize;
        if b < bins {
            side[b] = side[b].max(v.norm_sqr());
        }
    }
    let db = |p: Vec<f64>| -> Vec<f64> {
        p.into_iter()
            .map(|p| (10.0 * p.max(1e-300).log10()).max(LOWEST_DB))
            .map(|d| (d * 10.0).round() / 10.0)
            .collect()
    };
    Ok(Residual {
        bin_m,
        behind_db: db(behind),
        ahead_db: db(ahead),
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::f64::consts::PI;

    /// An `n`-point spectrum at `fs` with the band `|f| <= fs / 4` weighted 1.
    fn band(n: usize, fs: f64) -> (Vec<f64>, impl Fn(usize) -> f64) {
        let freq = move |k: usize| {
            (if k <= n / 2 {
                k as f64
            } else {
                k as f64 - n as f64
            }) * fs
                / n as f64
        };
        let power = (0..n)
            .map(|k| if freq(k).abs() <= fs / 4.0 { 1.0 } else { 0.0 })
            .collect();
        (power, freq)
    }

    #[test]
    fn an_echo_left_behind_shows_at_its_offset_and_level_through_every_window() {
        let (n, fs) = (2048, 2e9);
        let (power, freq) = band(n, fs);
        // What the fit left: an echo 9.34 ns behind at -63 dB (1.4 m of range).
        let (delay, level) = (9.34e-9, 10f64.powf(-63.0 / 20.0));
        let ratio: Vec<Complex64> = (0..n)
            .map(|k| {
                if power[k] > 0.0 {
                    Complex64::from_polar(level, -2.0 * PI * freq(k) * delay)
                } else {
                    Complex64::new(0.0, 0.0)
                }
            })
            .collect();
        for window in [
            Window::Rectangular,
            Window::Hann,
            Window::Taylor {
                nbar: 4,
                sll_db: -35.0,
            },
            Window::Chebyshev { sll_db: -50.0 },
        ] {
            let w = window_weights(&window, &power, &freq, [-fs / 4.0, fs / 4.0]).unwrap();
            let r = profile(&ratio, &w, fs, 0.05, 3.0).unwrap();
            assert_eq!(r.behind_db.len(), 60);
            let at = (1.4 / 0.05) as usize;
            let (peak_bin, peak) = r
                .behind_db
                .iter()
                .enumerate()
                .max_by(|a, b| a.1.total_cmp(b.1))
                .unwrap();
            assert!(
                peak_bin.abs_diff(at) <= 1,
                "{window:?}: peak in bin {peak_bin}"
            );
            assert!((peak + 63.0).abs() < 0.5, "{window:?}: {peak} dB");
            // Nothing of it ahead of the pillar beyond the window's side-lobes.
            let ahead = r.ahead_db.iter().copied().fold(LOWEST_DB, f64::max);
            assert!(ahead < -63.0 - 12.0, "{window:?}: {ahead} dB ahead");
        }
    }

    #[test]
    fn a_wide_band_takes_the_window_interpolated_within_1e_5() {
        let (n, fs) = (8192, 4e9);
        let (power, freq) = band(n, fs);
        let hann = Window::Hann;
        let w = window_weights(&hann, &power, &freq, [-fs / 4.0, fs / 4.0]).unwrap();
        let mut band: Vec<usize> = (0..n).filter(|&k| freq(k).abs() <= fs / 4.0).collect();
        band.sort_by(|&a, &b| freq(a).total_cmp(&freq(b)));
        assert!(band.len() > 2 * WINDOW_POINTS);
        let exact = hann.coefficients(band.len()).unwrap();
        for (&k, e) in band.iter().zip(&exact) {
            assert!((w[k] - e).abs() < 1e-5, "bin {k}: {} against {e}", w[k]);
        }
        assert_eq!(w.iter().filter(|&&v| v != 0.0).count(), band.len() - 2);
    }

    #[test]
    fn nothing_left_is_the_lowest_level_and_bad_input_is_refused() {
        let (n, fs) = (256, 1e9);
        let (power, _) = band(n, fs);
        let ratio = vec![Complex64::new(0.0, 0.0); n];
        let r = profile(&ratio, &power, fs, 0.1, 1.0).unwrap();
        assert!(r
            .behind_db
            .iter()
            .chain(&r.ahead_db)
            .all(|&d| d == LOWEST_DB));
        assert!(profile(&ratio, &power[1..], fs, 0.1, 1.0).is_err());
        assert!(profile(&ratio, &vec![0.0; n], fs, 0.1, 1.0).is_err());
        assert!(profile(&ratio, &power, fs, 0.0, 1.0).is_err());
    }
}
