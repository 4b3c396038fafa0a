//! Discrete echoes beyond a calibration's gate: the chain's (an IF cable mismatched at both ends
//! sends a copy of every path one round trip later, 6-20 ns on a lab bench) told from the
//! reference scene's (the Tx->Rx leakage ahead of the reference pillar, and what it makes).
//!
//! A gated estimate `H0` of the chain explains the reference's echo near its delay. What the
//! spectrum `Z` of the reference holds beyond that is, per bin, `Z / (X H0) = E S`: the chain's
//! echoes `E(f) = 1 + sum a_i e^{-j 2 pi f d_i}` (behind every path, so behind the reference:
//! `d_i > 0`) times the scene's `S(f) = 1 + sum c_k e^{-j 2 pi f t_k}` (the leakage, 2 R / c ahead
//! of the reference: `t_k < 0`). [`find`] takes the echoes out of `Z / (X H0) - 1` one at a time,
//! strongest first (each at its sub-sample delay, by golden-section search), and sorts them: ahead
//! of the reference is the scene; behind it is the chain, unless it sits where a scene echo's
//! chain echo would (`t_k + d_i`, at about `c_k a_i`). A reflector behind the reference within
//! [`Echoes::reach_s`] would be taken for the chain's: the reference must stand alone that far.

use super::response::BAND_FLOOR;
use num_complex::Complex64;
use std::f64::consts::PI;

/// One discrete echo relative to the reference's delay: `gain e^{-j 2 pi f delay_s}`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct Echo {
    pub delay_s: f64,
    pub gain: Complex64,
}

impl Echo {
    fn at(&self, f: f64) -> Complex64 {
        self.gain * Complex64::from_polar(1.0, -2.0 * PI * f * self.delay_s)
    }
}

/// The echoes found, sorted into the chain's and the scene's.
#[derive(Debug, Clone, Default, PartialEq)]
pub(crate) struct Echoes {
    /// Behind every path: corrected in every capture.
    pub chain: Vec<Echo>,
    /// The reference scene's own (the leakage ahead of the reference, and its chain echoes):
    /// divided out of the reference only.
    pub scene: Vec<Echo>,
    /// How far behind the reference the chain's echoes were searched, s.
    pub reach_s: f64,
    /// The weakest echo the search could take, power relative to the reference: the larger of
    /// its noise threshold and the weakest asked for (a weaker echo was left where it was).
    pub floor: f64,
}

impl Echoes {
    /// `1 + sum` of the chain's echoes at `f`.
    pub(crate) fn chain_at(&self, f: f64) -> Complex64 {
        factor(&self.chain, f)
    }

    /// `1 + sum` of the scene's echoes at `f`.
    pub(crate) fn scene_at(&self, f: f64) -> Complex64 {
        factor(&self.scene, f)
    }
}

fn factor(echoes: &[Echo], f: f64) -> Complex64 {
    echoes
        .iter()
        .fold(Complex64::new(1.0, 0.0), |acc, e| acc + e.at(f))
}

/// Limits of the search.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Search {
    /// Within this of the reference the gated estimate holds: not searched, s.
    pub inner_s: f64,
    /// Echoes are searched out to this either side, s.
    pub reach_s: f64,
    /// Weaker than this relative to the reference, an echo is left alone (dB).
    pub weakest_db: f64,
    /// Most echoes taken out.
    pub most: usize,
}

/// Echoes under this false-alarm probability per independent lag are taken for noise.
const PFA: f64 = 1e-4;
/// Golden-section steps for an echo's sub-sample delay.
const DELAY_STEPS: usize = 40;
/// A chain echo of a scene echo sits within this of `t_k + d_i`, s.
const PRODUCT_SLACK_S: f64 = 0.3e-9;

/// The echoes in the spectrum `z` (relative to the reference's delay) that `model` (`X H0`, per
/// bin) does not explain, over the bins where `coverage` (the waveform's gated power relative to
/// its peak) reaches [`BAND_FLOOR`]. `frequency_hz(k)` is bin `k`'s frequency, `fs` the rate.
pub(crate) fn find(
    z: &[Complex64],
    model: &[Complex64],
    coverage: &[f64],
    frequency_hz: impl Fn(usize) -> f64,
    fs: f64,
    search: Search,
) -> Echoes {
    let n = z.len();
    let mut found = Echoes {
        reach_s: search.reach_s,
        ..Echoes::default()
    };
    let Some(mut ratio) = Ratio::new(z, model, coverage, frequency_hz, fs) else {
        return found;
    };
    let (lo, hi) = ratio.span();
    let ifft = super::plans::inverse(n);
    let lag_s = |m: usize| {
        (if m <= n / 2 {
            m as f64
        } else {
            m as f64 - n as f64
        }) / fs
    };
    let searched = |m: usize| {
        let t = lag_s(m).abs();
        t > search.inner_s && t <= search.reach_s
    };
    let weakest = 10f64.powf(search.weakest_db / 10.0);
    let mut lags = vec![Complex64::new(0.0, 0.0); n];
    let mut noise_threshold = None;
    for _ in 0..search.most {
        lags.iter_mut().for_each(|v| *v = Complex64::new(0.0, 0.0));
        for ((&k, r), w) in ratio.band.iter().zip(&ratio.ratio).zip(&ratio.weight) {
            lags[k] = r * (*w / ratio.total);
        }
        ifft.process(&mut lags);
        let power: Vec<f64> = lags.iter().map(|v| v.norm_sqr()).collect();
        // The noise, once, from the lags searched before anything is taken out (the median of
        // an exponential is ln 2 of its mean; the echoes are too few to move it).
        let threshold = *noise_threshold.get_or_insert_with(|| {
            let mut p: Vec<f64> = (0..n).filter(|&m| searched(m)).map(|m| power[m]).collect();
            if p.is_empty() {
                return f64::INFINITY;
            }
            let mid = p.len() / 2;
            let median = *p.select_nth_unstable_by(mid, f64::total_cmp).1;
            // Independent lags: about the band's resolution apart.
            let independent = (2.0 * search.reach_s * (hi - lo)).max(1.0);
            median / std::f64::consts::LN_2 * (independent / PFA).ln()
        });
        // Local maxima only: the tail of what the gate holds is not an echo.
        let peak = |m: usize| power[m] >= power[(m + n - 1) % n] && power[m] >= power[(m + 1) % n];
        let Some(m) = (0..n)
            .filter(|&m| searched(m) && peak(m))
            .max_by(|&a, &b| power[a].total_cmp(&power[b]))
        else {
            break;
        };
        found.floor = threshold.max(weakest);
        if power[m] <= threshold.max(weakest) {
            break;
        }
        let echo = ratio.take_near(lag_s(m), 1.0 / fs);
        sort_into(&mut found, echo);
    }
    found
}

/// The echo the user named near `delay_s` (within `within_s`, relative to the reference) in
/// the spectrum `z` that `model` does not explain: its delay where its power peaks there, and its
/// gain (the same measure as [`find`]'s, at any level: the user says it is there). `None` when
/// the band is too narrow to measure it.
pub(crate) fn named(
    z: &[Complex64],
    model: &[Complex64],
    coverage: &[f64],
    frequency_hz: impl Fn(usize) -> f64,
    fs: f64,
    delay_s: f64,
    within_s: f64,
) -> Option<Echo> {
    let mut ratio = Ratio::new(z, model, coverage, frequency_hz, fs)?;
    Some(ratio.take_near(delay_s, within_s))
}

/// `z / model - 1` over the band, with the weights an echo's gain is measured with.
struct Ratio {
    band: Vec<usize>,
    freqs: Vec<f64>,
    weight: Vec<f64>,
    total: f64,
    ratio: Vec<Complex64>,
    df: f64,
}

impl Ratio {
    fn new(
        z: &[Complex64],
        model: &[Complex64],
        coverage: &[f64],
        frequency_hz: impl Fn(usize) -> f64,
        fs: f64,
    ) -> Option<Self> {
        let n = z.len();
        let band: Vec<usize> = (0..n)
            .filter(|&k| coverage[k] >= BAND_FLOOR && model[k].norm_sqr() > 0.0)
            .collect();
        if band.len() < 8 || n < 16 {
            return None;
        }
        let freqs: Vec<f64> = band.iter().map(|&k| frequency_hz(k)).collect();
        let (lo, hi) = span(&freqs);
        // Weights: the model's power (where the ratio is well measured) under a Hann taper over
        // the band (its side-lobes, not the band edge's sinc, decide what lies beside an echo).
        let peak = band
            .iter()
            .map(|&k| model[k].norm_sqr())
            .fold(0.0, f64::max);
        let weight: Vec<f64> = band
            .iter()
            .zip(&freqs)
            .map(|(&k, &f)| {
                let taper = (PI * (f - lo) / (hi - lo).max(1.0)).sin().powi(2);
                (model[k].norm_sqr() / peak).min(1.0) * taper
            })
            .collect();
        let total: f64 = weight.iter().sum();
        if total <= 0.0 {
            return None;
        }
        let ratio: Vec<Complex64> = band
            .iter()
            .map(|&k| z[k] / model[k] - Complex64::new(1.0, 0.0))
            .collect();
        Some(Ratio {
            band,
            freqs,
            weight,
            total,
            ratio,
            df: fs / n as f64,
        })
    }

    fn span(&self) -> (f64, f64) {
        span(&self.freqs)
    }

    /// The ratio's weighted mean at delay `t`: an echo's gain there.
    fn gain_at(&self, t: f64) -> Complex64 {
        let mut sum = Complex64::new(0.0, 0.0);
        let w = &self.weight;
        let r = &self.ratio;
        super::phasor::for_each(self.freqs.iter().copied(), 2.0 * PI * t, self.df, |i, p| {
            sum += r[i] * w[i] * p;
        });
        sum / self.total
    }

    /// The echo within `step` of `start` (at its sub-sample delay), taken out of the ratio.
    fn take_near(&mut self, start: f64, step: f64) -> Echo {
        let t = refine_delay(|t| self.gain_at(t).norm_sqr(), start, step);
        let echo = Echo {
            delay_s: t,
            gain: self.gain_at(t),
        };
        let ratio = &mut self.ratio;
        super::phasor::for_each(
            self.freqs.iter().copied(),
            -2.0 * PI * t,
            self.df,
            |i, p| {
                ratio[i] -= echo.gain * p;
            },
        );
        echo
    }
}

fn span(freqs: &[f64]) -> (f64, f64) {
    freqs
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), &f| {
            (a.min(f), b.max(f))
        })
}

/// Files `echo` with the scene (ahead of the reference, or a scene echo's chain echo) or the
/// chain (behind it).
fn sort_into(found: &mut Echoes, echo: Echo) {
    if echo.delay_s < 0.0 {
        found.scene.push(echo);
        return;
    }
    let level = echo.gain.norm();
    let product = found.scene.iter().any(|s| {
        found.chain.iter().any(|c| {
            let expected = s.gain.norm() * c.gain.norm();
            (echo.delay_s - (s.delay_s + c.delay_s)).abs() <= PRODUCT_SLACK_S
                && level < 3.0 * expected
                && level > expected / 3.0
        })
    });
    if product {
        found.scene.push(echo);
    } else {
        found.chain.push(echo);
    }
}

/// The delay near `start` (within a sample `step`) where `power(t)` peaks: golden-section search.
pub(crate) fn refine_delay(power: impl Fn(f64) -> f64, start: f64, step: f64) -> f64 {
    let g = (5f64.sqrt() - 1.0) / 2.0;
    let (mut a, mut b) = (start - step, start + step);
    let mut c = b - g * (b - a);
    let mut d = a + g * (b - a);
    let (mut fc, mut fd) = (power(c), power(d));
    for _ in 0..DELAY_STEPS {
        if fc > fd {
            b = d;
            d = c;
            fd = fc;
            c = b - g * (b - a);
            fc = power(c);
        } else {
            a = c;
            c = d;
            fc = fd;
            d = a + g * (b - a);
            fd = power(d);
        }
    }
    0.5 * (a + b)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::rng::SplitMix64;

    /// Bin `k`'s frequency of `n` at `fs`, Hz.
    fn frequency(n: usize, fs: f64) -> impl Fn(usize) -> f64 {
        move |k| {
            (if k <= n / 2 {
                k as f64
            } else {
                k as f64 - n as f64
            }) * fs
                / n as f64
        }
    }

    /// A flat band of `n` bins at `fs`, 1/16 of it in band, and a reference spectrum with
    /// `echoes` (relative delays and gains), plus noise of `sigma` per bin.
    fn spectrum(n: usize, fs: f64, echoes: &[Echo], sigma: f64) -> (Vec<Complex64>, Vec<f64>) {
        let mut rng = SplitMix64::new(5);
        let f = frequency(n, fs);
        let coverage: Vec<f64> = (0..n)
            .map(|k| if f(k).abs() <= fs / 32.0 { 1.0 } else { 0.0 })
            .collect();
        let z = (0..n)
            .map(|k| factor(echoes, f(k)) + rng.complex_gaussian(sigma * sigma))
            .collect();
        (z, coverage)
    }

    #[test]
    fn a_cable_echo_is_the_chains_and_the_leakage_the_scenes() {
        let (n, fs) = (16384, 16e9);
        let cable = Echo {
            delay_s: 15.03e-9,
            gain: Complex64::from_polar(0.0316, 0.7),
        };
        let leakage = Echo {
            delay_s: -6.671e-9,
            gain: Complex64::from_polar(0.05, -1.2),
        };
        // The leakage's own cable echo: a product, at the sum of the delays.
        let both = Echo {
            delay_s: cable.delay_s + leakage.delay_s,
            gain: cable.gain * leakage.gain,
        };
        let (z, coverage) = spectrum(n, fs, &[cable, leakage, both], 1e-3);
        let model = vec![Complex64::new(1.0, 0.0); n];
        let f = frequency(n, fs);
        let search = Search {
            inner_s: 4e-9,
            reach_s: 40e-9,
            weakest_db: -70.0,
            most: 8,
        };
        let found = find(&z, &model, &coverage, f, fs, search);
        assert_eq!(found.chain.len(), 1, "{found:?}");
        let c = found.chain[0];
        assert!((c.delay_s - cable.delay_s).abs() < 5e-12, "{c:?}");
        assert!((c.gain - cable.gain).norm() < 0.002, "{c:?}");
        assert!(
            !found.scene.is_empty() && found.scene.len() <= 2,
            "{found:?}"
        );
        let l = found.scene[0];
        assert!((l.delay_s - leakage.delay_s).abs() < 5e-12, "{l:?}");
        assert!((l.gain - leakage.gain).norm() < 0.002, "{l:?}");
    }

    #[test]
    fn a_named_echo_is_measured_where_the_search_does_not_look() {
        let (n, fs) = (16384, 16e9);
        let reflector = Echo {
            delay_s: -3.671e-9,
            gain: Complex64::from_polar(0.06, 2.1),
        };
        let leakage = Echo {
            delay_s: -6.671e-9,
            gain: Complex64::from_polar(0.05, -1.2),
        };
        let (z, coverage) = spectrum(n, fs, &[reflector, leakage], 1e-3);
        let model = vec![Complex64::new(1.0, 0.0); n];
        let search = Search {
            inner_s: 5.7e-9,
            reach_s: 40e-9,
            weakest_db: -70.0,
            most: 8,
        };
        let found = find(&z, &model, &coverage, frequency(n, fs), fs, search);
        assert!(found.scene.iter().all(|e| e.delay_s < -5.7e-9), "{found:?}");
        // Named 3 cm off where it is, once the leakage beside it is taken out (as the
        // calibration's rounds do): measured where it is.
        let f = frequency(n, fs);
        let z: Vec<Complex64> = (0..n).map(|k| z[k] / found.scene_at(f(k))).collect();
        let named = named(&z, &model, &coverage, f, fs, -3.87e-9, 0.5e-9).unwrap();
        assert!(
            (named.delay_s - reflector.delay_s).abs() < 10e-12,
            "{named:?}"
        );
        assert!((named.gain - reflector.gain).norm() < 0.003, "{named:?}");
    }

    #[test]
    fn noise_alone_gives_no_echo() {
        let (n, fs) = (16384, 16e9);
        let (z, coverage) = spectrum(n, fs, &[], 3e-3);
        let model = vec![Complex64::new(1.0, 0.0); n];
        let f = frequency(n, fs);
        let search = Search {
            inner_s: 4e-9,
            reach_s: 40e-9,
            weakest_db: -90.0,
            most: 8,
        };
        let found = find(&z, &model, &coverage, f, fs, search);
        assert!(
            found.chain.is_empty() && found.scene.is_empty(),
            "{found:?}"
        );
    }
}
