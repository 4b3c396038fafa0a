//! Polyphase FIR decimation with a designed anti-alias low-pass, usable in chunks.
//!
//! # The filter
//! A Kaiser-windowed sinc, linear phase, designed from a [`LowPassSpec`] whose edges are fractions of
//! the *input* sample rate. For the bench (80 GSa/s -> 16 GSa/s, factor 5, signal band +-0.5 GHz)
//! [`DecimatorConfig::default`] asks for:
//!
//! | edge | value | why |
//! |---|---|---|
//! | pass edge | 0.5 GHz (0.00625 fs_in) | the whole signal band (1 GHz wide, centred on 0 Hz) must stay flat: ripple <= 0.1 dB |
//! | stop edge | 8 GHz (0.1 fs_in) | the output Nyquist frequency: everything that would fold into the 16 GSa/s band is attenuated >= 60 dB, so noise does not alias either |
//!
//! The wide transition band (0.5 -> 8 GHz) is what makes the filter short: 41 taps. Lengths are
//! `2 D k + 1`, so the group delay `(L - 1) / 2` input samples is a whole number `k` of output
//! samples. Starting a little below Kaiser's length estimate, each length is tried with a small
//! search over the Kaiser beta and the cut-off, and the first length whose response, measured on a
//! dense grid, meets the spec wins: the attenuation is checked, not trusted to a formula.
//!
//! White noise loses `10 log10(1 / sum h^2)` dB in the filter: at
//! least the 7 dB of an ideal output-Nyquist filter (`10 log10 5`), more here because the designed
//! cut-off sits below the output Nyquist frequency. The signal band is untouched (0.1 dB), so the
//! per-sample SNR of an in-band signal rises by that amount.
//!
//! # Timing
//! Output sample `m` of the raw (causal) filter is `y[m] = sum_k h[k] x[m D - k]` with `x` zero before
//! the first input: it lags the input by the group delay `(L - 1) / 2` input samples. With
//! [`Alignment::Compensated`] (the default) the decimator drops the first `(L - 1) / (2 D)` outputs
//! and [`Decimator::finish`] flushes the same number at the end, so output `m` is the zero-phase
//! filtered input at `x[m D]` and a capture of `n` samples yields `ceil(n / D)` outputs, time-aligned
//! with the input: a target's delay (and the marker position) keeps its meaning after decimation.
//!
//! # Chunks
//! [`Decimator::process`] can be fed a capture in pieces of any size; the outputs are bit-identical to
//! one call with the whole capture. All buffers are allocated at construction (they grow only if a
//! later call needs more).
//!
//! # Speed
//! The input is transposed per block into `D` phase arrays (real and imaginary parts split), and
//! each tap is an axpy over 8 consecutive outputs held in registers, so the inner loop is contiguous
//! loads and multiply-adds. On x86-64 with AVX2 and FMA (checked at run time) the same kernel is
//! compiled for those instructions.

use num_complex::Complex64;

use super::DspError;

/// A record read by index, and by stride where that can be faster than one index at a time.
pub(crate) trait Samples {
    /// Sample `k`.
    fn at(&self, k: usize) -> Complex64;

    /// `(re[t], im[t]) = at(start + t * step)` for every `t`: the same values as
    /// [`at`](Self::at).
    fn strided(&self, start: usize, step: usize, re: &mut [f64], im: &mut [f64]) {
        for (t, (r, i)) in re.iter_mut().zip(im.iter_mut()).enumerate() {
            let z = self.at(start + t * step);
            *r = z.re;
            *i = z.im;
        }
    }
}

impl<F: Fn(usize) -> Complex64> Samples for F {
    fn at(&self, k: usize) -> Complex64 {
        self(k)
    }
}

/// A scope's 16-bit I and Q words as volts: `gain * word - offset` per channel.
pub(crate) struct ScaledWords<'a> {
    pub(crate) i: &'a [i16],
    pub(crate) q: &'a [i16],
    pub(crate) gain: [f64; 2],
    pub(crate) offset: [f64; 2],
}

impl Samples for ScaledWords<'_> {
    fn at(&self, k: usize) -> Complex64 {
        let ([gi, gq], [oi, oq]) = (self.gain, self.offset);
        Complex64::new(
            gi * f64::from(self.i[k]) - oi,
            gq * f64::from(self.q[k]) - oq,
        )
    }

    // The same arithmetic as `at`, with the words' bounds checked once per row.
    fn strided(&self, start: usize, step: usize, re: &mut [f64], im: &mut [f64]) {
        let count = re.len().min(im.len());
        if count == 0 {
            return;
        }
        let end = start + (count - 1) * step + 1;
        let ([gi, gq], [oi, oq]) = (self.gain, self.offset);
        let words = self.i[start..end]
            .iter()
            .step_by(step)
            .zip(self.q[start..end].iter().step_by(step));
        for ((r, m), (&a, &b)) in re.iter_mut().zip(im.iter_mut()).zip(words) {
            *r = gi * f64::from(a) - oi;
            *m = gq * f64::from(b) - oq;
        }
    }
}

/// Outputs computed per transposed block (sized so the phase arrays stay in the L1/L2 cache).
const BLOCK_OUT: usize = 512;
/// Outputs per register block of the kernel: 16 keeps 8 independent AVX2 accumulators in flight
/// (real and imaginary), enough to cover the multiply-add latency.
const LANES: usize = 16;
/// Frequency-grid points used to measure a designed response over [0, 0.5] cycles/sample.
const GRID: usize = 16_384;
/// Coarser grid used while searching candidate designs (the winner is checked on [`GRID`]).
const SEARCH_GRID: usize = 2048;
/// Longest filter the designer will produce.
const MAX_TAPS: usize = 16_385;

/// Low-pass requirements; edges in cycles per input sample (0 < pass < stop <= 0.5).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LowPassSpec {
    /// Highest frequency that must stay flat.
    pub pass_edge: f64,
    /// Lowest frequency that must be attenuated.
    pub stop_edge: f64,
    /// Minimum stop-band attenuation, dB (positive).
    pub stop_atten_db: f64,
    /// Maximum peak-to-peak pass-band ripple, dB.
    pub pass_ripple_db: f64,
}

/// Whether the decimator compensates the filter's group delay.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Alignment {
    /// Output `m` is aligned with input `m D` (delay removed; [`Decimator::finish`] flushes).
    #[default]
    Compensated,
    /// Plain causal filter: outputs lag by `(L - 1) / 2` input samples.
    Causal,
}

/// What to build: decimation factor, filter spec and alignment.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DecimatorConfig {
    pub factor: usize,
    pub spec: LowPassSpec,
    pub alignment: Alignment,
}

impl Default for DecimatorConfig {
    /// The bench: 80 GSa/s -> 16 GSa/s, flat over +-0.5 GHz, >= 60 dB from 8 GHz, delay compensated.
    fn default() -> Self {
        Self::for_band(80e9, 5, 0.5e9).expect("the default decimator spec is valid")
    }
}

impl DecimatorConfig {
    /// Decimation of a capture at `input_rate_hz` by `factor`, keeping a signal band of
    /// `+-band_edge_hz` flat (0.1 dB) and attenuating from the output Nyquist frequency on (60 dB).
    pub(crate) fn for_band(
        input_rate_hz: f64,
        factor: usize,
        band_edge_hz: f64,
    ) -> Result<Self, DspError> {
        if !(input_rate_hz.is_finite() && input_rate_hz > 0.0) {
            return Err(DspError::Param(format!(
                "input_rate_hz = {input_rate_hz}: must be a positive sample rate"
            )));
        }
        if factor < 2 {
            return Err(DspError::Param(format!(
                "decimation factor = {factor}: must be at least 2"
            )));
        }
        let out_nyquist = input_rate_hz / (2.0 * factor as f64);
        if !(band_edge_hz.is_finite() && band_edge_hz > 0.0 && band_edge_hz < out_nyquist) {
            return Err(DspError::Param(format!(
                "signal band edge = {band_edge_hz} Hz: must be above 0 and below the output Nyquist \
                 frequency {out_nyquist} Hz (input rate / (2 * factor))"
            )));
        }
        Ok(Self {
            factor,
            spec: LowPassSpec {
                pass_edge: band_edge_hz / input_rate_hz,
                stop_edge: 0.5 / factor as f64,
                stop_atten_db: 60.0,
                pass_ripple_db: 0.1,
            },
            alignment: Alignment::Compensated,
        })
    }
}

/// The measured response of a set of taps against a spec.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct MeasuredResponse {
    /// Smallest attenuation over [stop_edge, 0.5], dB.
    pub stop_atten_db: f64,
    /// Peak-to-peak ripple over [0, pass_edge], dB.
    pub pass_ripple_db: f64,
}

/// Magnitude of the response of real `taps` at `f` cycles/sample (DC gain of normalised taps: 1).
pub(crate) fn magnitude_response(taps: &[f64], f: f64) -> f64 {
    // sum_n h[n] e^{-j w n} with the phasor advanced by one complex multiply per tap (error about
    // L * 1e-16, far below any attenuation measured here).
    let step = Complex64::from_polar(1.0, -2.0 * std::f64::consts::PI * f);
    let mut phasor = Complex64::new(1.0, 0.0);
    let mut acc = Complex64::new(0.0, 0.0);
    for &h in taps {
        acc += phasor * h;
        phasor *= step;
    }
    acc.norm()
}

/// [`magnitude_response`] at each of `f`: the same bits, several times faster. The recurrence
/// of one frequency waits on its own last step; [`LANES`] frequencies side by side give the
/// processor independent work to overlap.
pub(crate) fn magnitude_responses(taps: &[f64], f: &[f64]) -> Vec<f64> {
    const LANES: usize = 8;
    let one = Complex64::new(1.0, 0.0);
    let mut out = Vec::with_capacity(f.len());
    for chunk in f.chunks(LANES) {
        let mut step = [one; LANES];
        for (s, &f) in step.iter_mut().zip(chunk) {
            *s = Complex64::from_polar(1.0, -2.0 * std::f64::consts::PI * f);
        }
        let mut phasor = [one; LANES];
        let mut acc = [Complex64::new(0.0, 0.0); LANES];
        for &h in taps {
            for j in 0..LANES {
                acc[j] += phasor[j] * h;
                phasor[j] *= step[j];
            }
        }
        out.extend(acc[..chunk.len()].iter().map(|a| a.norm()));
    }
    out
}

/// Measures `taps` on a dense grid (16 384 points over [0, 0.5], plus the band edges).
pub(crate) fn measure_response(taps: &[f64], spec: &LowPassSpec) -> MeasuredResponse {
    measure_response_on(taps, spec, GRID)
}

fn measure_response_on(taps: &[f64], spec: &LowPassSpec, points: usize) -> MeasuredResponse {
    let (mut stop_max, mut pass_min, mut pass_max) = (0.0f64, f64::INFINITY, 0.0f64);
    let grid = (0..=points)
        .map(|i| 0.5 * i as f64 / points as f64)
        .chain([spec.pass_edge, spec.stop_edge]);
    for f in grid {
        let a = magnitude_response(taps, f);
        if f >= spec.stop_edge {
            stop_max = stop_max.max(a);
        }
        if f <= spec.pass_edge {
            pass_min = pass_min.min(a);
            pass_max = pass_max.max(a);
        }
    }
    MeasuredResponse {
        stop_atten_db: -20.0 * stop_max.log10(),
        pass_ripple_db: 20.0 * (pass_max / pass_min).log10(),
    }
}

/// Kaiser's beta for a stop-band attenuation of `a` dB.
fn kaiser_beta(a: f64) -> f64 {
    if a > 50.0 {
        0.1102 * (a - 8.7)
    } else if a > 21.0 {
        0.5842 * (a - 21.0).powf(0.4) + 0.07886 * (a - 21.0)
    } else {
        0.0
    }
}

/// Modified Bessel function of the first kind, order 0 (power series; fine for the Kaiser beta range).
fn bessel_i0(x: f64) -> f64 {
    let q = x * x / 4.0;
    let (mut term, mut sum, mut k) = (1.0, 1.0, 0.0);
    while term > sum * 1e-17 {
        k += 1.0;
        term *= q / (k * k);
        sum += term;
    }
    sum
}

/// Kaiser-windowed sinc of odd length `len`, cut-off `cutoff` cycles/sample, DC gain 1.
fn kaiser_sinc(len: usize, cutoff: f64, beta: f64) -> Vec<f64> {
    let mid = (len - 1) as f64 / 2.0;
    let mut taps: Vec<f64> = (0..len)
        .map(|n| {
            let x = n as f64 - mid;
            let sinc = if x == 0.0 {
                2.0 * cutoff
            } else {
                (2.0 * std::f64::consts::PI * cutoff * x).sin() / (std::f64::consts::PI * x)
            };
            let r = if mid > 0.0 { x / mid } else { 0.0 };
            sinc * bessel_i0(beta * (1.0 - r * r).max(0.0).sqrt()) / bessel_i0(beta)
        })
        .collect();
    let dc: f64 = taps.iter().sum();
    for t in &mut taps {
        *t /= dc;
    }
    taps
}

/// Designs a linear-phase low-pass meeting `spec` whose length is `2 * multiple * k + 1`
/// (`multiple` = the decimation factor makes the group delay a whole number of output samples).
///
/// The Kaiser formulas give the first guess; the length then grows until the response measured by
/// [`measure_response`] meets the spec.
pub(crate) fn design_lowpass(spec: &LowPassSpec, multiple: usize) -> Result<Vec<f64>, DspError> {
    let LowPassSpec {
        pass_edge: fp,
        stop_edge: fst,
        stop_atten_db: atten,
        pass_ripple_db: ripple,
    } = *spec;
    if !(fp.is_finite() && fst.is_finite() && fp > 0.0 && fp < fst && fst <= 0.5) {
        return Err(DspError::Param(format!(
            "low-pass edges pass {fp}, stop {fst} (cycles/sample): need 0 < pass < stop <= 0.5"
        )));
    }
    if !(atten.is_finite() && (20.0..=150.0).contains(&atten)) {
        return Err(DspError::Param(format!(
            "stop-band attenuation {atten} dB: must be between 20 and 150 dB"
        )));
    }
    if !(ripple.is_finite() && ripple > 0.0) {
        return Err(DspError::Param(format!(
            "pass-band ripple {ripple} dB: must be positive"
        )));
    }
    let multiple = multiple.max(1);
    // Kaiser's formulas give beta and a first length. For each length (growing in steps that keep
    // the group delay a whole number of output samples) a small search over beta and the cut-off
    // (moved towards the pass edge, since the pass-band ripple allowance is usually loose) picks the
    // candidate with the most stop-band attenuation; the first length whose best candidate meets the
    // spec on the dense grid wins. The search starts two steps below the estimate.
    let beta0 = kaiser_beta(atten);
    let estimate =
        ((atten - 8.0) / (2.285 * 2.0 * std::f64::consts::PI * (fst - fp))).ceil() as usize + 1;
    let step = 2 * multiple;
    let mut len = (estimate.saturating_sub(1).div_ceil(step).max(3) - 2) * step + 1;
    while len <= MAX_TAPS {
        let mut best: Option<(f64, Vec<f64>)> = None;
        for db in [-0.5, -0.25, 0.0, 0.25, 0.5, 0.75] {
            for frac in [0.35, 0.4, 0.45, 0.5] {
                let taps = kaiser_sinc(len, fp + frac * (fst - fp), (beta0 + db).max(0.0));
                let m = measure_response_on(&taps, spec, SEARCH_GRID);
                if m.pass_ripple_db <= ripple
                    && best.as_ref().is_none_or(|(a, _)| m.stop_atten_db > *a)
                {
                    best = Some((m.stop_atten_db, taps));
                }
            }
        }
        if let Some((_, taps)) = best {
            let m = measure_response(&taps, spec);
            if m.stop_atten_db >= atten && m.pass_ripple_db <= ripple {
                return Ok(taps);
            }
        }
        len += step;
    }
    Err(DspError::Param(format!(
        "low-pass spec (pass {fp}, stop {fst}, {atten} dB, {ripple} dB ripple) needs more than \
         {MAX_TAPS} taps: widen the transition band"
    )))
}

/// Streaming polyphase FIR decimator for complex samples.
#[derive(Debug, Clone)]
pub struct Decimator {
    factor: usize,
    taps: Vec<f64>,
    alignment: Alignment,
    /// Taps in window order (`hr[j] = h[L-1-j]`) and, per tap, its offset in the phase block.
    reversed: Vec<f64>,
    tap_offset: Vec<usize>,
    /// Row stride of the phase block (outputs per block + taps per phase).
    stride: usize,
    /// Unconsumed input (history), and the phase block (`factor` rows, real and imaginary).
    hist: Vec<Complex64>,
    phase_re: Vec<f64>,
    phase_im: Vec<f64>,
    out_re: Vec<f64>,
    out_im: Vec<f64>,
    /// Outputs still to drop for delay compensation.
    to_skip: usize,
    /// Inputs seen since the last reset.
    inputs: u64,
    /// Zeros fed by `finish` (kept to avoid allocating per capture).
    flush: Vec<Complex64>,
    use_fma: bool,
}

impl Decimator {
    /// Designs the filter for `config` and sets up the buffers.
    ///
    /// # Errors
    ///
    /// [`DspError::Param`] when the factor is 0, the filter specification cannot be met (edges out
    /// of order, attenuation outside 20..=150 dB, ripple not positive), or a compensated alignment
    /// needs a group delay that is not a whole number of output samples.
    pub fn new(config: &DecimatorConfig) -> Result<Self, DspError> {
        if config.factor < 1 {
            return Err(DspError::Param(
                "decimation factor = 0: must be at least 1".into(),
            ));
        }
        let taps = design_lowpass(&config.spec, config.factor)?;
        Self::with_taps(config.factor, taps, config.alignment)
    }

    /// A decimator with your own taps. [`Alignment::Compensated`] needs a group delay of a whole
    /// number of output samples: `len = 2 * factor * k + 1`.
    pub(crate) fn with_taps(
        factor: usize,
        taps: Vec<f64>,
        alignment: Alignment,
    ) -> Result<Self, DspError> {
        if factor == 0 {
            return Err(DspError::Param(
                "decimation factor = 0: must be at least 1".into(),
            ));
        }
        if taps.is_empty() || taps.iter().any(|t| !t.is_finite()) {
            return Err(DspError::Param(
                "decimator taps: need at least one tap, all finite".into(),
            ));
        }
        let len = taps.len();
        if alignment == Alignment::Compensated && (len - 1) % (2 * factor) != 0 {
            return Err(DspError::Param(format!(
                "decimator taps: {len} taps give a group delay of {} input samples, not a whole \
                 number of output samples at factor {factor}; use 2 * factor * k + 1 taps or \
                 Alignment::Causal",
                (len - 1) as f64 / 2.0
            )));
        }
        let per_phase = len.div_ceil(factor);
        let stride = BLOCK_OUT + per_phase;
        let reversed: Vec<f64> = taps.iter().rev().copied().collect();
        let tap_offset = (0..len)
            .map(|j| (j % factor) * stride + j / factor)
            .collect();
        let mut d = Self {
            factor,
            taps,
            alignment,
            reversed,
            tap_offset,
            stride,
            hist: Vec::with_capacity(len + factor),
            phase_re: vec![0.0; factor * stride],
            phase_im: vec![0.0; factor * stride],
            out_re: vec![0.0; BLOCK_OUT],
            out_im: vec![0.0; BLOCK_OUT],
            to_skip: 0,
            inputs: 0,
            flush: Vec::with_capacity(len + factor),
            use_fma: fma_available(),
        };
        d.reset();
        Ok(d)
    }

    pub fn factor(&self) -> usize {
        self.factor
    }

    /// The filter taps `h[0..L]` (DC gain 1).
    pub fn taps(&self) -> &[f64] {
        &self.taps
    }

    /// Group delay of the filter in input samples, `(L - 1) / 2`.
    pub(crate) fn group_delay_input_samples(&self) -> f64 {
        (self.taps.len() - 1) as f64 / 2.0
    }

    /// Group delay in output samples, `(L - 1) / (2 D)`; removed when [`Alignment::Compensated`].
    pub fn group_delay_output_samples(&self) -> f64 {
        self.group_delay_input_samples() / self.factor as f64
    }

    /// How much the filter lowers white noise power, in dB: `-10 log10(sum h^2)` (DC gain is 1, so
    /// an in-band signal keeps its power and its per-sample SNR rises by this much).
    #[cfg(test)]
    pub(crate) fn noise_gain_db(&self) -> f64 {
        -10.0 * self.taps.iter().map(|h| h * h).sum::<f64>().log10()
    }

    pub fn alignment(&self) -> Alignment {
        self.alignment
    }

    /// Forgets all input: the next sample is the start of a new capture.
    pub fn reset(&mut self) {
        self.hist.clear();
        self.hist
            .resize(self.taps.len() - 1, Complex64::new(0.0, 0.0));
        self.to_skip = match self.alignment {
            Alignment::Compensated => (self.taps.len() - 1) / (2 * self.factor),
            Alignment::Causal => 0,
        };
        self.inputs = 0;
    }

    /// Number of outputs `ceil(n / D)` a whole capture of `n` samples gives (after
    /// [`Decimator::finish`] when compensated).
    pub fn output_len(&self, n: usize) -> usize {
        n.div_ceil(self.factor)
    }

    /// Feeds the next piece of the capture and appends every output it completes to `out`.
    pub fn process(&mut self, input: &[Complex64], out: &mut Vec<Complex64>) {
        self.inputs += input.len() as u64;
        let len = self.taps.len();
        let d = self.factor;
        let avail = self.hist.len() + input.len();
        if avail < len {
            self.hist.extend_from_slice(input);
            return;
        }
        let total = (avail - len) / d + 1;
        out.reserve(total.saturating_sub(self.to_skip));
        let mut done = 0;
        while done < total {
            let count = (total - done).min(BLOCK_OUT);
            self.fill_phases(input, done * d, count);
            self.run_kernel(count);
            let skip = self.to_skip.min(count);
            self.to_skip -= skip;
            out.extend(
                self.out_re[skip..count]
                    .iter()
                    .zip(&self.out_im[skip..count])
                    .map(|(&re, &im)| Complex64::new(re, im)),
            );
            done += count;
        }
        // Keep what the next output's window needs.
        let consumed = total * d;
        let hist_len = self.hist.len();
        if consumed >= hist_len {
            self.hist.clear();
            self.hist.extend_from_slice(&input[consumed - hist_len..]);
        } else {
            self.hist.drain(..consumed);
            self.hist.extend_from_slice(input);
        }
    }

    /// Ends the capture: with [`Alignment::Compensated`], flushes the outputs still owed (so the
    /// total is `ceil(n / D)`), then resets for the next capture. With [`Alignment::Causal`] it only
    /// resets.
    pub fn finish(&mut self, out: &mut Vec<Complex64>) {
        if self.alignment == Alignment::Compensated && self.inputs > 0 {
            let n = self.inputs as usize;
            let wanted = n.div_ceil(self.factor);
            let g = (self.taps.len() - 1) / (2 * self.factor);
            // Raw output wanted - 1 + g ends its window at input (wanted - 1 + g) D.
            let last_needed = (wanted - 1 + g) * self.factor;
            let zeros = (last_needed + 1).saturating_sub(n);
            self.flush.clear();
            self.flush.resize(zeros, Complex64::new(0.0, 0.0));
            let flush = std::mem::take(&mut self.flush);
            self.process(&flush, out);
            self.flush = flush;
        }
        self.reset();
    }

    /// One-shot: resets, decimates `input` whole and finishes.
    pub fn decimate(&mut self, input: &[Complex64]) -> Vec<Complex64> {
        self.reset();
        let mut out = Vec::with_capacity(self.output_len(input.len()));
        self.process(input, &mut out);
        self.finish(&mut out);
        out
    }

    /// Transposes the samples for `count` outputs starting `start` samples into `hist ++ input`.
    fn fill_phases(&mut self, input: &[Complex64], start: usize, count: usize) {
        let d = self.factor;
        let rows = count + self.stride - BLOCK_OUT;
        let hist = &self.hist;
        let avail = hist.len() + input.len();
        let (span_start, span_end) = (start, start + rows * d);
        if span_start >= hist.len() && span_end <= avail {
            // Fast path (every block but the first and last of a call): one sequential pass over
            // the input, scattering each sample to its phase row.
            let src = &input[span_start - hist.len()..span_end - hist.len()];
            for (i, group) in src.chunks_exact(d).enumerate() {
                for (r, z) in group.iter().enumerate() {
                    self.phase_re[r * self.stride + i] = z.re;
                    self.phase_im[r * self.stride + i] = z.im;
                }
            }
            return;
        }
        for r in 0..d {
            let row_re = &mut self.phase_re[r * self.stride..r * self.stride + rows];
            let row_im = &mut self.phase_im[r * self.stride..r * self.stride + rows];
            for (i, (re, im)) in row_re.iter_mut().zip(row_im.iter_mut()).enumerate() {
                let g = start + i * d + r;
                let z = if g < hist.len() {
                    hist[g]
                } else if g < avail {
                    input[g - hist.len()]
                } else {
                    Complex64::new(0.0, 0.0)
                };
                *re = z.re;
                *im = z.im;
            }
        }
    }

    /// The delay-compensated filter's outputs `ks` on the `n`-periodic signal `sample(p mod n)`,
    /// appended to `out`: output `k` is `sum_j hr[j] x[(k D + j - (L - 1) / 2) mod n]`. Each output
    /// is the same sum, in the same order, as [`process`](Self::process) gives for the periodic
    /// extension of the signal (the phase block holds the same samples; only the way they are
    /// gathered differs), so the same bits.
    fn periodic_into(
        &mut self,
        n: usize,
        sample: &impl Samples,
        ks: std::ops::Range<usize>,
        out: &mut Vec<Complex64>,
    ) {
        if n == 0 {
            return;
        }
        let d = self.factor;
        let half = (self.taps.len() - 1) / 2;
        let stride = self.stride;
        let mut k0 = ks.start;
        while k0 < ks.end {
            let count = (ks.end - k0).min(BLOCK_OUT);
            let rows = count + stride - BLOCK_OUT;
            // Input index of row 0, column 0 (before wrapping around the period).
            let first = (k0 * d) as i64 - half as i64;
            let last = first + (rows * d) as i64;
            for r in 0..d {
                let row_re = &mut self.phase_re[r * stride..r * stride + rows];
                let row_im = &mut self.phase_im[r * stride..r * stride + rows];
                if first >= 0 && last <= n as i64 {
                    sample.strided(first as usize + r, d, row_re, row_im);
                } else {
                    for (i, (re, im)) in row_re.iter_mut().zip(row_im.iter_mut()).enumerate() {
                        let p = (first + (i * d + r) as i64).rem_euclid(n as i64) as usize;
                        let z = sample.at(p);
                        *re = z.re;
                        *im = z.im;
                    }
                }
            }
            self.run_kernel(count);
            out.extend(
                self.out_re[..count]
                    .iter()
                    .zip(&self.out_im[..count])
                    .map(|(&re, &im)| Complex64::new(re, im)),
            );
            k0 += count;
        }
    }

    fn run_kernel(&mut self, count: usize) {
        #[cfg(target_arch = "x86_64")]
        if self.use_fma {
            // SAFETY: `use_fma` is set only when the CPU reports AVX2 and FMA at run time.
            unsafe {
                kernel_fma(
                    &self.reversed,
                    &self.tap_offset,
                    &self.phase_re,
                    &self.phase_im,
                    &mut self.out_re[..count],
                    &mut self.out_im[..count],
                );
            }
            return;
        }
        kernel::<false>(
            &self.reversed,
            &self.tap_offset,
            &self.phase_re,
            &self.phase_im,
            &mut self.out_re[..count],
            &mut self.out_im[..count],
        );
    }
}

fn fma_available() -> bool {
    #[cfg(target_arch = "x86_64")]
    {
        std::arch::is_x86_feature_detected!("avx2") && std::arch::is_x86_feature_detected!("fma")
    }
    #[cfg(not(target_arch = "x86_64"))]
    {
        false
    }
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma")]
unsafe fn kernel_fma(
    taps: &[f64],
    offsets: &[usize],
    re: &[f64],
    im: &[f64],
    out_re: &mut [f64],
    out_im: &mut [f64],
) {
    kernel::<true>(taps, offsets, re, im, out_re, out_im);
}

/// `out[m] = sum_j taps[j] * phase[offsets[j] + m]` for real and imaginary parts, 8 outputs at a
/// time in registers.
#[inline(always)]
fn kernel<const FMA: bool>(
    taps: &[f64],
    offsets: &[usize],
    re: &[f64],
    im: &[f64],
    out_re: &mut [f64],
    out_im: &mut [f64],
) {
    let count = out_re.len();
    let mut m = 0;
    while m + LANES <= count {
        let mut acc_re = [0.0f64; LANES];
        let mut acc_im = [0.0f64; LANES];
        for (&c, &off) in taps.iter().zip(offsets) {
            let xr: &[f64; LANES] = re[off + m..off + m + LANES].try_into().unwrap();
            let xi: &[f64; LANES] = im[off + m..off + m + LANES].try_into().unwrap();
            for t in 0..LANES {
                if FMA {
                    acc_re[t] = c.mul_add(xr[t], acc_re[t]);
                    acc_im[t] = c.mul_add(xi[t], acc_im[t]);
                } else {
                    acc_re[t] += c * xr[t];
                    acc_im[t] += c * xi[t];
                }
            }
        }
        out_re[m..m + LANES].copy_from_slice(&acc_re);
        out_im[m..m + LANES].copy_from_slice(&acc_im);
        m += LANES;
    }
    for m in m..count {
        let (mut ar, mut ai) = (0.0f64, 0.0f64);
        for (&c, &off) in taps.iter().zip(offsets) {
            if FMA {
                ar = c.mul_add(re[off + m], ar);
                ai = c.mul_add(im[off + m], ai);
            } else {
                ar += c * re[off + m];
                ai += c * im[off + m];
            }
        }
        out_re[m] = ar;
        out_im[m] = ai;
    }
}

/// The lab decimator ([`Decimator`], delay-compensated) applied to a periodic capture: the
/// capture is extended circularly by whole output samples on both sides, so the filter sees what a
/// continuously repeated frame (or a zero-padded pulse) would give, with no edge transient.
pub struct PeriodicDecimator {
    decimator: Decimator,
    /// Extension on each side, input samples (a multiple of the factor).
    guard: usize,
    /// The extended record, kept between captures (no fresh allocation per capture).
    extended: Vec<Complex64>,
}

impl PeriodicDecimator {
    /// Decimation of a capture at `capture_rate_hz` by `factor`, flat over +-`band_edge_hz`.
    ///
    /// # Errors
    ///
    /// [`DspError::Param`] when the rate is not positive, the factor is below 2, the band edge is not
    /// below the output Nyquist frequency, or the filter cannot be designed for them.
    pub fn new(capture_rate_hz: f64, factor: usize, band_edge_hz: f64) -> Result<Self, DspError> {
        let config = DecimatorConfig::for_band(capture_rate_hz, factor, band_edge_hz)?;
        let taps = Self::design(&config)?;
        Self::from_design(&config, taps)
    }

    /// The anti-alias filter [`new`](Self::new) designs for `config` (the costly part: a cache
    /// may keep the taps).
    pub(crate) fn design(config: &DecimatorConfig) -> Result<Vec<f64>, DspError> {
        if config.factor < 1 {
            return Err(DspError::Param(
                "decimation factor = 0: must be at least 1".into(),
            ));
        }
        design_lowpass(&config.spec, config.factor)
    }

    /// [`new`](Self::new) with the taps [`design`](Self::design) gave for `config`.
    pub(crate) fn from_design(config: &DecimatorConfig, taps: Vec<f64>) -> Result<Self, DspError> {
        let decimator = Decimator::with_taps(config.factor, taps, config.alignment)?;
        let half = decimator.taps().len() / 2 + 1;
        Ok(Self {
            guard: half.div_ceil(config.factor) * config.factor,
            decimator,
            extended: Vec::new(),
        })
    }

    /// The anti-alias filter's taps (linear phase, delay compensated: its response is real).
    pub fn taps(&self) -> &[f64] {
        self.decimator.taps()
    }

    /// The decimation factor.
    pub fn factor(&self) -> usize {
        self.decimator.factor()
    }

    /// The filter's (real, delay-compensated) response at `nu` cycles per *output* sample: the
    /// extra spectral weight of a decimated capture's point spread
    /// (`crate::dsp::TabulatedPsf::correlation`).
    pub fn response_at_output(&self, nu: f64) -> f64 {
        magnitude_response(self.decimator.taps(), nu / self.decimator.factor() as f64)
    }

    /// [`response_at_output`](Self::response_at_output) at every bin of an `n`-point DFT of the
    /// output (bin `k` at `k / n`, the upper half at the negative frequencies): the same bits,
    /// the upper half mirrored (the taps are real) and the rest taken side by side.
    pub(crate) fn response_at_output_bins(&self, n: usize) -> Vec<f64> {
        let factor = self.decimator.factor() as f64;
        let half: Vec<f64> = (0..=n / 2).map(|k| k as f64 / n as f64 / factor).collect();
        let gains = magnitude_responses(self.decimator.taps(), &half);
        (0..n)
            .map(|k| if k <= n / 2 { gains[k] } else { gains[n - k] })
            .collect()
    }

    pub fn decimate(&mut self, x: &[Complex64]) -> Vec<Complex64> {
        self.decimate_map(x.len(), |k| x[k])
    }

    /// [`decimate`](Self::decimate) of the `n` samples `sample(0..n)`, read straight into the
    /// extended record (e.g. from the scope's words, without a record in volts first).
    pub(crate) fn decimate_map(
        &mut self,
        n: usize,
        sample: impl Fn(usize) -> Complex64,
    ) -> Vec<Complex64> {
        self.decimate_map_rotated(n, sample, 0)
    }

    /// [`decimate_map`](Self::decimate_map) with its output rotated by `rotate` samples: output
    /// `k` lands at `(k + rotate) % len` (what aligning a record to its marker does next), with
    /// no extended record: each phase block is read from `sample` directly (around the period
    /// where the filter reaches past an end). The same bits as decimating the extended record.
    pub(crate) fn decimate_map_rotated(
        &mut self,
        n: usize,
        sample: impl Samples,
        rotate: usize,
    ) -> Vec<Complex64> {
        if self.decimator.alignment() == Alignment::Compensated && self.guard <= n {
            // Output k goes to (k + rotate) % len: the outputs from len - rotate on come first.
            let len = n / self.decimator.factor();
            let mut out = Vec::with_capacity(len);
            let split = (len - rotate % len.max(1)) % len.max(1);
            self.decimator
                .periodic_into(n, &sample, split..len, &mut out);
            self.decimator.periodic_into(n, &sample, 0..split, &mut out);
            return out;
        }
        let y = self.decimate_extended(n, sample);
        if y.is_empty() {
            return y;
        }
        let s = rotate % y.len();
        let mut out = Vec::with_capacity(y.len());
        out.extend_from_slice(&y[y.len() - s..]);
        out.extend_from_slice(&y[..y.len() - s]);
        out
    }

    /// The extended record (`guard` samples of the period's end before it, of its start after
    /// it) decimated whole: the definition [`decimate_map_rotated`](Self::decimate_map_rotated)
    /// computes without the record, and what it does for a capture shorter than the guard.
    fn decimate_extended(&mut self, n: usize, sample: impl Samples) -> Vec<Complex64> {
        let sample = |k: usize| sample.at(k);
        let g = self.guard.min(n);
        let mut extended = std::mem::take(&mut self.extended);
        extended.clear();
        extended.extend((n - g..n).map(&sample));
        extended.extend((0..n).map(&sample));
        extended.extend((0..g).map(&sample));
        self.decimator.reset();
        let y = self.decimator.decimate(&extended);
        self.extended = extended;
        let factor = self.decimator.factor();
        let skip = g / factor;
        y[skip..skip + n / factor].to_vec()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;
    use std::f64::consts::PI;

    fn tone(f: f64, n: usize) -> Vec<Complex64> {
        (0..n)
            .map(|k| Complex64::from_polar(1.0, 2.0 * std::f64::consts::PI * f * k as f64))
            .collect()
    }

    /// Every bin at once gives the bits one bin at a time gives (mirrored half and the lanes'
    /// ragged end included).
    #[test]
    fn the_response_at_every_output_bin_is_the_response_at_each() {
        let d = PeriodicDecimator::new(80e9, 5, 0.5e9).unwrap();
        for n in [1, 2, 7, 64, 1001, 51_200] {
            let each: Vec<f64> = (0..n)
                .map(|k| {
                    let signed = if k <= n / 2 {
                        k as f64
                    } else {
                        k as f64 - n as f64
                    };
                    d.response_at_output(signed / n as f64)
                })
                .collect();
            assert_eq!(d.response_at_output_bins(n), each, "{n} bins");
        }
    }

    /// Designs once per factor (the design search is the slow part at test opt-level).
    fn designed(factor: usize) -> Vec<f64> {
        use std::sync::{Mutex, OnceLock};
        type Designs = Vec<(usize, Vec<f64>)>;
        static CACHE: OnceLock<Mutex<Designs>> = OnceLock::new();
        let cache = CACHE.get_or_init(|| Mutex::new(Vec::new()));
        let mut cache = cache.lock().unwrap();
        if let Some((_, t)) = cache.iter().find(|(f, _)| *f == factor) {
            return t.clone();
        }
        let spec = DecimatorConfig::for_band(80e9, factor, 0.5e9).unwrap().spec;
        let taps = design_lowpass(&spec, factor).unwrap();
        cache.push((factor, taps.clone()));
        taps
    }

    fn noise(n: usize, seed: u64) -> Vec<Complex64> {
        let mut r = crate::rng::SplitMix64::new(seed);
        (0..n).map(|_| r.complex_gaussian(1.0)).collect()
    }

    #[test]
    fn default_design_meets_its_spec() {
        let cfg = DecimatorConfig::default();
        let d = Decimator::new(&cfg).unwrap();
        assert_eq!(d.factor(), 5);
        assert_eq!(d.taps().len(), 41);
        assert_eq!(d.group_delay_input_samples(), 20.0);
        assert_eq!(d.group_delay_output_samples(), 4.0);
        // At least the 7 dB of an ideal 16 GSa/s filter.
        assert!(
            d.noise_gain_db() > 10.0 * 5f64.log10(),
            "{}",
            d.noise_gain_db()
        );
        let m = measure_response(d.taps(), &cfg.spec);
        assert!(m.stop_atten_db >= 60.0, "{m:?}");
        assert!(m.pass_ripple_db <= 0.1, "{m:?}");
        // Linear phase: symmetric taps.
        let t = d.taps();
        for k in 0..t.len() {
            assert!((t[k] - t[t.len() - 1 - k]).abs() < 1e-15);
        }
    }

    #[test]
    fn stop_band_measured_on_tones() {
        // Tones from the output Nyquist (8 GHz of 80) to the input Nyquist, both signs: every one
        // comes out at least 60 dB down; tones in the +-0.5 GHz band come out within 0.1 dB.
        let mut d = Decimator::new(&DecimatorConfig::default()).unwrap();
        let n = 20_000;
        let level = |y: &[Complex64]| {
            let mid = &y[20..y.len() - 20]; // skip the edge transients
            (mid.iter().map(|z| z.norm_sqr()).sum::<f64>() / mid.len() as f64).sqrt()
        };
        for i in 0..=40 {
            let f = 0.1 + 0.4 * i as f64 / 40.0;
            for f in [f, -f] {
                let y = d.decimate(&tone(f, n));
                let db = 20.0 * level(&y).log10();
                assert!(db <= -60.0, "tone at {f} cycles/sample: {db} dB");
            }
        }
        for f in [0.0, 0.002, -0.004, 0.00625, -0.00625] {
            let y = d.decimate(&tone(f, n));
            let db = 20.0 * level(&y).log10();
            assert!(db.abs() <= 0.1, "pass-band tone at {f}: {db} dB");
        }
    }

    #[test]
    fn compensated_output_is_aligned_with_the_input() {
        let mut d = Decimator::new(&DecimatorConfig::default()).unwrap();
        let x = tone(0.003, 10_001);
        let y = d.decimate(&x);
        assert_eq!(y.len(), 2001);
        // Zero phase (the delay is removed exactly) and gain within the 0.1 dB pass-band ripple.
        for m in 10..y.len() - 10 {
            let ratio = y[m] / x[5 * m];
            assert!(
                ratio.arg().abs() < 1e-9,
                "output {m}: phase {}",
                ratio.arg()
            );
            assert!(
                (20.0 * ratio.norm().log10()).abs() < 0.1,
                "output {m}: {ratio}"
            );
        }
        // The causal filter lags by the group delay instead.
        let cfg = DecimatorConfig {
            alignment: Alignment::Causal,
            ..Default::default()
        };
        let mut c = Decimator::new(&cfg).unwrap();
        let yc = c.decimate(&x);
        assert_eq!(yc.len(), 2001);
        let g = d.group_delay_output_samples() as usize;
        for m in g..yc.len() {
            assert_eq!(yc[m], y[m - g]);
        }
    }

    #[test]
    fn output_length_is_ceil_n_over_d() {
        let mut d = Decimator::new(&DecimatorConfig::default()).unwrap();
        for n in [0, 1, 4, 5, 6, 19, 20, 21, 40, 41, 42, 1000, 1001] {
            assert_eq!(d.decimate(&noise(n, 1)).len(), n.div_ceil(5), "n = {n}");
        }
    }

    #[test]
    fn other_factors_and_bad_parameters() {
        for factor in [2, 3, 4, 8, 10] {
            let cfg = DecimatorConfig::for_band(80e9, factor, 0.5e9).unwrap();
            let mut d = Decimator::new(&cfg).unwrap();
            assert_eq!((d.taps().len() - 1) % (2 * factor), 0);
            let m = measure_response(d.taps(), &cfg.spec);
            assert!(
                m.stop_atten_db >= 60.0 && m.pass_ripple_db <= 0.1,
                "{factor}: {m:?}"
            );
            let x = tone(0.001, 3000);
            let y = d.decimate(&x);
            assert!((y[100] - x[100 * factor]).norm() < 0.012);
        }
        assert!(DecimatorConfig::for_band(80e9, 1, 0.5e9).is_err());
        assert!(DecimatorConfig::for_band(80e9, 5, 9e9).is_err());
        assert!(DecimatorConfig::for_band(f64::NAN, 5, 0.5e9).is_err());
        let bad = LowPassSpec {
            pass_edge: 0.2,
            stop_edge: 0.1,
            stop_atten_db: 60.0,
            pass_ripple_db: 0.1,
        };
        assert!(design_lowpass(&bad, 5).is_err());
        assert!(Decimator::with_taps(5, vec![1.0; 40], Alignment::Compensated).is_err());
        assert!(Decimator::with_taps(0, vec![1.0], Alignment::Causal).is_err());
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(48))]

        #[test]
        fn chunked_equals_one_shot(
            n in 0usize..3000,
            cuts in proptest::collection::vec(0usize..400, 0..12),
            factor in 2usize..7,
            causal in any::<bool>(),
            seed in any::<u64>(),
        ) {
            let alignment = if causal { Alignment::Causal } else { Alignment::Compensated };
            let mut d = Decimator::with_taps(factor, designed(factor), alignment).unwrap();
            let x = noise(n, seed);
            let whole = d.decimate(&x);
            let mut pieces = Vec::new();
            let mut at = 0;
            for c in cuts {
                let end = (at + c).min(n);
                d.process(&x[at..end], &mut pieces);
                at = end;
            }
            d.process(&x[at..], &mut pieces);
            d.finish(&mut pieces);
            prop_assert_eq!(whole.len(), n.div_ceil(factor));
            prop_assert_eq!(pieces, whole);
        }

        #[test]
        fn periodic_without_the_extended_record_gives_the_same_bits(
            n in 0usize..4000,
            factor in 2usize..7,
            rotate in 0usize..5000,
            seed in any::<u64>(),
        ) {
            let config = DecimatorConfig::for_band(80e9, factor, 0.5e9).unwrap();
            let mut d = PeriodicDecimator::from_design(&config, designed(factor)).unwrap();
            let x = noise(n, seed);
            let y = d.decimate_extended(n, |k| x[k]);
            let got = d.decimate_map_rotated(n, |k| x[k], rotate);
            prop_assert_eq!(got.len(), y.len());
            for (k, v) in y.iter().enumerate() {
                let at = (k + rotate) % y.len();
                prop_assert_eq!(got[at].re.to_bits(), v.re.to_bits(), "output {} of {}", k, n);
                prop_assert_eq!(got[at].im.to_bits(), v.im.to_bits(), "output {} of {}", k, n);
            }
        }

        #[test]
        fn words_read_by_stride_give_the_bits_of_words_read_one_by_one(
            n in 0usize..4000,
            factor in 2usize..7,
            rotate in 0usize..5000,
            seed in any::<u64>(),
            gain in 1e-6f64..1e-2,
            offset in -1.0f64..1.0,
        ) {
            let config = DecimatorConfig::for_band(80e9, factor, 0.5e9).unwrap();
            let mut d = PeriodicDecimator::from_design(&config, designed(factor)).unwrap();
            let x = noise(n, seed);
            let i: Vec<i16> = x.iter().map(|z| (z.re * 32767.0) as i16).collect();
            let q: Vec<i16> = x.iter().map(|z| (z.im * 32767.0) as i16).collect();
            let words = ScaledWords { i: &i, q: &q, gain: [gain, 2.0 * gain], offset: [offset, -offset] };
            let one_by_one = |k: usize| {
                Complex64::new(
                    gain * f64::from(i[k]) - offset,
                    2.0 * gain * f64::from(q[k]) + offset,
                )
            };
            let want = d.decimate_map_rotated(n, one_by_one, rotate);
            let got = d.decimate_map_rotated(n, words, rotate);
            prop_assert_eq!(got.len(), want.len());
            for (k, (g, w)) in got.iter().zip(&want).enumerate() {
                prop_assert_eq!(g.re.to_bits(), w.re.to_bits(), "output {} of {}", k, n);
                prop_assert_eq!(g.im.to_bits(), w.im.to_bits(), "output {} of {}", k, n);
            }
        }

        #[test]
        fn matches_direct_convolution(n in 1usize..600, seed in any::<u64>()) {
            let mut d = Decimator::with_taps(5, designed(5), Alignment::Causal).unwrap();
            let x = noise(n, seed);
            let y = d.decimate(&x);
            let h = d.taps().to_vec();
            for (m, got) in y.iter().enumerate() {
                let mut want = Complex64::new(0.0, 0.0);
                for (k, &hk) in h.iter().enumerate() {
                    if let Some(i) = (5 * m).checked_sub(k) {
                        want += x[i] * hk;
                    }
                }
                prop_assert!((got - want).norm() < 1e-12);
            }
        }
    }

    #[test]
    fn periodic_decimation_keeps_a_band_limited_tone_everywhere() {
        let n = 5000;
        let x: Vec<Complex64> = (0..n)
            .map(|i| Complex64::from_polar(1.0, 2.0 * PI * 10.0 * i as f64 / n as f64))
            .collect();
        let mut d = PeriodicDecimator::new(80e9, 5, 0.5e9).unwrap();
        let y = d.decimate(&x);
        assert_eq!(y.len(), 1000);
        for (m, v) in y.iter().enumerate() {
            assert!(
                (v - x[5 * m]).norm() < 0.02,
                "sample {m}: {v} vs {}",
                x[5 * m]
            );
        }
    }
}
