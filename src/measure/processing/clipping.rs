//! Clipping: the samples of each channel at the scope's ADC rails, counted where the scope's
//! words are turned into volts, what to change on the bench, and what clipping does to
//! detection.
//!
//! # The rails of a WORD
//! The LeCroy driver reads `CFMT DEF9,WORD,BIN`: each sample is a signed 16-bit word with the
//! ADC's code in its upper bits (the 8-bit code in the upper byte; `adc_bits` of the catalog).
//! A sample is at a rail when its code is the ADC's extreme code, whatever the lower bits hold:
//! for 8 bits the words 0x7F00..=0x7FFF (code 127) and 0x8000..=0x80FF (code -128), not only
//! +-32767. The lower byte is zero on a plain 8-bit acquisition; with averaging or ERES it holds
//! fractional bits, and an average in the top code still means every averaged sample sat at the
//! rail. [`Rails`] compares each word with two limits (no shifting), so counting a record costs
//! one pass over its words (well under a millisecond for 10^6 samples).
//!
//! # What clipping does to detection
//! A clipped record is `alpha x + d` (Bussgang): the echoes slightly compressed, plus distortion
//! `d`. For chirps much of `d` is intermodulation of the echoes (`x_a x_b conj(x_c)` for MSK-LFM is
//! the same chirp delayed by `tau_a + tau_b - tau_c`), which the matched filter compresses into
//! point-like responses at combination ranges: false targets 25-35 dB under the echoes at 8 %
//! clipped. (OFDM's products stay noise-like: the division by the transmitted symbols
//! decorrelates them.) [`mitigate`] predicts them: it builds the fitted echoes (targets and
//! reflectors outside the window) as the scope saw them, with the record's DC offset, scaled until
//! they clip as often as the capture did, clips them at the rails, fits each echo's own copy out
//! (least squares: a Bussgang gain per echo) and runs what is left through the same range
//! processing. Echoes join the model strongest first, each one only while the model does not
//! explain it (products are weaker than the echoes that make them); an echo the model explains,
//! not [`MODEL_MARGIN_DB`] above its distortion at its range, is not reported as a target, and
//! the threshold drawn includes the distortion. When the echoes cannot explain the clipping (it
//! would take more than [`MAX_MODEL_GAIN`] times their fitted level), the bound of a Gaussian
//! signal clipped as often applies everywhere: no single product can exceed the distortion's
//! total power (Cauchy-Schwarz on the matched filter), so nothing weaker is reported.
//!
//! Measured on the mock lab: the model predicts the products' fitted levels within about 1 dB
//! (8-38 % clipped, MSK-LFM).

use super::detect::DetectionReport;
use super::range_result::RangeResult;
use super::transmit::Transmission;
use crate::measure::error::MeasureError;
use crate::physics::C0;
use num_complex::Complex64;
use serde::Serialize;
use std::f64::consts::PI;
use std::sync::Arc;

/// A detection must stand this far above the modelled distortion at its range, dB: the model
/// knows the echoes (not the noise, nor the bench's own non-linearity), so its products can be
/// off by a few dB.
pub(crate) const MODEL_MARGIN_DB: f64 = 10.0;

/// Largest factor the fitted echoes may be scaled by to clip as often as the capture: beyond it
/// something else (interference, a DC offset, noise) clipped, and the bound applies.
pub(crate) const MAX_MODEL_GAIN: f64 = 4.0;

/// Margin over the estimated peak in a suggested vertical scale (20 %).
const SCALE_MARGIN: f64 = 1.2;

/// The rails of an ADC whose code sits in the upper bits of a signed 16-bit word (or, for a
/// `.trc` in BYTE format, is the value itself).
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct Rails {
    bits: u8,
    /// Bits below the code.
    shift: u8,
    /// The lowest value holding the top code.
    top: i16,
    /// The highest value holding the bottom code.
    bottom: i16,
}

impl Rails {
    /// `bits` (1..=16) of code in the upper bits of each word (WORD format).
    pub(crate) fn word(bits: u8) -> Rails {
        let bits = bits.clamp(1, 16);
        Rails::with_shift(bits, 16 - bits)
    }

    /// An 8-bit code as the value itself (BYTE format).
    pub(crate) fn byte() -> Rails {
        Rails::with_shift(8, 0)
    }

    fn with_shift(bits: u8, shift: u8) -> Rails {
        let (bottom_code, top_code) = Rails::codes_of(bits);
        Rails {
            bits,
            shift,
            top: (top_code << shift) as i16,
            bottom: ((bottom_code << shift) + (1 << shift) - 1) as i16,
        }
    }

    fn codes_of(bits: u8) -> (i32, i32) {
        let b = bits - 1;
        (-(1i32 << b), (1i32 << b) - 1)
    }

    /// Whether `word` holds an extreme code.
    pub(crate) fn at_rail(&self, word: i16) -> bool {
        word >= self.top || word <= self.bottom
    }

    /// Words at either rail.
    pub(crate) fn count(&self, words: &[i16]) -> usize {
        // Two comparisons a word, no branch: the compiler vectorises this loop, on 16-bit lanes
        // within a chunk (a chunk's count fits in them).
        words
            .chunks(u16::MAX as usize)
            .map(|chunk| {
                let n: u16 = chunk.iter().map(|&w| u16::from(self.at_rail(w))).sum();
                usize::from(n)
            })
            .sum()
    }

    /// The rails in volts, `(bottom, top)`, for a channel's scaling `volts = gain * word -
    /// offset`: the extreme codes with zero lower bits.
    pub(crate) fn volts(&self, gain: f64, offset: f64) -> (f64, f64) {
        let (bottom, top) = self.codes();
        let at = |code: i32| gain * f64::from(code << self.shift) - offset;
        let (a, b) = (at(bottom), at(top));
        (a.min(b), a.max(b))
    }

    /// The extreme codes.
    fn codes(&self) -> (i32, i32) {
        Rails::codes_of(self.bits)
    }

    /// Bits of the code.
    pub(crate) fn bits(&self) -> u8 {
        self.bits
    }
}

/// What the bench knows about the scope's vertical settings, for a clipped capture's advice.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct ScopeAdc {
    pub(crate) rails: Rails,
    /// Volts per division of I and Q as set.
    pub(crate) volts_per_div: [f64; 2],
    /// The largest the catalog allows.
    pub(crate) volts_per_div_max: f64,
}

/// Samples at the ADC's rails, per channel.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub(crate) struct ClipCount {
    /// I samples at a rail.
    pub(crate) i: usize,
    /// Q samples at a rail.
    pub(crate) q: usize,
    /// Samples per channel looked at.
    pub(crate) samples: usize,
}

impl ClipCount {
    pub(crate) fn any(&self) -> bool {
        self.i + self.q > 0
    }

    /// Fraction of all I and Q samples at a rail.
    pub(crate) fn fraction(&self) -> f64 {
        (self.i + self.q) as f64 / (2 * self.samples).max(1) as f64
    }

    fn of(&self, channel: usize) -> usize {
        if channel == 0 {
            self.i
        } else {
            self.q
        }
    }

    fn fraction_of(&self, channel: usize) -> f64 {
        self.of(channel) as f64 / self.samples.max(1) as f64
    }

    pub(crate) fn add(&mut self, other: &ClipCount) {
        self.i += other.i;
        self.q += other.q;
        self.samples += other.samples;
    }
}

/// One record's clipping as processing sees it: the count and the rails in volts.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RecordClipping {
    pub(crate) count: ClipCount,
    /// `(bottom, top)` rail of I and of Q, volts.
    pub(crate) rails_v: [(f64, f64); 2],
    pub(crate) scope: Option<ScopeAdc>,
}

impl RecordClipping {
    /// The clipping of several records together (their count summed, the first one's rails).
    pub(crate) fn total(records: &[RecordClipping]) -> Option<RecordClipping> {
        let mut total = *records.first()?;
        for r in &records[1..] {
            total.count.add(&r.count);
        }
        Some(total)
    }
}

/// How detection was made conservative for a clipped record.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ClipDetection {
    /// `model`: the fitted echoes clipped as the capture was; `bound`: the Gaussian clipper's
    /// total distortion, everywhere.
    pub floor: &'static str,
    /// Distortion power over the received echoes' power, dB (the model's, or the bound's).
    pub distortion_db: f64,
    /// Echoes fitted but not reported as targets: clipping alone could have made them, m.
    pub suppressed_m: Vec<f64>,
}

/// A record's clipping as reported (`clipped_samples` in `summary.json`).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Clipping {
    pub i: usize,
    pub q: usize,
    /// Samples per channel (all repetitions of the record).
    pub samples: usize,
    /// Fraction of all I and Q samples at a rail.
    pub fraction: f64,
    pub fraction_i: f64,
    pub fraction_q: f64,
    /// How detection was adjusted (absent when nothing clipped or the algorithm has no
    /// detector).
    pub conservative_detection: Option<ClipDetection>,
}

impl Clipping {
    pub(crate) fn of(count: &ClipCount, detection: Option<ClipDetection>) -> Clipping {
        Clipping {
            i: count.i,
            q: count.q,
            samples: count.samples,
            fraction: count.fraction(),
            fraction_i: count.fraction_of(0),
            fraction_q: count.fraction_of(1),
            conservative_detection: detection,
        }
    }
}

/// The distortion clipping adds, per cell of the primary profile (power, like a target's
/// `|a|^2`), and how it was found.
struct Floor {
    power: Vec<f64>,
    kind: &'static str,
    distortion_db: f64,
    /// What the scope's I and Q saw (model only).
    scale: Option<[Reach; 2]>,
    /// Fitted echoes (index into targets then outside) the model takes for real reflectors.
    real: Vec<usize>,
}

/// How far a channel's signal (echoes and DC offset, unclipped) reaches against its rails.
#[derive(Debug, Clone, Copy)]
struct Reach {
    /// The largest excursion from 0 V, volts.
    peak_v: f64,
    /// The DC offset, volts.
    dc_v: f64,
    /// The vertical scale must grow this much for the signal to stay within the rails.
    need: f64,
}

/// One fitted echo: delay in samples of the aligned record, complex amplitude on the profile's
/// scale, and its profile cell.
#[derive(Debug, Clone, Copy)]
struct Echo {
    /// Index into the detection's targets, then its reflectors outside the window.
    index: usize,
    delay: f64,
    amplitude: Complex64,
    cell: Option<f64>,
}

/// The echoes as fitted: targets and reflectors outside the window, strongest first.
fn fitted_echoes(detection: &DetectionReport, offset_m: f64, fs: f64) -> Vec<Echo> {
    let mut echoes: Vec<Echo> = detection
        .targets
        .iter()
        .chain(&detection.outside)
        .enumerate()
        .filter_map(|(index, d)| {
            d.fitted.map(|(range_m, amplitude)| Echo {
                index,
                delay: (range_m - offset_m) * 2.0 * fs / C0,
                amplitude,
                cell: d.cell,
            })
        })
        .collect();
    echoes.sort_by(|a, b| b.amplitude.norm().total_cmp(&a.amplitude.norm()));
    echoes
}

/// The largest of `power` within a cell of `cell`.
fn near(power: &[f64], cell: f64) -> f64 {
    let n = power.len();
    if n == 0 {
        return 0.0;
    }
    let c = (cell.round().max(0.0) as usize).min(n - 1);
    power[c.saturating_sub(1)..=(c + 1).min(n - 1)]
        .iter()
        .copied()
        .fold(0.0, f64::max)
}

/// Calls `f(k, exp(-j 2 pi k_s x / n))` for every bin `k` of an `n`-point DFT, `k_s` its signed
/// frequency: a delay of `x` samples.
fn for_each_delay_bin(n: usize, x: f64, mut f: impl FnMut(usize, Complex64)) {
    let w = -2.0 * PI / n as f64;
    let step = Complex64::from_polar(1.0, w * x);
    let half = n / 2;
    let mut rot = Complex64::new(1.0, 0.0);
    for k in 0..=half.min(n.saturating_sub(1)) {
        f(k, rot);
        rot *= step;
    }
    let mut rot = Complex64::from_polar(1.0, w * x * ((half + 1) as f64 - n as f64));
    for k in half + 1..n {
        f(k, rot);
        rot *= step;
    }
}

/// Solves `a x = b` (complex, `a` square and well conditioned) by Gaussian elimination with
/// partial pivoting; `None` when singular.
fn solve(mut a: Vec<Vec<Complex64>>, mut b: Vec<Complex64>) -> Option<Vec<Complex64>> {
    let n = b.len();
    for col in 0..n {
        let pivot = (col..n).max_by(|&i, &j| a[i][col].norm().total_cmp(&a[j][col].norm()))?;
        if a[pivot][col].norm() < 1e-300 {
            return None;
        }
        a.swap(col, pivot);
        b.swap(col, pivot);
        let (upper, lower) = a.split_at_mut(col + 1);
        let pivot_row = &upper[col];
        for (row, r) in lower.iter_mut().enumerate() {
            let f = r[col] / pivot_row[col];
            for (x, p) in r[col..].iter_mut().zip(&pivot_row[col..]) {
                *x -= f * p;
            }
            let v = b[col];
            b[col + 1 + row] -= f * v;
        }
    }
    let mut x = vec![Complex64::new(0.0, 0.0); n];
    for row in (0..n).rev() {
        let mut s = b[row];
        for k in row + 1..n {
            s -= a[row][k] * x[k];
        }
        x[row] = s / a[row][row];
    }
    Some(x)
}

/// `v` clipped at the rails, I and Q separately.
fn clip(v: Complex64, rails: &[(f64, f64); 2]) -> Complex64 {
    Complex64::new(
        v.re.clamp(rails[0].0, rails[0].1),
        v.im.clamp(rails[1].0, rails[1].1),
    )
}

/// How many times the rail `x` reaches: above 1 it clips (0 for the wrong sign, infinite when
/// the rail is on the other side of 0 V).
fn reach(x: f64, (lo, hi): (f64, f64)) -> f64 {
    if x > 0.0 {
        if hi > 0.0 {
            x / hi
        } else {
            f64::INFINITY
        }
    } else if x < 0.0 {
        if lo < 0.0 {
            x / lo
        } else {
            f64::INFINITY
        }
    } else if hi <= 0.0 || lo >= 0.0 {
        f64::INFINITY
    } else {
        0.0
    }
}

/// The rails as seen by the signal without its DC offset `dc`.
fn shifted(rails: &[(f64, f64); 2], dc: Complex64) -> [(f64, f64); 2] {
    [
        (rails[0].0 - dc.re, rails[0].1 - dc.re),
        (rails[1].0 - dc.im, rails[1].1 - dc.im),
    ]
}

/// The gain that makes `g u + dc` clip in a fraction `wanted` of its I and Q samples (a sample
/// clips once `g` reaches 1 over its reach); `None` beyond [`MAX_MODEL_GAIN`].
fn gain_for_fraction(
    u: &[Complex64],
    rails: &[(f64, f64); 2],
    dc: Complex64,
    wanted: f64,
) -> Option<f64> {
    let rails = shifted(rails, dc);
    let mut r: Vec<f64> = u
        .iter()
        .flat_map(|v| [reach(v.re, rails[0]), reach(v.im, rails[1])])
        .collect();
    if r.is_empty() {
        return None;
    }
    let m = ((wanted * r.len() as f64).round() as usize).clamp(1, r.len()) - 1;
    // The m-th largest reach clips at g = 1 / reach.
    let (_, &mut at, _) = r.select_nth_unstable_by(m, |a, b| b.total_cmp(a));
    if at.is_infinite() {
        // The DC offset alone clips that often: the echoes as fitted.
        return Some(1.0);
    }
    (at > 0.0)
        .then(|| 1.0 / at)
        .filter(|g| *g <= MAX_MODEL_GAIN)
}

/// What the clipping's model asks of the pipeline that processed the record: its transmission,
/// record length, scale and range processing, to run modelled records through the same
/// processing (the pipeline implements it; the model never names the pipeline).
pub(crate) trait RangeProcessing {
    fn transmission(&self) -> &Arc<Transmission>;
    /// Samples in one repetition.
    fn period(&self) -> usize;
    /// Volts at the scope per unit of the profile's scale, inverted.
    fn level_scale(&self) -> f64;
    /// The range offset of a record aligned with `residual_s` left over, metres.
    fn offset_m(&self, residual_s: f64) -> f64;
    /// The range processing of `samples` (one repetition), ranges offset by `offset_m`.
    fn range_profiles(
        &mut self,
        samples: &[Complex64],
        offset_m: f64,
    ) -> Result<RangeResult, MeasureError>;
}

/// The echoes of a record as the scope saw them, clipped, and what is left once each echo's own
/// (compressed) copy is fitted out: the clipping's distortion.
struct Model<'a> {
    /// The spectrum of one repetition of the reference.
    reference: Vec<Complex64>,
    unit_v: f64,
    rails: [(f64, f64); 2],
    /// The record's DC offset, volts.
    dc: Complex64,
    wanted: f64,
    offset_m: f64,
    planner: rustfft::FftPlanner<f64>,
    echoes: &'a [Echo],
}

impl Model<'_> {
    /// The distortion (per profile cell, with [`MODEL_MARGIN_DB`]) when the echoes `real` (indices
    /// into `echoes`) are the reflectors; `None` when they cannot clip as often as the capture.
    fn floor(
        &mut self,
        pipeline: &mut dyn RangeProcessing,
        real: &[usize],
    ) -> Result<Option<Floor>, MeasureError> {
        let n = self.reference.len();
        let echoes: Vec<Echo> = real.iter().map(|&i| self.echoes[i]).collect();
        // sum_i a_i ref(m - x_i), in volts at the scope.
        let mut spec = vec![Complex64::new(0.0, 0.0); n];
        for e in &echoes {
            for_each_delay_bin(n, e.delay, |k, p| {
                spec[k] += self.reference[k] * p * e.amplitude
            });
        }
        let mut u = spec;
        self.planner.plan_fft_inverse(n).process(&mut u);
        let k = self.unit_v / n as f64;
        for v in &mut u {
            *v *= k;
        }
        let Some(g) = gain_for_fraction(&u, &self.rails, self.dc, self.wanted) else {
            return Ok(None);
        };
        let dc = self.dc;
        let mut w: Vec<Complex64> = u
            .iter()
            .map(|v| clip(v * g + dc, &self.rails) - dc)
            .collect();
        self.planner.plan_fft_forward(n).process(&mut w);
        // Least squares: each echo's own copy in the clipped record (the Bussgang gain per echo).
        let k = echoes.len();
        let power: Vec<f64> = self.reference.iter().map(|r| r.norm_sqr()).collect();
        let mut gram = vec![vec![Complex64::new(0.0, 0.0); k]; k];
        let mut proj = vec![Complex64::new(0.0, 0.0); k];
        for i in 0..k {
            for_each_delay_bin(n, echoes[i].delay, |b, p| {
                proj[i] += w[b] * (self.reference[b] * p).conj()
            });
            for j in i..k {
                let mut s = Complex64::new(0.0, 0.0);
                for_each_delay_bin(n, echoes[i].delay - echoes[j].delay, |b, p| {
                    s += power[b] * p
                });
                gram[i][j] = s;
                gram[j][i] = s.conj();
            }
        }
        let trace: f64 = (0..k).map(|i| gram[i][i].re).sum::<f64>() / k.max(1) as f64;
        for (i, row) in gram.iter_mut().enumerate() {
            row[i] += 1e-9 * trace;
        }
        let Some(beta) = solve(gram, proj) else {
            return Ok(None);
        };
        let mut d = w;
        for (e, b) in echoes.iter().zip(&beta) {
            for_each_delay_bin(n, e.delay, |k, p| d[k] -= self.reference[k] * p * b);
        }
        // The record's own DC is not distortion (and the detector never sees it as a target).
        d[0] = Complex64::new(0.0, 0.0);
        self.planner.plan_fft_inverse(n).process(&mut d);
        for v in &mut d {
            *v /= n as f64;
        }
        let distortion = d.iter().map(|v| v.norm_sqr()).sum::<f64>();
        let echo = u.iter().map(|v| v.norm_sqr()).sum::<f64>() * g * g;
        let range = pipeline.range_profiles(&d, self.offset_m)?;
        let Some(z) = range.complex else {
            return Ok(None);
        };
        let margin = 10f64.powf(MODEL_MARGIN_DB / 10.0);
        let channel = |f: fn(Complex64) -> f64, rails: (f64, f64)| {
            let (mut peak_v, mut need) = (0.0f64, 0.0f64);
            for v in &u {
                let x = f(v * g + dc);
                peak_v = peak_v.max(x.abs());
                need = need.max(reach(x, rails));
            }
            Reach {
                peak_v,
                dc_v: f(dc),
                need,
            }
        };
        Ok(Some(Floor {
            power: z.iter().map(|v| v.norm_sqr() * margin).collect(),
            kind: "model",
            distortion_db: 10.0 * (distortion.max(1e-300) / echo.max(1e-300)).log10(),
            scale: Some([
                channel(|v| v.re, self.rails[0]),
                channel(|v| v.im, self.rails[1]),
            ]),
            real: echoes.iter().map(|e| e.index).collect(),
        }))
    }
}

/// Most times the model is run for one record.
const MODEL_ROUNDS: usize = 8;

/// Which fitted echoes are reflectors and which clipping made, and the distortion of the
/// reflectors: starting from the strongest echo, the strongest echo the model does not explain
/// (stronger than its distortion there) joins the reflectors and the model runs again, until it
/// explains every other echo. Products are weaker than the echoes that make them, so those join
/// first. `None` when the echoes cannot explain the clipping.
fn model_floor(
    pipeline: &mut dyn RangeProcessing,
    aligned: &[Complex64],
    residual_s: f64,
    detection: &DetectionReport,
    clipping: &RecordClipping,
) -> Result<Option<Floor>, MeasureError> {
    let tx = pipeline.transmission().clone();
    let fs = tx.sample_rate_hz();
    let n = pipeline.period();
    let offset_m = pipeline.offset_m(residual_s);
    let echoes = fitted_echoes(detection, offset_m, fs);
    if echoes.is_empty() {
        return Ok(None);
    }
    let mut planner = rustfft::FftPlanner::<f64>::new();
    let mut reference = tx.reference.clone();
    reference.resize(n, Complex64::new(0.0, 0.0));
    planner.plan_fft_forward(n).process(&mut reference);
    let unit_v = 1.0 / pipeline.level_scale();
    // The record's mean less the echoes' own (bin 0 of their sum).
    let echoes_mean =
        reference[0] * echoes.iter().map(|e| e.amplitude).sum::<Complex64>() * unit_v / n as f64;
    let dc = aligned.iter().sum::<Complex64>() / aligned.len().max(1) as f64 - echoes_mean;
    let mut model = Model {
        reference,
        unit_v,
        rails: clipping.rails_v,
        dc,
        wanted: clipping.count.fraction(),
        offset_m,
        planner,
        echoes: &echoes,
    };
    let mut real = vec![0];
    let mut last = None;
    for round in 0..MODEL_ROUNDS {
        let floor = model.floor(pipeline, &real)?;
        let unexplained = |f: &Option<Floor>| {
            (0..echoes.len()).filter(|i| !real.contains(i)).find(|&i| {
                let e = &echoes[i];
                match (f, e.cell) {
                    (Some(f), Some(c)) => e.amplitude.norm_sqr() > near(&f.power, c),
                    // Too few reflectors to clip as often: the next one is needed.
                    (None, _) => true,
                    (_, None) => false,
                }
            })
        };
        match unexplained(&floor) {
            Some(i) if round + 1 < MODEL_ROUNDS => real.push(i),
            _ => {
                last = floor;
                break;
            }
        }
    }
    Ok(last)
}

/// `erfc(x)`, fractional error under 1.2e-7 (Numerical Recipes' Chebyshev fit).
fn erfc(x: f64) -> f64 {
    let z = x.abs();
    let t = 1.0 / (1.0 + 0.5 * z);
    let poly = -z * z - 1.265_512_23
        + t * (1.000_023_68
            + t * (0.374_091_96
                + t * (0.096_784_18
                    + t * (-0.186_288_06
                        + t * (0.278_868_07
                            + t * (-1.135_203_98
                                + t * (1.488_515_87 + t * (-0.822_152_23 + t * 0.170_872_77))))))));
    let r = t * poly.exp();
    if x >= 0.0 {
        r
    } else {
        2.0 - r
    }
}

/// Distortion over signal power of a Gaussian signal clipped symmetrically in a fraction `f` of
/// its samples (Bussgang: `alpha = 1 - f`, `E[y^2] = sigma^2 ((1 - f) - 2 k phi(k) + k^2 f)` for a
/// clip level `k sigma`).
pub(crate) fn gaussian_distortion(f: f64) -> f64 {
    if f <= 0.0 {
        return 0.0;
    }
    let f = f.min(0.999);
    // k with erfc(k / sqrt 2) = f; erfc falls with k.
    let (mut lo, mut hi) = (0.0f64, 12.0f64);
    for _ in 0..60 {
        let mid = 0.5 * (lo + hi);
        if erfc(mid / std::f64::consts::SQRT_2) > f {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    let k = 0.5 * (lo + hi);
    let phi = (-0.5 * k * k).exp() / (2.0 * PI).sqrt();
    let alpha = 1.0 - f;
    let y2 = (1.0 - f) - 2.0 * k * phi + k * k * f;
    ((y2 - alpha * alpha) / (alpha * alpha)).max(0.0)
}

/// The bound: the total distortion power of a Gaussian signal clipped as often, everywhere.
fn bound_floor(
    pipeline: &dyn RangeProcessing,
    aligned: &[Complex64],
    clipping: &RecordClipping,
    cells: usize,
) -> Floor {
    let d = 0.5
        * (gaussian_distortion(clipping.count.fraction_of(0))
            + gaussian_distortion(clipping.count.fraction_of(1)));
    let tx = pipeline.transmission();
    let n = aligned.len().max(1) as f64;
    let received = aligned.iter().map(|v| v.norm_sqr()).sum::<f64>() / n;
    let unit_v = 1.0 / pipeline.level_scale();
    let unit = tx.reference.iter().map(|v| v.norm_sqr()).sum::<f64>() / n * unit_v * unit_v;
    // Distortion power on the profile's scale: what a unit echo of its power would show.
    let floor = d / (1.0 + d) * received / unit.max(1e-300);
    Floor {
        power: vec![floor; cells],
        kind: "bound",
        distortion_db: 10.0 * d.max(1e-30).log10(),
        scale: None,
        real: Vec::new(),
    }
}

/// The next value of the 1-2-5 sequence at or above `v`.
fn one_two_five(v: f64) -> f64 {
    if !(v.is_finite() && v > 0.0) {
        return v;
    }
    let decade = 10f64.powf(v.log10().floor());
    [1.0, 2.0, 5.0, 10.0]
        .iter()
        .map(|m| m * decade)
        .find(|&c| c >= v * (1.0 - 1e-9))
        .unwrap_or(10.0 * decade)
}

fn volts(v: f64) -> String {
    if v.abs() < 1.0 {
        format!("{:.0} mV", v * 1e3)
    } else {
        format!("{v:.2} V")
    }
}

/// What to change: per clipped channel, its scale and a suggestion from what the signal reaches.
fn advice(clipping: &RecordClipping, scale: Option<[Reach; 2]>) -> String {
    let names = ["I (C1)", "Q (C2)"];
    let Some(scope) = clipping.scope else {
        return "Raise the scope's volts/div on the clipped channel, or add Rx attenuation.".into();
    };
    let mut parts = Vec::new();
    let mut attenuation_db: f64 = 0.0;
    let mut beyond = false;
    for ch in 0..2 {
        if clipping.count.of(ch) == 0 {
            continue;
        }
        let vdiv = scope.volts_per_div[ch];
        let Some(r) = scale.map(|s| s[ch]) else {
            parts.push(format!("{} is at {}/div", names[ch], volts(vdiv)));
            continue;
        };
        let (lo, hi) = clipping.rails_v[ch];
        let rail = if r.dc_v >= 0.0 { hi } else { -lo };
        let need = r.need * SCALE_MARGIN;
        let suggested = one_two_five(vdiv * need);
        let dc = if r.dc_v.abs() > 0.1 * rail.abs() {
            format!(
                " (with a DC offset of {}: check the receiver's I/Q offset)",
                volts(r.dc_v)
            )
        } else {
            String::new()
        };
        let reaches = format!(
            "{} is at {}/div and its signal reaches about {}{dc} against the {} rail",
            names[ch],
            volts(vdiv),
            volts(r.peak_v),
            volts(rail)
        );
        if !need.is_finite() {
            parts.push(format!("{reaches}: remove the offset"));
        } else if suggested > scope.volts_per_div_max * (1.0 + 1e-9) {
            beyond = true;
            attenuation_db = attenuation_db.max(20.0 * need.log10());
            parts.push(format!(
                "{reaches}: it needs {}/div, beyond the scope's largest {}/div",
                volts(suggested),
                volts(scope.volts_per_div_max)
            ));
        } else {
            attenuation_db = attenuation_db.max(20.0 * need.log10());
            parts.push(format!("{reaches}: set {}/div", volts(suggested)));
        }
    }
    let where_ = "(`volts_per_div` in the bench file's [scope] section sets both channels)";
    match scale {
        Some(_) if beyond => format!(
            "{}. Add at least {:.0} dB of Rx attenuation (`attenuation_db` under [rx]) and \
             raise volts/div {where_}.",
            parts.join("; "),
            attenuation_db.ceil()
        ),
        Some(_) => format!(
            "Raise the scope's volts/div: {} {where_}; or add {:.0} dB of Rx attenuation \
             (`attenuation_db` under [rx]).",
            parts.join("; "),
            attenuation_db.max(1.0).ceil()
        ),
        None => format!(
            "Raise the scope's volts/div ({}) until nothing clips {where_}, or add Rx \
             attenuation (`attenuation_db` under [rx]).",
            parts.join(", ")
        ),
    }
}

/// Makes detection conservative on a clipped record and says so: detections clipping alone
/// could have made are dropped (their ranges kept in the report), the threshold raised by the
/// distortion, and the warning written. The detection must come from the record `aligned`
/// (after background subtraction) processed by `pipeline`; call it after everything that reads
/// the pipeline's state of that record (velocities, range-Doppler map): the model runs through
/// the same range processing.
pub(crate) fn mitigate(
    pipeline: &mut dyn RangeProcessing,
    aligned: &[Complex64],
    residual_s: f64,
    detection: &mut DetectionReport,
    clipping: &RecordClipping,
) -> Result<(Option<ClipDetection>, String), MeasureError> {
    let c = &clipping.count;
    let (bottom, top) = clipping.scope.map_or((-128, 127), |s| s.rails.codes());
    let mut text = format!(
        "the capture clipped: {} of {} I samples ({:.2} %) and {} of {} Q samples ({:.2} %) sit \
         at the scope's ADC rails (codes {bottom} and {top}), so the echoes are compressed and \
         distorted. ",
        c.i,
        c.samples,
        100.0 * c.fraction_of(0),
        c.q,
        c.samples,
        100.0 * c.fraction_of(1),
    );
    let cells = detection.threshold.len();
    if cells == 0 {
        text += &advice(clipping, None);
        text += " The subspace estimates may include clipping products (at sums and differences \
                 of the echoes' ranges): check them against a capture that does not clip.";
        return Ok((None, text));
    }
    let floor = match model_floor(pipeline, aligned, residual_s, detection, clipping)? {
        Some(f) if f.power.len() == cells => f,
        _ => bound_floor(pipeline, aligned, clipping, cells),
    };
    let near = |cell: f64| near(&floor.power, cell);
    let mut suppressed = Vec::new();
    let mut index = 0;
    detection.targets.retain_mut(|t| {
        index += 1;
        let (Some(cell), Some((_, a))) = (t.cell, t.fitted) else {
            return true;
        };
        let p = a.norm_sqr();
        let f = near(cell);
        if p <= f && !floor.real.contains(&(index - 1)) {
            suppressed.push(t.range_m);
            return false;
        }
        if let Some(above) = t.above_threshold_db {
            // The threshold it passed, plus the distortion.
            let others = p / 10f64.powf(above / 10.0);
            t.above_threshold_db = Some(10.0 * (p / (others + f)).log10());
        }
        true
    });
    for (t, f) in detection.threshold.iter_mut().zip(&floor.power) {
        *t = (*t * *t + f).sqrt();
    }
    detection.strongest = super::detect::strongest(&detection.targets);
    text += &advice(clipping, floor.scale);
    text += &match floor.kind {
        "model" => format!(
            " Detection was made conservative: an echo is reported only {MODEL_MARGIN_DB:.0} dB \
             above the distortion the clipped echoes make at its range (distortion {:.1} dB \
             under the echoes)",
            -floor.distortion_db
        ),
        _ => format!(
            " Detection was made conservative: the echoes found do not explain the clipping, so \
             an echo is reported only above the total distortion power of a signal clipped as \
             often ({:.1} dB under the received power), anywhere",
            -floor.distortion_db
        ),
    };
    text += &if suppressed.is_empty() {
        "; no echo was dropped.".to_string()
    } else {
        let list: Vec<String> = suppressed.iter().map(|r| format!("{r:.3} m")).collect();
        format!(
            "; {} fitted echo{} not reported as target{}: {}.",
            suppressed.len(),
            if suppressed.len() == 1 {
                " was"
            } else {
                "es were"
            },
            if suppressed.len() == 1 { "" } else { "s" },
            list.join(", ")
        )
    };
    Ok((
        Some(ClipDetection {
            floor: floor.kind,
            distortion_db: floor.distortion_db,
            suppressed_m: suppressed,
        }),
        text,
    ))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_rails_of_an_8_bit_code_in_a_word_are_its_upper_byte_extremes() {
        let r = Rails::word(8);
        for w in [0x7F00i16, 0x7F01, 0x7FFF, i16::MIN, -32513] {
            assert!(r.at_rail(w), "{w:#06x}");
        }
        for w in [0x7EFFi16, 0, -32512, 0x7E00, -0x7E00] {
            assert!(!r.at_rail(w), "{w:#06x}");
        }
        // Codes -128..=127 in the upper byte: two of the 256 are rails.
        let words: Vec<i16> = (-128i16..=127).map(|c| c << 8).collect();
        assert_eq!(r.count(&words), 2);
        assert_eq!(r.count(&[127 << 8, 127 << 8, -128 << 8, 5 << 8, 0]), 3);
        assert_eq!(r.count(&[]), 0);
        // BYTE format: the code is the value.
        let b = Rails::byte();
        assert!(b.at_rail(127) && b.at_rail(-128) && !b.at_rail(126) && !b.at_rail(0));
        assert_eq!(b.volts(0.002, 0.0), (-0.256, 0.254));
        // A 12-bit code: its own extremes, not the byte's.
        let r12 = Rails::word(12);
        assert!(r12.at_rail(2047 << 4) && r12.at_rail(-2048 << 4));
        assert!(!r12.at_rail(2046 << 4) && !r12.at_rail(127 << 8));
        // Rails in volts with a channel's scaling: 8 divisions of 25 codes, 50 mV/div.
        let gain = 0.05 / (25.0 * 256.0);
        let (lo, hi) = r.volts(gain, 0.0);
        assert!((hi - 127.0 * 0.002).abs() < 1e-12 && (lo + 128.0 * 0.002).abs() < 1e-12);
        let (lo, hi) = r.volts(gain, 0.1);
        assert!((hi - (0.254 - 0.1)).abs() < 1e-12 && (lo - (-0.256 - 0.1)).abs() < 1e-12);
    }

    #[test]
    fn counts_add_up_and_give_fractions() {
        let mut c = ClipCount {
            i: 10,
            q: 30,
            samples: 100,
        };
        c.add(&ClipCount {
            i: 0,
            q: 10,
            samples: 100,
        });
        assert_eq!((c.i, c.q, c.samples), (10, 40, 200));
        assert!((c.fraction() - 0.125).abs() < 1e-12);
        let j = Clipping::of(&c, None);
        assert!((j.fraction_i - 0.05).abs() < 1e-12 && (j.fraction_q - 0.2).abs() < 1e-12);
        assert!(!ClipCount::default().any() && c.any());
    }

    #[test]
    fn the_gaussian_clipper_distorts_more_the_more_it_clips() {
        assert_eq!(gaussian_distortion(0.0), 0.0);
        // 8.4 % clipped: a clip level of 1.73 sigma, distortion about -16 dB.
        let d = 10.0 * gaussian_distortion(0.084).log10();
        assert!((-17.5..-15.5).contains(&d), "{d}");
        let mut last = 0.0;
        for f in [1e-4, 1e-3, 0.01, 0.05, 0.2, 0.5] {
            let d = gaussian_distortion(f);
            assert!(d > last, "{f}: {d}");
            last = d;
        }
        assert!((erfc(0.0) - 1.0).abs() < 1e-7 && (erfc(1.0) - 0.157_299_2).abs() < 1e-7);
    }

    /// Pillars (delay in samples, amplitude) and a tone of `tone` times a unit echo's amplitude
    /// at 3 GHz, at the waveform rate, through an 8-bit ADC (code in the upper byte) whose rails
    /// sit at `rail` times the peak, as the scope's words.
    fn pillars_through_the_adc(
        tx: &crate::measure::Transmission,
        pillars: &[(usize, f64)],
        tone: f64,
        rail: f64,
    ) -> super::super::pipeline::RawWords {
        let n = tx.len();
        let unit_v = 127.0 * 0.5 / 255.0;
        let mut rx: Vec<Complex64> = (0..n)
            .map(|m| {
                let t = m as f64 / tx.sample_rate_hz();
                pillars
                    .iter()
                    .map(|&(d, a)| tx.reference[(m + n - d) % n] * a * unit_v)
                    .sum::<Complex64>()
                    + Complex64::from_polar(tone * unit_v, 2.0 * PI * 3e9 * t)
            })
            .collect();
        // A little deterministic dither so the ADC's steps are not all the noise there is.
        let mut state = 0x9E37_79B9_7F4A_7C15u64;
        for v in &mut rx {
            let mut next = || {
                state ^= state << 13;
                state ^= state >> 7;
                state ^= state << 17;
                (state >> 11) as f64 / (1u64 << 53) as f64 - 0.5
            };
            *v += Complex64::new(next(), next()) * (2e-3 * unit_v);
        }
        let peak = rx
            .iter()
            .map(|v| v.re.abs().max(v.im.abs()))
            .fold(0.0, f64::max);
        let gain = rail * peak / (127.0 * 256.0);
        let word = |v: f64| (((v / gain / 256.0).round().clamp(-128.0, 127.0)) as i16) << 8;
        super::super::pipeline::RawWords {
            i: rx.iter().map(|v| word(v.re)).collect(),
            q: rx.iter().map(|v| word(v.im)).collect(),
            gain: [gain; 2],
            offset: [0.0; 2],
            sample_rate_hz: tx.sample_rate_hz(),
            first_point_s: 0.0,
        }
    }

    #[test]
    fn a_clipped_record_is_counted_and_its_products_are_not_targets() {
        use crate::measure::{Dac, Pipeline, ProcessOptions, RecordGeometry, Transmission};
        use crate::waveform::WaveformSpec;
        let spec = WaveformSpec::msk_lfm_default();
        let tx = std::sync::Arc::new(Transmission::new(&spec, None, 1, Dac::default()).unwrap());
        let options = ProcessOptions::for_waveform(spec.kind());
        let geometry = RecordGeometry::for_capture(tx.len(), tx.sample_rate_hz(), &options);
        let adc = ScopeAdc {
            rails: Rails::word(8),
            volts_per_div: [0.05; 2],
            volts_per_div_max: 0.5,
        };
        let run = |pillars: &[(usize, f64)], rail: f64, counted: bool| {
            let mut p = Pipeline::new(tx.clone(), options.clone(), geometry).unwrap();
            p.set_awg_amplitude(0.5).unwrap();
            let raw = pillars_through_the_adc(&tx, pillars, 0.0, rail);
            let clipped = if counted {
                vec![Some(raw.clipping(&adc))]
            } else {
                Vec::new()
            };
            let bw = tx.bandwidth_hz();
            crate::measure::capture::process_repetitions(&mut p, &[raw], None, bw, &clipped)
                .unwrap()
                .0
        };
        // Two strong pillars and a weak one 25 dB under them, away from their products: 1.50,
        // 2.20 and 5.35 m at 16 GSa/s.
        let three = [(160usize, 0.9), (235, 0.9), (571, 0.05)];
        let pillars = [1.4990, 2.2016, 5.3494];
        let is_pillar = |r: f64| pillars.iter().any(|p| (p - r).abs() < 0.01);
        // Rails at half the peak: over a third of the samples clip.
        let counted = run(&three, 0.5, true);
        let c = counted.clipping.as_ref().unwrap();
        assert!(c.fraction > 0.3 && c.fraction < 0.45, "{c:?}");
        assert!(c.i > 0 && c.q > 0 && c.samples == tx.len());
        let found: Vec<f64> = counted.targets.iter().map(|t| t.range_m).collect();
        assert_eq!(found.len(), 3, "{found:?}");
        assert!(found.iter().all(|&r| is_pillar(r)), "{found:?}");
        let warning = counted
            .warnings
            .iter()
            .find(|w| w.starts_with("the capture clipped"))
            .expect("a clipping warning");
        assert!(
            warning.contains("50 mV/div") && warning.contains("Rx attenuation"),
            "{warning}"
        );
        let cd = c.conservative_detection.as_ref().unwrap();
        assert_eq!(cd.floor, "model");
        // The same record with its clipping not counted: the products are taken for targets.
        let blind = run(&three, 0.5, false);
        assert!(blind.clipping.is_none());
        let false_targets = blind
            .targets
            .iter()
            .filter(|t| !is_pillar(t.range_m))
            .count();
        assert!(false_targets > 0, "{:?}", blind.targets);
        assert_eq!(cd.suppressed_m.len(), false_targets, "{cd:?}");
        // Rails above the peak: nothing clips, nothing changes, no warning.
        let clean = run(&three, 1.5, true);
        let c = clean.clipping.as_ref().unwrap();
        assert_eq!((c.i, c.q, c.conservative_detection.is_none()), (0, 0, true));
        assert!(clean.warnings.iter().all(|w| !w.contains("clipped")));
        let plain = run(&three, 1.5, false);
        assert_eq!(clean.targets, plain.targets);
        assert_eq!(clean.detection.threshold, plain.detection.threshold);
    }

    #[test]
    fn clipping_the_echoes_do_not_explain_takes_the_bound() {
        use crate::measure::{Dac, Pipeline, ProcessOptions, RecordGeometry, Transmission};
        use crate::waveform::WaveformSpec;
        let spec = WaveformSpec::msk_lfm_default();
        let tx = std::sync::Arc::new(Transmission::new(&spec, None, 1, Dac::default()).unwrap());
        let options = ProcessOptions::for_waveform(spec.kind());
        let geometry = RecordGeometry::for_capture(tx.len(), tx.sample_rate_hz(), &options);
        let mut p = Pipeline::new(tx.clone(), options, geometry).unwrap();
        p.set_awg_amplitude(0.5).unwrap();
        // A strong tone out of the band clips; the one pillar is far too weak to.
        let raw = pillars_through_the_adc(&tx, &[(160, 0.1)], 3.0, 0.95);
        let adc = ScopeAdc {
            rails: Rails::word(8),
            volts_per_div: [0.05; 2],
            volts_per_div_max: 0.5,
        };
        let clipped = [Some(raw.clipping(&adc))];
        let bw = tx.bandwidth_hz();
        let (out, _, _) =
            crate::measure::capture::process_repetitions(&mut p, &[raw], None, bw, &clipped)
                .unwrap();
        let c = out.clipping.unwrap();
        assert!(c.fraction > 0.05, "{c:?}");
        let cd = c.conservative_detection.unwrap();
        assert_eq!(cd.floor, "bound");
        assert!(
            cd.distortion_db < -10.0 && cd.distortion_db > -40.0,
            "{cd:?}"
        );
        let w = &out.warnings[0];
        assert!(w.contains("do not explain the clipping"), "{w}");
        // No peak is known: the advice names the scale without a suggestion.
        assert!(w.contains("until nothing clips"), "{w}");
    }

    #[test]
    fn suggested_scales_follow_1_2_5() {
        assert_eq!(one_two_five(0.082), 0.1);
        assert_eq!(one_two_five(0.1), 0.1);
        assert!((one_two_five(0.12) - 0.2).abs() < 1e-15);
        assert!((one_two_five(0.3) - 0.5).abs() < 1e-15);
        assert!((one_two_five(0.6) - 1.0).abs() < 1e-15);
    }
}
