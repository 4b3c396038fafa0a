//! Scenes for the detection tests and the limits study, synthesised through the real kernels: the
//! thesis MSK-LFM pulse or OFDM frame from `radbench::waveform`, echoes delayed by fractional
//! samples in the frequency domain (circularly, as the looping AWG gives), seeded complex noise, then
//! the real receivers (`CorrelationProfiler`, `OfdmRadar`) to a complex profile.
#![allow(dead_code)]

use num_complex::Complex64;
use radbench::dsp::Axis;
use radbench::dsp::CorrelationProfiler;
use radbench::dsp::PeriodicDecimator;
use radbench::dsp::C0;
use radbench::dsp::{DetectOptions, Detector, SpectralLines, TabulatedPsf};
use radbench::dsp::{IDiv, OfdmRadar, OfdmRadarConfig};
use radbench::rng::SplitMix64;
use radbench::waveform::BitSource;
use radbench::waveform::{MskLfm, MskLfmParams};
use radbench::waveform::{Ofdm, OfdmParams};
use rustfft::{Fft, FftPlanner};
use std::f64::consts::PI;
use std::sync::Arc;

/// Per-sample SNR of a unit-amplitude echo at the profile's input (16 GSa/s): the bench's 30 dB
/// at 80 GSa/s plus the 7 dB of a band-matched decimation by 5.
pub const SNR_DB: f64 = 37.0;
/// The bench carrier, for physical echo phases.
pub const CARRIER_HZ: f64 = 80e9;
/// The resolution cell c0 / 2B at 1 GHz, m.
pub const RES_M: f64 = C0 / 2e9;
/// Range window of the reports (the capture's default min/max range).
pub const WINDOW: std::ops::RangeInclusive<f64> = 0.15..=10.0;

/// A point reflector: range, amplitude, echo phase (radians).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Pillar {
    pub range_m: f64,
    pub amp: f64,
    pub phase: f64,
}

impl Pillar {
    /// A reflector with the physical carrier phase `-2 pi f_c tau`.
    pub fn physical(range_m: f64, amp: f64) -> Self {
        let tau = 2.0 * range_m / C0;
        Self {
            range_m,
            amp,
            phase: -2.0 * PI * (CARRIER_HZ * tau).fract(),
        }
    }
}

/// The direct Tx -> Rx leakage of the simulated bench: 0.01 at 0.2 ns (3 cm).
pub fn leakage(amp: f64) -> Pillar {
    Pillar::physical(0.2e-9 * C0 / 2.0, amp)
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Wave {
    MskLfm,
    Ofdm,
}

impl Wave {
    pub fn name(self) -> &'static str {
        match self {
            Wave::MskLfm => "MSK-LFM (correlation)",
            Wave::Ofdm => "OFDM (Fourier, rect)",
        }
    }
}

enum Receiver {
    Correlation {
        profiler: CorrelationProfiler,
        lags: usize,
        ext: Vec<Complex64>,
    },
    Fourier {
        radar: OfdmRadar,
        symbols: Vec<Complex64>,
        idiv: IDiv,
    },
}

/// One waveform's transmitter, channel and receiver, with its point spread.
pub struct Bench {
    pub wave: Wave,
    /// One repetition of the transmitted signal at 16 GSa/s.
    pub reference: Vec<Complex64>,
    spectrum: Vec<Complex64>,
    forward: Arc<dyn Fft<f64>>,
    inverse: Arc<dyn Fft<f64>>,
    fs: f64,
    receiver: Receiver,
    pub profile: Vec<Complex64>,
    pub axis: Axis,
    psf_msk: Option<TabulatedPsf>,
    psf_ofdm: Option<TabulatedPsf>,
    pub lines: Option<SpectralLines>,
}

impl Bench {
    pub fn new(wave: Wave) -> Self {
        match wave {
            Wave::MskLfm => Self::msk_lfm(),
            Wave::Ofdm => Self::ofdm(),
        }
    }

    /// The thesis MSK-LFM: 1 GHz, 10 us, 128 bits at 16 GSa/s; correlation lags for 10 m plus the
    /// 20 ns margin of the capture processing.
    pub fn msk_lfm() -> Self {
        let gen = MskLfm::new(MskLfmParams::default()).unwrap();
        let fs = gen.sample_rate_hz();
        let reference = gen
            .generate(&BitSource::Prbs { seed: 1 }, 1)
            .unwrap()
            .samples;
        let lags = ((2.0 * 10.0 / C0 + 20e-9) * fs).ceil() as usize;
        let p = reference.len();
        let profiler = CorrelationProfiler::new(&reference, p + lags - 1, lags, fs).unwrap();
        let axis = profiler.axis();
        let psf = TabulatedPsf::correlation(&reference, None, lags + 16).unwrap();
        Self::finish(
            Wave::MskLfm,
            reference,
            fs,
            Receiver::Correlation {
                profiler,
                lags,
                ext: Vec::new(),
            },
            axis,
            Some(psf),
            None,
            None,
        )
    }

    /// The thesis OFDM: 128 subcarriers over 1 GHz, CP 1/4, x16 at 16 GSa/s, 100 symbols; Fourier
    /// profile zero-padded x10, rectangular window.
    pub fn ofdm() -> Self {
        let params = OfdmParams::default();
        let gen = Ofdm::new(params).unwrap();
        let fs = gen.sample_rate_hz();
        let signal = gen.generate(&BitSource::Prbs { seed: 2 }, 1).unwrap();
        let radar = OfdmRadar::new(OfdmRadarConfig::default()).unwrap();
        let axis = radar.range_axis();
        let k = radar.config().profile_len();
        let lines =
            SpectralLines::ofdm(radar.config().zero_pad, radar.normalised_window()).unwrap();
        let psf = TabulatedPsf::from_lines(&lines, Some(k)).unwrap();
        Self::finish(
            Wave::Ofdm,
            signal.samples,
            fs,
            Receiver::Fourier {
                radar,
                symbols: signal.symbols.into_vec(),
                idiv: IDiv::new(),
            },
            axis,
            None,
            Some(psf),
            Some(lines),
        )
    }

    #[allow(clippy::too_many_arguments)]
    fn finish(
        wave: Wave,
        reference: Vec<Complex64>,
        fs: f64,
        receiver: Receiver,
        axis: Axis,
        psf_msk: Option<TabulatedPsf>,
        psf_ofdm: Option<TabulatedPsf>,
        lines: Option<SpectralLines>,
    ) -> Self {
        let p = reference.len();
        let mut planner = FftPlanner::new();
        let forward = planner.plan_fft_forward(p);
        let inverse = planner.plan_fft_inverse(p);
        let mut spectrum = reference.clone();
        forward.process(&mut spectrum);
        Self {
            wave,
            reference,
            spectrum,
            forward,
            inverse,
            fs,
            receiver,
            profile: Vec::new(),
            axis,
            psf_msk,
            psf_ofdm,
            lines,
        }
    }

    /// The tabulated point spread of this bench's profile.
    pub fn psf(&self) -> TabulatedPsf {
        self.psf_msk
            .clone()
            .or_else(|| self.psf_ofdm.clone())
            .unwrap()
    }

    pub fn detector(&self, options: DetectOptions) -> Detector {
        Detector::new(self.psf(), options).unwrap()
    }

    /// The received repetition: every pillar's echo (exact fractional, circular delay) plus
    /// complex noise of power `10^(-snr/10)` per sample (none for `None`).
    pub fn capture(&self, pillars: &[Pillar], snr_db: Option<f64>, seed: u64) -> Vec<Complex64> {
        self.capture_through(pillars, snr_db, seed, &|_| Complex64::new(1.0, 0.0))
    }

    /// As [`Bench::capture`], through a chain of frequency response `response(f)` (f in Hz from
    /// the carrier).
    pub fn capture_through(
        &self,
        pillars: &[Pillar],
        snr_db: Option<f64>,
        seed: u64,
        response: &dyn Fn(f64) -> Complex64,
    ) -> Vec<Complex64> {
        let p = self.reference.len();
        let mut acc = vec![Complex64::default(); p];
        for t in pillars {
            let d = 2.0 * t.range_m / C0 * self.fs;
            let a = Complex64::from_polar(t.amp / p as f64, t.phase);
            for (k, (o, s)) in acc.iter_mut().zip(&self.spectrum).enumerate() {
                let nu = if k <= p / 2 {
                    k as f64
                } else {
                    k as f64 - p as f64
                } / p as f64;
                *o +=
                    s * a * response(nu * self.fs) * Complex64::from_polar(1.0, -2.0 * PI * nu * d);
            }
        }
        self.inverse.process(&mut acc);
        if let Some(snr) = snr_db {
            SplitMix64::new(seed).add_noise(&mut acc, 10f64.powf(-snr / 10.0));
        }
        acc
    }

    /// The bench's capture path: the echoes at 80 GSa/s (ideal AWG interpolation of the periodic
    /// segment), noise of power `10^(-snr/10)` per sample at 80 GSa/s, then the lab decimator by 5
    /// back to 16 GSa/s (`PeriodicDecimator`, flat to 0.55 GHz as the capture processing asks).
    pub fn capture_80g(
        &self,
        pillars: &[Pillar],
        snr_db: f64,
        seed: u64,
        decimator: &mut PeriodicDecimator,
    ) -> Vec<Complex64> {
        let p = self.reference.len();
        let up = 5 * p;
        let mut acc = vec![Complex64::default(); up];
        for t in pillars {
            let d = 2.0 * t.range_m / C0 * self.fs;
            let a = Complex64::from_polar(t.amp / p as f64, t.phase);
            for (k, s) in self.spectrum.iter().enumerate() {
                let signed = if k <= p / 2 {
                    k as isize
                } else {
                    k as isize - p as isize
                };
                let nu = signed as f64 / p as f64;
                acc[signed.rem_euclid(up as isize) as usize] +=
                    s * a * Complex64::from_polar(1.0, -2.0 * PI * nu * d);
            }
        }
        FftPlanner::new().plan_fft_inverse(up).process(&mut acc);
        SplitMix64::new(seed).add_noise(&mut acc, 10f64.powf(-snr_db / 10.0));
        decimator.decimate(&acc)
    }

    /// The complex profile of a capture, into `self.profile`.
    pub fn process(&mut self, rx: &[Complex64]) -> &[Complex64] {
        match &mut self.receiver {
            Receiver::Correlation {
                profiler,
                lags,
                ext,
            } => {
                ext.clear();
                ext.extend_from_slice(rx);
                ext.extend_from_slice(&rx[..*lags - 1]);
                let z = profiler.complex_profile(ext).unwrap();
                self.profile.clear();
                self.profile.extend_from_slice(z);
            }
            Receiver::Fourier {
                radar,
                symbols,
                idiv,
            } => {
                radar.divide(rx, 0, symbols, idiv).unwrap();
                radar.complex_profile(idiv, &mut self.profile).unwrap();
            }
        }
        &self.profile
    }

    /// Capture and process in one go.
    pub fn scene(&mut self, pillars: &[Pillar], snr_db: Option<f64>, seed: u64) -> &[Complex64] {
        let rx = self.capture(pillars, snr_db, seed);
        self.process(&rx)
    }

    /// The forward FFT plan of one repetition (for tests that need spectra).
    pub fn forward(&self) -> &Arc<dyn Fft<f64>> {
        &self.forward
    }
}

/// Random scene of the property test: 1-4 pillars in `lo..hi` m, at least `min_gap` m apart, the
/// strongest at amplitude 1 and the others within `spread_db` of it, random phases and sub-cell
/// positions.
pub fn random_scene(
    rng: &mut SplitMix64,
    lo: f64,
    hi: f64,
    min_gap: f64,
    spread_db: f64,
) -> Vec<Pillar> {
    let count = 1 + (rng.uniform() * 4.0) as usize;
    let mut pillars: Vec<Pillar> = Vec::new();
    while pillars.len() < count.min(4) {
        let r = lo + rng.uniform() * (hi - lo);
        if pillars.iter().all(|p| (p.range_m - r).abs() >= min_gap) {
            let amp = if pillars.is_empty() {
                1.0
            } else {
                10f64.powf(-rng.uniform() * spread_db / 20.0)
            };
            pillars.push(Pillar {
                range_m: r,
                amp,
                phase: 2.0 * PI * rng.uniform(),
            });
        }
    }
    pillars
}

/// Matches detections to pillars: for each pillar the nearest detected range within `tol` m
/// (each detection used once), and the detections matched to none.
pub fn match_targets(pillars: &[Pillar], found: &[f64], tol: f64) -> (Vec<Option<f64>>, Vec<f64>) {
    let mut used = vec![false; found.len()];
    let mut matched = Vec::new();
    for p in pillars {
        let best = found
            .iter()
            .enumerate()
            .filter(|(i, r)| !used[*i] && (*r - p.range_m).abs() <= tol)
            .min_by(|a, b| (a.1 - p.range_m).abs().total_cmp(&(b.1 - p.range_m).abs()));
        matched.push(best.map(|(i, &r)| {
            used[i] = true;
            r
        }));
    }
    let extra = found
        .iter()
        .zip(&used)
        .filter(|(_, u)| !**u)
        .map(|(r, _)| *r)
        .collect();
    (matched, extra)
}
