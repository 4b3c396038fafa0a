//! OFDM: generator and communication receiver (thesis 2.3, 3.2).
//!
//! # Layout
//! `N` subcarriers `k = 0..N` at baseband frequency `f_k = (k - N/2) df`, `df = B / N`, always stored
//! in this ascending-frequency order. The symbol matrix is symbol-major, `[symbol][k]`.
//!
//! One OFDM symbol is the inverse FFT of size `L = N * os` with subcarrier `k` in bin
//! `(k - N/2) mod L` and every other bin zero (ideal interpolation by `os`), scaled by `1/sqrt(N)` so
//! the mean power per sample is 1 for unit-power QPSK. The cyclic prefix is the last
//! `cp_fraction * L` samples, prepended. The sample rate is `fs = os * B`.
//!
//! A frame is `symbols_per_frame` symbols: first `preamble_symbols` known QPSK symbols (seeded with
//! `PREAMBLE_SEED`, identical in every frame) for channel estimation, then data symbols. Data bits
//! fill the data symbols subcarrier by subcarrier (ascending `k`), two bits per subcarrier, QPSK Gray:
//! `(b0, b1) -> ((1 - 2 b0) + j (1 - 2 b1)) / sqrt(2)`. The radar uses the whole symbol matrix,
//! preamble included: every transmitted symbol is known to it.
//!
//! # Receiver
//! Per symbol: drop the CP, FFT of size `L`, take bin `(k - N/2) mod L` for subcarrier `k` and undo
//! the generator's scale (so a noise-free, unit-gain channel returns exactly the sent symbols). The
//! channel per subcarrier is then estimated from the preamble (least squares, averaged over the
//! preamble symbols of each frame) or given, each data symbol divided by it, and QPSK decided by the
//! signs of its real and imaginary parts. The receiver expects frame-aligned captures.

use std::sync::Arc;

use num_complex::Complex64;
use rustfft::{Fft, FftPlanner};

use super::bits::{frame_bits, BitSource};
use super::ParamError;
use crate::dsp::ofdm_radar::{Numerology, NumerologyFault, Sizes};
use crate::rng::SplitMix64;

/// Seed of the known preamble symbols ("PREAMBLE" in ASCII).
pub(crate) const PREAMBLE_SEED: u64 = 0x5052_4541_4D42_4C45;

const ZERO: Complex64 = Complex64 { re: 0.0, im: 0.0 };

/// OFDM parameters. [`Default`] is the thesis' setting (Table 4.2, read as in thesis-notes.md).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct OfdmParams {
    /// Number of subcarriers `N`, even (default 128). Any even size works; powers of two are fastest.
    pub subcarriers: usize,
    /// Occupied bandwidth `B = N df` in Hz (default 1e9).
    pub bandwidth_hz: f64,
    /// Oversampling factor `os`: the sample rate is `os * B` (default 16, i.e. 16 GSa/s).
    pub oversampling: usize,
    /// Cyclic prefix as a fraction of the useful symbol, in [0, 1) (default 0.25).
    pub cp_fraction: f64,
    /// Symbols per frame, preamble included (default 100).
    pub symbols_per_frame: usize,
    /// Known preamble symbols at the start of each frame, used to estimate the channel (default 1).
    pub preamble_symbols: usize,
}

impl Default for OfdmParams {
    fn default() -> Self {
        Self {
            subcarriers: 128,
            bandwidth_hz: 1e9,
            oversampling: 16,
            cp_fraction: 0.25,
            symbols_per_frame: 100,
            preamble_symbols: 1,
        }
    }
}

/// QPSK Gray mapping of one bit pair.
pub(crate) fn qpsk_map(b0: u8, b1: u8) -> Complex64 {
    Complex64::new(1.0 - 2.0 * f64::from(b0 & 1), 1.0 - 2.0 * f64::from(b1 & 1))
        * std::f64::consts::FRAC_1_SQRT_2
}

/// QPSK Gray hard decision: the bit pair of the nearest constellation point.
pub(crate) fn qpsk_decide(z: Complex64) -> (u8, u8) {
    (u8::from(z.re < 0.0), u8::from(z.im < 0.0))
}

/// A symbol-major matrix of subcarrier values: `symbols` rows of `subcarriers` values in ascending
/// frequency order.
#[derive(Debug, Clone, PartialEq)]
pub struct SymbolMatrix {
    symbols: usize,
    subcarriers: usize,
    data: Vec<Complex64>,
}

impl SymbolMatrix {
    /// Wraps `data` (`symbols * subcarriers` values, symbol-major).
    pub(crate) fn from_vec(
        symbols: usize,
        subcarriers: usize,
        data: Vec<Complex64>,
    ) -> Result<Self, ParamError> {
        if data.len() != symbols * subcarriers {
            return Err(ParamError::out_of_range(
                "symbol matrix length",
                data.len(),
                &format!("must be symbols * subcarriers = {symbols} * {subcarriers}"),
            ));
        }
        Ok(Self {
            symbols,
            subcarriers,
            data,
        })
    }

    pub fn symbols(&self) -> usize {
        self.symbols
    }

    pub fn subcarriers(&self) -> usize {
        self.subcarriers
    }

    /// Symbol `s`, subcarriers in ascending frequency. Panics if `s >= symbols()`.
    pub fn row(&self, s: usize) -> &[Complex64] {
        &self.data[s * self.subcarriers..(s + 1) * self.subcarriers]
    }

    /// All rows in order.
    pub fn rows(&self) -> std::slice::ChunksExact<'_, Complex64> {
        self.data.chunks_exact(self.subcarriers)
    }

    /// The flat symbol-major data.
    pub fn as_slice(&self) -> &[Complex64] {
        &self.data
    }

    pub fn into_vec(self) -> Vec<Complex64> {
        self.data
    }
}

/// A generated OFDM transmission.
#[derive(Debug, Clone)]
pub struct OfdmSignal {
    /// Time samples at `os * B`, `frames * symbols_per_frame * symbol_len` of them.
    pub samples: Vec<Complex64>,
    /// Every transmitted symbol (preambles included), `[symbol][k]`.
    pub symbols: SymbolMatrix,
    /// The data bits (preambles excluded) in transmission order.
    pub bits: Vec<u8>,
    /// Number of frames.
    pub frames: usize,
    /// Payload length in bytes when the bits came from a payload.
    pub payload_len: Option<usize>,
}

/// A validated OFDM waveform with its FFT plans.
#[derive(Clone)]
pub struct Ofdm {
    params: OfdmParams,
    fft_len: usize,
    cp_len: usize,
    scale: f64,
    inverse: Arc<dyn Fft<f64>>,
    forward: Arc<dyn Fft<f64>>,
    preamble: Vec<Complex64>,
}

impl std::fmt::Debug for Ofdm {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Ofdm")
            .field("params", &self.params)
            .field("fft_len", &self.fft_len)
            .field("cp_len", &self.cp_len)
            .finish_non_exhaustive()
    }
}

impl Ofdm {
    /// Validates `params` and plans the FFTs.
    ///
    /// Errors name the parameter: subcarriers zero or odd, bandwidth not positive, oversampling zero,
    /// a CP fraction outside [0, 1) (the CP must be shorter than the symbol) or not a whole number of
    /// samples, a frame without data symbols.
    ///
    /// # Errors
    ///
    /// [`ParamError`] for each of the cases above, and when `subcarriers * oversampling` exceeds 2^28
    /// samples per symbol.
    pub fn new(params: OfdmParams) -> Result<Self, ParamError> {
        let n = params.subcarriers;
        let subcarriers = || {
            ParamError::out_of_range(
                "subcarriers",
                n,
                "must be even and at least 2 (subcarrier k sits at (k - N/2) df)",
            )
        };
        // The generator's own rule; the numerology the radar shares is checked once, in dsp.
        if n % 2 != 0 {
            return Err(subcarriers());
        }
        let (b, os, cp) = (params.bandwidth_hz, params.oversampling, params.cp_fraction);
        let numerology = Numerology {
            subcarriers: n,
            oversampling: os,
            cp_fraction: cp,
            bandwidth_hz: b,
        };
        let Sizes { fft_len, cp_len } = numerology.check().map_err(|fault| match fault {
            NumerologyFault::Subcarriers => subcarriers(),
            NumerologyFault::Bandwidth => ParamError::out_of_range(
                "bandwidth_hz",
                b,
                "must be a positive, finite bandwidth in Hz",
            ),
            NumerologyFault::Oversampling => ParamError::out_of_range(
                "oversampling",
                os,
                "must be at least 1 (the sample rate is oversampling * bandwidth)",
            ),
            NumerologyFault::SymbolTooLong => ParamError::out_of_range(
                "subcarriers * oversampling",
                format!("{n} * {os}"),
                "must be at most 2^28 samples per symbol",
            ),
            NumerologyFault::CpFraction => ParamError::out_of_range(
                "cp_fraction",
                cp,
                "must be at least 0 and below 1: the cyclic prefix must be shorter than the symbol",
            ),
            NumerologyFault::CpNotWhole { samples, fft_len } => ParamError::out_of_range(
                "cp_fraction",
                cp,
                &format!(
                    "must give a whole number of samples: cp_fraction * subcarriers * oversampling = \
                     {samples}; use a multiple of 1/{fft_len}"
                ),
            ),
        })?;
        if params.symbols_per_frame == 0 || params.preamble_symbols >= params.symbols_per_frame {
            return Err(ParamError::out_of_range(
                "symbols_per_frame",
                params.symbols_per_frame,
                &format!(
                    "must exceed preamble_symbols ({}) so a frame carries data",
                    params.preamble_symbols
                ),
            ));
        }
        let mut planner = FftPlanner::new();
        let inverse = planner.plan_fft_inverse(fft_len);
        let forward = planner.plan_fft_forward(fft_len);
        let mut rng = SplitMix64::new(PREAMBLE_SEED);
        let preamble = rng
            .bits(2 * n * params.preamble_symbols)
            .chunks_exact(2)
            .map(|p| qpsk_map(p[0], p[1]))
            .collect();
        Ok(Self {
            params,
            fft_len,
            cp_len,
            scale: 1.0 / (n as f64).sqrt(),
            inverse,
            forward,
            preamble,
        })
    }

    pub fn params(&self) -> &OfdmParams {
        &self.params
    }

    pub fn subcarriers(&self) -> usize {
        self.params.subcarriers
    }

    /// `os * B` in Sa/s.
    pub fn sample_rate_hz(&self) -> f64 {
        self.params.oversampling as f64 * self.params.bandwidth_hz
    }

    /// Subcarrier spacing `df = B / N` in Hz.
    pub(crate) fn subcarrier_spacing_hz(&self) -> f64 {
        self.params.bandwidth_hz / self.params.subcarriers as f64
    }

    /// Useful symbol length `L = N * os` in samples (the FFT size).
    pub fn fft_len(&self) -> usize {
        self.fft_len
    }

    /// Cyclic prefix length in samples.
    pub fn cp_len(&self) -> usize {
        self.cp_len
    }

    /// CP plus useful part, in samples.
    pub fn symbol_len(&self) -> usize {
        self.fft_len + self.cp_len
    }

    /// Samples in one frame.
    pub(crate) fn frame_len(&self) -> usize {
        self.params.symbols_per_frame * self.symbol_len()
    }

    /// Data bits in one frame (`2 N` per data symbol).
    pub(crate) fn bits_per_frame(&self) -> usize {
        2 * self.params.subcarriers * (self.params.symbols_per_frame - self.params.preamble_symbols)
    }

    /// FFT bin of subcarrier `k`: `(k - N/2) mod L`.
    pub(crate) fn bin_of_subcarrier(&self, k: usize) -> usize {
        (k + self.fft_len - self.params.subcarriers / 2) % self.fft_len
    }

    /// The known preamble, `preamble_symbols` rows of `N` values.
    pub fn preamble(&self) -> &[Complex64] {
        &self.preamble
    }

    /// Generates at least `min_frames` frames from `source` (a payload takes as many frames as it
    /// needs; framing in `super::bits`).
    ///
    /// # Errors
    ///
    /// [`ParamError`] when a payload is longer than its 32-bit length header can describe.
    pub fn generate(
        &self,
        source: &BitSource,
        min_frames: usize,
    ) -> Result<OfdmSignal, ParamError> {
        let framed = frame_bits(source, self.bits_per_frame(), min_frames)?;
        let n = self.params.subcarriers;
        let spf = self.params.symbols_per_frame;
        let mut data = Vec::with_capacity(framed.units * spf * n);
        for frame_bits in framed.bits.chunks_exact(self.bits_per_frame()) {
            data.extend_from_slice(&self.preamble);
            data.extend(frame_bits.chunks_exact(2).map(|p| qpsk_map(p[0], p[1])));
        }
        let symbols = SymbolMatrix::from_vec(framed.units * spf, n, data)?;
        let samples = self.modulate(&symbols)?;
        Ok(OfdmSignal {
            samples,
            symbols,
            bits: framed.bits,
            frames: framed.units,
            payload_len: framed.payload_len,
        })
    }

    /// Time signal of any symbol matrix with `N` columns: `symbols() * symbol_len()` samples.
    ///
    /// # Errors
    ///
    /// [`ParamError`] when `symbols` does not have the waveform's number of subcarriers.
    pub fn modulate(&self, symbols: &SymbolMatrix) -> Result<Vec<Complex64>, ParamError> {
        let mut out = vec![ZERO; symbols.symbols() * self.symbol_len()];
        self.modulate_into(symbols, &mut out)?;
        Ok(out)
    }

    /// As [`Ofdm::modulate`], into `out` (exactly `symbols() * symbol_len()` long).
    pub(crate) fn modulate_into(
        &self,
        symbols: &SymbolMatrix,
        out: &mut [Complex64],
    ) -> Result<(), ParamError> {
        let n = self.params.subcarriers;
        if symbols.subcarriers() != n {
            return Err(ParamError::out_of_range(
                "symbol matrix subcarriers",
                symbols.subcarriers(),
                &format!("must equal the waveform's subcarriers = {n}"),
            ));
        }
        if out.len() != symbols.symbols() * self.symbol_len() {
            return Err(ParamError::out_of_range(
                "OFDM output length",
                out.len(),
                &format!(
                    "must be symbols * symbol_len = {} * {}",
                    symbols.symbols(),
                    self.symbol_len()
                ),
            ));
        }
        let mut scratch = vec![ZERO; self.inverse.get_inplace_scratch_len()];
        for (row, sym_out) in symbols.rows().zip(out.chunks_exact_mut(self.symbol_len())) {
            let (cp, body) = sym_out.split_at_mut(self.cp_len);
            body.fill(ZERO);
            for (k, &x) in row.iter().enumerate() {
                body[self.bin_of_subcarrier(k)] = x * self.scale;
            }
            self.inverse.process_with_scratch(body, &mut scratch);
            cp.copy_from_slice(&body[self.fft_len - self.cp_len..]);
        }
        Ok(())
    }

    /// A receiver with its own scratch buffers.
    pub fn receiver(&self) -> OfdmReceiver {
        OfdmReceiver {
            ofdm: self.clone(),
            buf: vec![ZERO; self.fft_len],
            scratch: vec![ZERO; self.forward.get_inplace_scratch_len()],
            received: Vec::new(),
        }
    }
}

/// How the receiver learns the channel per subcarrier.
#[derive(Debug, Clone, PartialEq)]
pub enum Equalisation {
    /// Least-squares estimate from each frame's preamble symbols (averaged over them).
    Preamble,
    /// A known channel, one complex gain per subcarrier in ascending frequency.
    Known(Vec<Complex64>),
    /// No equalisation (unit channel).
    None,
}

/// What the OFDM receiver recovered from a capture.
#[derive(Debug, Clone)]
pub struct OfdmReception {
    /// Hard-decision data bits in transmission order (preambles excluded).
    pub bits: Vec<u8>,
    /// Equalised data symbols, `[symbol][k]`, preambles excluded.
    pub equalised: Vec<Complex64>,
    /// The channel estimate used for each frame, `[frame][k]`.
    pub channel: Vec<Complex64>,
}

/// OFDM receiver: plans shared with its [`Ofdm`], scratch owned, reusable across captures.
pub struct OfdmReceiver {
    ofdm: Ofdm,
    buf: Vec<Complex64>,
    scratch: Vec<Complex64>,
    received: Vec<Complex64>,
}

impl OfdmReceiver {
    pub fn waveform(&self) -> &Ofdm {
        &self.ofdm
    }

    /// Subcarrier values of every symbol of a symbol-aligned capture (`len` a multiple of
    /// `symbol_len`), `[symbol][k]`, appended to `out`, the generator's scale undone.
    ///
    /// # Errors
    ///
    /// [`ParamError`] when `capture` is not a whole number of symbols; nothing is appended then.
    pub fn subcarriers_into(
        &mut self,
        capture: &[Complex64],
        out: &mut Vec<Complex64>,
    ) -> Result<(), ParamError> {
        let sl = self.ofdm.symbol_len();
        if capture.len() % sl != 0 {
            return Err(ParamError::out_of_range(
                "OFDM capture length",
                capture.len(),
                &format!("must be a multiple of the symbol length {sl} (CP + FFT size)"),
            ));
        }
        let n = self.ofdm.params.subcarriers;
        let unscale = 1.0 / (self.ofdm.fft_len as f64 * self.ofdm.scale);
        out.reserve(capture.len() / sl * n);
        for sym in capture.chunks_exact(sl) {
            self.buf.copy_from_slice(&sym[self.ofdm.cp_len..]);
            self.ofdm
                .forward
                .process_with_scratch(&mut self.buf, &mut self.scratch);
            out.extend((0..n).map(|k| self.buf[self.ofdm.bin_of_subcarrier(k)] * unscale));
        }
        Ok(())
    }

    /// Demodulates a frame-aligned capture of whole frames.
    ///
    /// # Errors
    ///
    /// [`ParamError`] when `capture` is empty or not a whole number of frames,
    /// [`Equalisation::Preamble`] is asked of a frame without preamble symbols, or a known channel
    /// does not hold one finite, non-zero gain per subcarrier.
    pub fn receive(
        &mut self,
        capture: &[Complex64],
        equalisation: &Equalisation,
    ) -> Result<OfdmReception, ParamError> {
        let fl = self.ofdm.frame_len();
        if capture.is_empty() || capture.len() % fl != 0 {
            return Err(ParamError::out_of_range(
                "OFDM capture length",
                capture.len(),
                &format!("must be a non-zero multiple of the frame length {fl}"),
            ));
        }
        let n = self.ofdm.params.subcarriers;
        if *equalisation == Equalisation::Preamble && self.ofdm.params.preamble_symbols == 0 {
            return Err(ParamError::out_of_range(
                "preamble_symbols",
                0,
                "must be at least 1 to equalise from the preamble; or give the channel \
                 (Equalisation::Known)",
            ));
        }
        if let Equalisation::Known(h) = equalisation {
            if h.len() != n || h.iter().any(|z| !(z.norm_sqr() > 0.0 && z.is_finite())) {
                return Err(ParamError::out_of_range(
                    "known channel",
                    format!("{} values", h.len()),
                    &format!("must hold {n} finite, non-zero gains (one per subcarrier)"),
                ));
            }
        }
        let mut received = std::mem::take(&mut self.received);
        received.clear();
        self.subcarriers_into(capture, &mut received)?;
        let spf = self.ofdm.params.symbols_per_frame;
        let npre = self.ofdm.params.preamble_symbols;
        let frames = capture.len() / fl;
        let mut reception = OfdmReception {
            bits: Vec::with_capacity(frames * self.ofdm.bits_per_frame()),
            equalised: Vec::with_capacity(frames * (spf - npre) * n),
            channel: Vec::with_capacity(frames * n),
        };
        let mut h = vec![Complex64::new(1.0, 0.0); n];
        for frame in received.chunks_exact(spf * n) {
            match equalisation {
                Equalisation::Known(given) => h.copy_from_slice(given),
                Equalisation::None => h.fill(Complex64::new(1.0, 0.0)),
                Equalisation::Preamble => {
                    h.fill(ZERO);
                    for (rx, tx) in frame[..npre * n]
                        .chunks_exact(n)
                        .zip(self.ofdm.preamble.chunks_exact(n))
                    {
                        for k in 0..n {
                            h[k] += rx[k] / tx[k];
                        }
                    }
                    for v in &mut h {
                        *v /= npre as f64;
                    }
                }
            }
            reception.channel.extend_from_slice(&h);
            for sym in frame[npre * n..].chunks_exact(n) {
                for (k, &y) in sym.iter().enumerate() {
                    let z = y / h[k];
                    let (b0, b1) = qpsk_decide(z);
                    reception.equalised.push(z);
                    reception.bits.push(b0);
                    reception.bits.push(b1);
                }
            }
        }
        self.received = received;
        Ok(reception)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn small() -> Ofdm {
        Ofdm::new(OfdmParams {
            subcarriers: 16,
            oversampling: 4,
            symbols_per_frame: 5,
            ..Default::default()
        })
        .unwrap()
    }

    #[test]
    fn default_sizes_follow_the_thesis() {
        let o = Ofdm::new(OfdmParams::default()).unwrap();
        assert_eq!(o.fft_len(), 2048);
        assert_eq!(o.cp_len(), 512);
        assert_eq!(o.frame_len(), 256_000);
        assert_eq!(o.sample_rate_hz(), 16e9);
        assert_eq!(o.bin_of_subcarrier(0), 2048 - 64);
        assert_eq!(o.bin_of_subcarrier(64), 0);
    }

    #[test]
    fn unit_mean_power_and_cyclic_prefix() {
        let o = small();
        let sig = o.generate(&BitSource::Prbs { seed: 1 }, 2).unwrap();
        // Parseval: the useful part of every symbol has mean power exactly 1 (the CP is a copy of a
        // random stretch of it, so the whole frame is 1 only on average).
        for sym in sig.samples.chunks_exact(o.symbol_len()) {
            let body = &sym[o.cp_len()..];
            let p = body.iter().map(|z| z.norm_sqr()).sum::<f64>() / body.len() as f64;
            assert!((p - 1.0).abs() < 1e-12, "mean power {p}");
        }
        for sym in sig.samples.chunks_exact(o.symbol_len()) {
            let (cp, body) = sym.split_at(o.cp_len());
            for (a, b) in cp.iter().zip(&body[o.fft_len() - o.cp_len()..]) {
                assert_eq!(a, b);
            }
        }
        assert_eq!(sig.symbols.symbols(), 10);
        assert_eq!(sig.symbols.row(0), o.preamble());
        assert_eq!(sig.symbols.row(5), o.preamble());
    }

    #[test]
    fn noise_free_round_trip_returns_the_symbols() {
        let o = small();
        let sig = o.generate(&BitSource::Prbs { seed: 2 }, 1).unwrap();
        let mut rx = o.receiver();
        let mut values = Vec::new();
        rx.subcarriers_into(&sig.samples, &mut values).unwrap();
        for (a, b) in values.iter().zip(sig.symbols.as_slice()) {
            assert!((a - b).norm() < 1e-12);
        }
        let r = rx.receive(&sig.samples, &Equalisation::Preamble).unwrap();
        assert_eq!(r.bits, sig.bits);
    }

    #[test]
    fn validation_names_the_parameter() {
        let bad = |p: OfdmParams| Ofdm::new(p).unwrap_err().message;
        let d = OfdmParams::default();
        assert!(bad(OfdmParams {
            cp_fraction: 1.0,
            ..d
        })
        .contains("shorter than the symbol"));
        assert!(bad(OfdmParams {
            cp_fraction: 0.1,
            ..d
        })
        .contains("whole number"));
        assert!(bad(OfdmParams {
            subcarriers: 7,
            ..d
        })
        .contains("subcarriers"));
        assert!(bad(OfdmParams {
            oversampling: 0,
            ..d
        })
        .contains("oversampling"));
        assert!(bad(OfdmParams {
            preamble_symbols: 100,
            ..d
        })
        .contains("symbols_per_frame"));
        assert!(bad(OfdmParams {
            bandwidth_hz: -1.0,
            ..d
        })
        .contains("bandwidth_hz"));
        // Equalising from a preamble that is not there is an error, not a silent unit channel.
        let o = Ofdm::new(OfdmParams {
            subcarriers: 8,
            oversampling: 2,
            symbols_per_frame: 3,
            preamble_symbols: 0,
            ..d
        })
        .unwrap();
        let sig = o.generate(&BitSource::Prbs { seed: 1 }, 1).unwrap();
        assert_eq!(sig.bits.len(), 48);
        let mut rx = o.receiver();
        let err = rx
            .receive(&sig.samples, &Equalisation::Preamble)
            .unwrap_err();
        assert!(err.message.contains("preamble_symbols"), "{err}");
        assert_eq!(
            rx.receive(&sig.samples, &Equalisation::None).unwrap().bits,
            sig.bits
        );
        // Not a power of two is fine.
        assert!(Ofdm::new(OfdmParams {
            subcarriers: 100,
            ..d
        })
        .is_ok());
    }
}
