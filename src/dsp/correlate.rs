//! FFT cross-correlation with the transmit spectrum computed once.
//!
//! # Definition and lag order
//! For a received capture `rx` (length `Nr`) and the transmitted waveform `tx` (length `Nt`):
//!
//! ```text
//! r[l] = sum_n rx[n] conj(tx[n - l])      (terms with n - l outside 0..Nt are zero)
//! ```
//!
//! An echo delayed by `d` samples peaks at `l = d`; lag `l` is range `l * C0 / (2 fs)`. This is a
//! *linear* correlation: the full result has lags `-(Nt - 1) ..= Nr - 1`. A [`CrossCorrelator`]
//! returns the lags of the range you choose at construction, in ascending order: output index `i`
//! holds lag `first_lag + i`. Radar processing usually wants only `0 ..= max_lag`
//! ([`CrossCorrelator::new`] with `0..=max_lag`), which also lets the FFT be shorter.
//!
//! # How
//! Two strategies give the same numbers (up to rounding); [`Strategy::Auto`] picks the cheaper:
//!
//! * **One FFT** ([`Strategy::SingleFft`]): `r` is the inverse FFT of `RX(f) conj(TX(f))` of length
//!   `K`, the smallest 2-3-5-7 smooth length (fast for rustfft) with
//!   `K >= max(Nr - first_lag, last_lag + Nt, Nr, Nt)`: then no lag in the chosen range is touched by
//!   the circular wrap-around. For all lags of two 160 000-sample signals, `K` = 320 000.
//! * **Blocks** ([`Strategy::Blocks`]), for a lag window `W = last - first + 1` much shorter than the
//!   capture (a radar's range window): the capture is cut into blocks of `B = Kb - W + 1` samples;
//!   block `b` is correlated against the stretch of `tx` it can meet at those lags, with FFTs of the
//!   short length `Kb`, and the block spectra are summed before one inverse FFT. For 160 000
//!   samples and lags 0..2048 this is 12 FFTs of 16 384 points (cache-resident) plus one inverse,
//!   against 2 FFTs of 163 840 points.
//!
//! The transmit spectra (`conj(TX) / K`, per block for the block strategy) are computed once at
//! construction; each call only transforms the capture, multiplies and transforms back, in buffers
//! owned by the correlator (no allocation per call).

use std::ops::RangeInclusive;
use std::sync::Arc;

use num_complex::Complex64;
use rustfft::Fft;

use super::DspError;

const ZERO: Complex64 = Complex64 { re: 0.0, im: 0.0 };

/// Smallest `n >= min` of the form `2^a 3^b 5^c 7^d` (rustfft's fast sizes); `min = 0` gives 1.
pub fn fast_fft_len(min: usize) -> usize {
    let min = min.max(1);
    let mut best = min.next_power_of_two();
    let mut p7 = 1usize;
    while p7 < best {
        let mut p75 = p7;
        while p75 < best {
            let mut p753 = p75;
            while p753 < best {
                // Smallest power of two taking p753 to at least `min`.
                let mut n = p753;
                while n < min {
                    n *= 2;
                }
                best = best.min(n);
                p753 *= 3;
            }
            p75 *= 5;
        }
        p7 *= 7;
    }
    best
}

/// How a [`CrossCorrelator`] computes (see the module docs).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Strategy {
    /// The cheaper of the two by an operation count.
    #[default]
    Auto,
    /// One forward and one inverse FFT over the whole (zero-padded) capture.
    SingleFft,
    /// Block correlation with FFTs of (at least) `fft_len` points, rounded up to a fast length of
    /// at least twice the lag window.
    Blocks { fft_len: usize },
}

/// Cross-correlates captures against one transmitted waveform by FFT.
pub struct CrossCorrelator {
    tx_len: usize,
    rx_len: usize,
    first_lag: isize,
    last_lag: isize,
    fft_len: usize,
    /// Capture samples per block (`rx_len` or more for the single-FFT strategy).
    block_len: usize,
    forward: Arc<dyn Fft<f64>>,
    inverse: Arc<dyn Fft<f64>>,
    /// `conj(FFT(tx stretch of block b)) / K`, block after block.
    tx_spectra_conj: Vec<Complex64>,
    buf: Vec<Complex64>,
    acc: Vec<Complex64>,
    scratch: Vec<Complex64>,
}

impl std::fmt::Debug for CrossCorrelator {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("CrossCorrelator")
            .field("tx_len", &self.tx_len)
            .field("rx_len", &self.rx_len)
            .field("lags", &(self.first_lag..=self.last_lag))
            .field("fft_len", &self.fft_len)
            .field("blocks", &self.blocks())
            .finish_non_exhaustive()
    }
}

/// Rough cost of a plan: FFT work `n log2 n` per transform plus one multiply-add per bin and block.
fn plan_cost(blocks: usize, fft_len: usize) -> f64 {
    let k = fft_len as f64;
    (blocks + 1) as f64 * k * k.log2() + blocks as f64 * k
}

impl CrossCorrelator {
    /// Prepares correlation of captures of up to `rx_len` samples against `tx`, returning the lags
    /// `lags` (inclusive, within `-(tx.len() - 1) ..= rx_len - 1`), with [`Strategy::Auto`].
    ///
    /// # Errors
    ///
    /// [`DspError::Param`] when `tx` or `rx_len` is empty or above 2^30 samples, or `lags` is
    /// descending or outside the range above.
    pub fn new(
        tx: &[Complex64],
        rx_len: usize,
        lags: RangeInclusive<isize>,
    ) -> Result<Self, DspError> {
        Self::with_strategy(tx, rx_len, lags, Strategy::Auto)
    }

    /// All lags, `-(tx.len() - 1) ..= rx_len - 1`.
    ///
    /// # Errors
    ///
    /// [`DspError::Param`] when `tx` or `rx_len` is empty or above 2^30 samples.
    pub fn full(tx: &[Complex64], rx_len: usize) -> Result<Self, DspError> {
        let lo = -(tx.len() as isize - 1);
        Self::new(tx, rx_len, lo..=rx_len as isize - 1)
    }

    /// As [`CrossCorrelator::new`] with a chosen strategy.
    pub(crate) fn with_strategy(
        tx: &[Complex64],
        rx_len: usize,
        lags: RangeInclusive<isize>,
        strategy: Strategy,
    ) -> Result<Self, DspError> {
        if tx.is_empty() || rx_len == 0 {
            return Err(DspError::Param(format!(
                "correlation lengths: transmit {} and receive {} samples; both must be at least 1",
                tx.len(),
                rx_len
            )));
        }
        if tx.len() > 1 << 30 || rx_len > 1 << 30 {
            return Err(DspError::Param(
                "correlation lengths: at most 2^30 samples each".into(),
            ));
        }
        let (first, last) = (*lags.start(), *lags.end());
        let lo = -(tx.len() as isize - 1);
        let hi = rx_len as isize - 1;
        if first > last || first < lo || last > hi {
            return Err(DspError::Param(format!(
                "correlation lags {first}..={last}: must be ascending and within {lo}..={hi} \
                 (-(transmit length - 1) ..= receive length - 1)"
            )));
        }
        let window = (last - first + 1) as usize;
        // Single FFT: no alias may land on a chosen lag, and both signals must fit.
        let single_len = fast_fft_len(
            (rx_len as isize - first)
                .max(last + tx.len() as isize)
                .max(tx.len() as isize)
                .max(rx_len as isize) as usize,
        );
        let blocks_of = |k: usize| rx_len.div_ceil(k - window + 1);
        let (fft_len, block_len) = match strategy {
            Strategy::SingleFft => (single_len, usize::MAX),
            Strategy::Blocks { fft_len } => {
                let k = fast_fft_len(fft_len.max(2 * window));
                (k, k - window + 1)
            }
            Strategy::Auto => {
                let mut best = (plan_cost(1, single_len), single_len, usize::MAX);
                let mut k = fast_fft_len(2 * window);
                while k < single_len {
                    let cost = plan_cost(blocks_of(k), k);
                    if cost < best.0 {
                        best = (cost, k, k - window + 1);
                    }
                    k = fast_fft_len(k + k / 4 + 1);
                }
                (best.1, best.2)
            }
        };
        let forward = super::plans::forward(fft_len);
        let inverse = super::plans::inverse(fft_len);
        let scratch_len = forward
            .get_inplace_scratch_len()
            .max(inverse.get_inplace_scratch_len());
        let mut scratch = vec![ZERO; scratch_len];
        let scale = 1.0 / fft_len as f64;
        let tx_spectra_conj = if block_len == usize::MAX {
            let mut spectrum = vec![ZERO; fft_len];
            spectrum[..tx.len()].copy_from_slice(tx);
            forward.process_with_scratch(&mut spectrum, &mut scratch);
            spectrum.iter().map(|z| z.conj() * scale).collect()
        } else {
            // Block b meets tx[b B - last + j] for j in 0..K (zero outside tx).
            let blocks = rx_len.div_ceil(block_len);
            let mut spectra = vec![ZERO; blocks * fft_len];
            for (b, spectrum) in spectra.chunks_exact_mut(fft_len).enumerate() {
                let origin = (b * block_len) as isize - last;
                for (j, v) in spectrum.iter_mut().enumerate() {
                    let i = origin + j as isize;
                    if i >= 0 && (i as usize) < tx.len() {
                        *v = tx[i as usize];
                    }
                }
                forward.process_with_scratch(spectrum, &mut scratch);
                for v in spectrum.iter_mut() {
                    *v = v.conj() * scale;
                }
            }
            spectra
        };
        Ok(Self {
            tx_len: tx.len(),
            rx_len,
            first_lag: first,
            last_lag: last,
            fft_len,
            block_len,
            forward,
            inverse,
            tx_spectra_conj,
            buf: vec![ZERO; fft_len],
            acc: vec![ZERO; fft_len],
            scratch,
        })
    }

    /// The lags returned, ascending: output index `i` is lag `lags().start() + i`.
    pub fn lags(&self) -> RangeInclusive<isize> {
        self.first_lag..=self.last_lag
    }

    /// Number of lags returned.
    pub fn output_len(&self) -> usize {
        (self.last_lag - self.first_lag + 1) as usize
    }

    /// The FFT length used.
    pub fn fft_len(&self) -> usize {
        self.fft_len
    }

    /// Number of capture blocks (1 for the single-FFT strategy).
    pub fn blocks(&self) -> usize {
        self.tx_spectra_conj.len() / self.fft_len
    }

    /// Longest capture accepted.
    pub fn rx_len(&self) -> usize {
        self.rx_len
    }

    /// Correlates `rx` (at most `rx_len` samples; shorter is zero-padded) into `out`
    /// (`output_len()` values, ascending lags).
    ///
    /// # Errors
    ///
    /// [`DspError::Param`] when `rx` is longer than `rx_len` or `out` is not `output_len()` long.
    pub fn correlate_into(
        &mut self,
        rx: &[Complex64],
        out: &mut [Complex64],
    ) -> Result<(), DspError> {
        if rx.len() > self.rx_len {
            return Err(DspError::Param(format!(
                "capture of {} samples: this correlator was built for at most {}",
                rx.len(),
                self.rx_len
            )));
        }
        if out.len() != self.output_len() {
            return Err(DspError::Param(format!(
                "correlation output of {} values: must be exactly the {} lags {}..={}",
                out.len(),
                self.output_len(),
                self.first_lag,
                self.last_lag
            )));
        }
        let k = self.fft_len;
        if self.block_len == usize::MAX {
            self.buf[..rx.len()].copy_from_slice(rx);
            self.buf[rx.len()..].fill(ZERO);
            self.forward
                .process_with_scratch(&mut self.buf, &mut self.scratch);
            for (x, t) in self.buf.iter_mut().zip(&self.tx_spectra_conj) {
                *x *= t;
            }
            self.inverse
                .process_with_scratch(&mut self.buf, &mut self.scratch);
            // Lags first..=last sit at circular indices first mod K onwards, at most one wrap.
            copy_circular(
                &self.buf,
                self.first_lag.rem_euclid(k as isize) as usize,
                out,
            );
            return Ok(());
        }
        self.acc.fill(ZERO);
        for (block, spectrum) in rx
            .chunks(self.block_len)
            .zip(self.tx_spectra_conj.chunks_exact(k))
        {
            self.buf[..block.len()].copy_from_slice(block);
            self.buf[block.len()..].fill(ZERO);
            self.forward
                .process_with_scratch(&mut self.buf, &mut self.scratch);
            for ((a, x), t) in self.acc.iter_mut().zip(&self.buf).zip(spectrum) {
                *a += x * t;
            }
        }
        self.inverse
            .process_with_scratch(&mut self.acc, &mut self.scratch);
        // Lag first + i is the block correlation at i - (W - 1), i.e. circular index i + B.
        copy_circular(&self.acc, self.block_len % k, out);
        Ok(())
    }

    /// As [`CrossCorrelator::correlate_into`], allocating the output.
    ///
    /// # Errors
    ///
    /// [`DspError::Param`] when `rx` is longer than `rx_len`.
    pub fn correlate(&mut self, rx: &[Complex64]) -> Result<Vec<Complex64>, DspError> {
        let mut out = vec![ZERO; self.output_len()];
        self.correlate_into(rx, &mut out)?;
        Ok(out)
    }
}

/// `out[i] = buf[(start + i) mod buf.len()]`, with `out.len() <= buf.len()`.
fn copy_circular(buf: &[Complex64], start: usize, out: &mut [Complex64]) {
    let head = (buf.len() - start).min(out.len());
    out[..head].copy_from_slice(&buf[start..start + head]);
    let rest = out.len() - head;
    out[head..].copy_from_slice(&buf[..rest]);
}

/// Direct `O(Nr * lags)` correlation with the same definition and lag order; the reference the FFT
/// version is tested against. Lags outside the support give 0.
#[cfg(test)]
pub(crate) fn correlate_direct(
    rx: &[Complex64],
    tx: &[Complex64],
    lags: RangeInclusive<isize>,
) -> Vec<Complex64> {
    lags.map(|l| {
        let mut acc = ZERO;
        for (n, &x) in rx.iter().enumerate() {
            let m = n as isize - l;
            if m >= 0 && (m as usize) < tx.len() {
                acc += x * tx[m as usize].conj();
            }
        }
        acc
    })
    .collect()
}

#[cfg(test)]
mod tests {
    use super::Strategy; // over proptest's trait of the same name
    use super::*;
    use crate::rng::SplitMix64;
    use proptest::prelude::*;

    fn noise(n: usize, seed: u64) -> Vec<Complex64> {
        let mut r = SplitMix64::new(seed);
        (0..n).map(|_| r.complex_gaussian(1.0)).collect()
    }

    #[test]
    fn fast_lengths() {
        assert_eq!(fast_fft_len(0), 1);
        assert_eq!(fast_fft_len(1), 1);
        assert_eq!(fast_fft_len(11), 12);
        assert_eq!(fast_fft_len(13), 14);
        assert_eq!(fast_fft_len(319_999), 320_000);
        let smooth = |k: usize| {
            let mut m = k;
            for p in [2, 3, 5, 7] {
                while m % p == 0 {
                    m /= p;
                }
            }
            m == 1
        };
        for n in 1..3000 {
            let k = fast_fft_len(n);
            assert!(k >= n && smooth(k), "{n} -> {k}");
            assert!((n..k).all(|j| !smooth(j)), "{n} -> {k} is not the smallest");
        }
    }

    #[test]
    fn echo_peaks_at_its_delay() {
        let tx = noise(1000, 1);
        let mut rx = vec![ZERO; 1500];
        rx[123..1123].copy_from_slice(&tx);
        let mut c = CrossCorrelator::new(&tx, rx.len(), 0..=400).unwrap();
        let r = c.correlate(&rx).unwrap();
        let peak = (0..r.len())
            .max_by(|&a, &b| r[a].norm().total_cmp(&r[b].norm()))
            .unwrap();
        assert_eq!(peak, 123);
    }

    #[test]
    fn auto_strategy_uses_blocks_for_a_range_window() {
        let tx = noise(160_000, 7);
        let c = CrossCorrelator::new(&tx, 160_000, 0..=2047).unwrap();
        assert!(c.blocks() > 1, "{c:?}");
        assert!(c.fft_len() < 65_536, "{c:?}");
        let c = CrossCorrelator::full(&tx, 160_000).unwrap();
        assert_eq!((c.blocks(), c.fft_len()), (1, 320_000));
    }

    #[test]
    fn single_lag_windows_plan_and_agree() {
        // A one-lag window once made the Auto search loop forever (k + k/4 == k for k < 4).
        let tx = noise(300, 10);
        let rx = noise(500, 11);
        for lag in [-299, 0, 5, 499] {
            let mut c = CrossCorrelator::new(&tx, rx.len(), lag..=lag).unwrap();
            let got = c.correlate(&rx).unwrap();
            let want = correlate_direct(&rx, &tx, lag..=lag);
            assert!((got[0] - want[0]).norm() < 1e-9, "lag {lag}");
        }
    }

    #[test]
    fn strategies_agree_on_a_long_capture() {
        let tx = noise(20_000, 8);
        let mut rx = noise(20_000, 9);
        for (r, t) in rx[700..].iter_mut().zip(&tx) {
            *r += t * 3.0;
        }
        let lags = -50..=999;
        let mut a =
            CrossCorrelator::with_strategy(&tx, rx.len(), lags.clone(), Strategy::SingleFft)
                .unwrap();
        let mut b = CrossCorrelator::with_strategy(
            &tx,
            rx.len(),
            lags.clone(),
            Strategy::Blocks { fft_len: 4096 },
        )
        .unwrap();
        assert!(b.blocks() > 1);
        let (ra, rb) = (a.correlate(&rx).unwrap(), b.correlate(&rx).unwrap());
        let direct = correlate_direct(&rx, &tx, lags);
        for ((x, y), d) in ra.iter().zip(&rb).zip(&direct) {
            assert!((x - d).norm() < 1e-8 && (y - d).norm() < 1e-8);
        }
        // The echo (gain 3, 19 300 overlapping samples of unit power) at lag 700 = index 750.
        assert!(
            (ra[750].norm() - 57_900.0).abs() < 1_500.0,
            "{}",
            ra[750].norm()
        );
    }

    #[test]
    fn parseval() {
        // Zero lag of a signal with itself is its energy; and the total correlation energy equals
        // (1/K) sum |RX|^2 |TX|^2 over an independent DFT of length K = Nr + Nt - 1.
        let tx = noise(37, 2);
        let rx = noise(50, 3);
        let mut auto = CrossCorrelator::full(&tx, tx.len()).unwrap();
        let r = auto.correlate(&tx).unwrap();
        let energy: f64 = tx.iter().map(|z| z.norm_sqr()).sum();
        assert!((r[tx.len() - 1] - energy).norm() < 1e-9 * energy);
        let mut c = CrossCorrelator::full(&tx, rx.len()).unwrap();
        let r = c.correlate(&rx).unwrap();
        let lhs: f64 = r.iter().map(|z| z.norm_sqr()).sum();
        let k = rx.len() + tx.len() - 1;
        let dft = |x: &[Complex64], f: usize| -> Complex64 {
            x.iter()
                .enumerate()
                .map(|(n, &v)| {
                    v * Complex64::from_polar(
                        1.0,
                        -2.0 * std::f64::consts::PI * (f * n % k) as f64 / k as f64,
                    )
                })
                .sum()
        };
        let rhs: f64 = (0..k)
            .map(|f| dft(&rx, f).norm_sqr() * dft(&tx, f).norm_sqr())
            .sum::<f64>()
            / k as f64;
        assert!((lhs - rhs).abs() < 1e-9 * rhs, "{lhs} vs {rhs}");
    }

    #[test]
    fn bad_parameters_are_errors() {
        let tx = noise(10, 4);
        assert!(CrossCorrelator::new(&[], 10, 0..=1).is_err());
        assert!(CrossCorrelator::new(&tx, 0, 0..=0).is_err());
        assert!(CrossCorrelator::new(&tx, 20, 0..=20).is_err());
        assert!(CrossCorrelator::new(&tx, 20, -10..=0).is_err());
        #[allow(clippy::reversed_empty_ranges)]
        let backwards = 5..=1;
        assert!(CrossCorrelator::new(&tx, 20, backwards).is_err());
        let mut c = CrossCorrelator::new(&tx, 20, 0..=5).unwrap();
        assert!(c.correlate(&noise(21, 5)).is_err());
        assert!(c.correlate_into(&noise(20, 5), &mut [ZERO; 5]).is_err());
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(192))]

        #[test]
        fn fft_correlation_equals_direct(
            nt in 1usize..80,
            nr in 1usize..120,
            a in 0.0f64..1.0,
            b in 0.0f64..1.0,
            short in 0usize..5,
            strategy in 0usize..3,
            block_fft in 1usize..64,
            seed in any::<u64>(),
        ) {
            let tx = noise(nt, seed);
            let rx = noise(nr.saturating_sub(short).max(1), seed ^ 1);
            let lo = -(nt as isize - 1);
            let hi = nr as isize - 1;
            let span = (hi - lo) as f64;
            let (x, y) = (lo + (a * span) as isize, lo + (b * span) as isize);
            let lags = x.min(y)..=x.max(y);
            let strategy = match strategy {
                0 => Strategy::Auto,
                1 => Strategy::SingleFft,
                _ => Strategy::Blocks { fft_len: block_fft },
            };
            let mut c = CrossCorrelator::with_strategy(&tx, nr, lags.clone(), strategy).unwrap();
            let got = c.correlate(&rx).unwrap();
            let want = correlate_direct(&rx, &tx, lags);
            prop_assert_eq!(got.len(), want.len());
            let scale: f64 = (nt * nr) as f64;
            for (g, w) in got.iter().zip(&want) {
                prop_assert!((g - w).norm() < 1e-10 * scale.sqrt() * 10.0, "{} vs {}", g, w);
            }
            // Reuse: a second call gives the same answer.
            let again = c.correlate(&rx).unwrap();
            prop_assert_eq!(again, got);
        }
    }
}
