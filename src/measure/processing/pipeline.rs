//! The one measurement pipeline: from a capture in volts to range profiles, targets, metrics and
//! the decoded payload. Every caller (capture, calibrate, campaigns, `process`, simulations) goes
//! through a [`Pipeline`]; the five range algorithms are dispatched here and nowhere else.
//!
//! A pipeline is configured once per transmission, processing choice and record geometry: the
//! decimation filter, FFT plans, correlation spectra, OFDM and MUSIC workspaces and the payload
//! receivers are built in [`Pipeline::new`] (the decimator on the first capture at a new rate) and
//! reused for every capture.
//!
//! Chain: [`Pipeline::align`] decimates the capture to the waveform rate and rotates it so sample
//! `m` lies `m / fs` after the marker edge (up to a sub-sample residual); `Pipeline::analyse`
//! computes the range profiles and the detections; [`Pipeline::process`] adds the metrics and the
//! payload. The AWG loops its segment, so the received signal is periodic: one repetition holds
//! every echo (wrapped) and correlation is circular over it. Ranges are measured from the antennas:
//! the time of the first sample after the trigger is added and the calibrated system delay
//! subtracted.

use super::clipping::{self, Clipping, RecordClipping, ScopeAdc};
use super::options::{Algorithm, ProcessOptions, MAX_ZERO_PAD, MUSIC_GRID_FACTOR};
use super::payload::PayloadDecoder;
use super::range_result::RangeResult;
use super::ranging::RangingModel;
use super::transmit::Transmission;
use crate::dsp::decimate::{Samples, ScaledWords};
use crate::dsp::music::root_music_ranges;
use crate::dsp::ofdm_radar::{
    IDiv, OfdmRadar, OfdmRadarConfig, RangeDoppler, RangeDopplerConfig, RangeDopplerMap,
    RangeProfile, VelocityEstimator,
};
use crate::dsp::range_profile::{music_profile, weighted_filter, CorrelationProfiler, Profile};
use crate::dsp::response::RxEqualiser;
use crate::dsp::Axis;
use crate::dsp::C0;
use crate::dsp::{DecimatorConfig, PeriodicDecimator};
use crate::dsp::{Detector, SpectralLines, TabulatedPsf};
use crate::dsp::{ModelOrder, Music, MusicConfig, MusicSpectrum, OrderCriterion};
use crate::measure::error::MeasureError;
use crate::measure::processing::detect;
use crate::waveform::{Ofdm, SymbolMatrix};
use num_complex::Complex64;
use std::sync::Arc;

pub use super::detect::{Detection, DetectionReport};
pub use super::payload::PayloadResult;

/// A bit error rate above this is reported as a failed decoding (a working link is orders of
/// magnitude below it; 0.5 is a coin toss).
const BER_WARNING: f64 = 0.1;

const ZERO: Complex64 = Complex64 { re: 0.0, im: 0.0 };

/// Lags the correlation keeps beyond the farthest range of interest, seconds: the side-lobes of a
/// target at the far edge of the window stay visible.
const CORRELATION_MARGIN_S: f64 = 20e-9;

/// The capture in volts at the scope's rate.
#[derive(Debug, Clone)]
pub struct RawIq {
    pub samples: Vec<Complex64>,
    pub sample_rate_hz: f64,
    /// Time of the first sample after the trigger (marker edge), seconds.
    pub first_point_s: f64,
}

/// The capture as the scope's words and their scaling (volts = gain * word - offset), I and Q:
/// aligned without a record in volts first.
#[derive(Debug, Clone)]
pub struct RawWords {
    pub i: Vec<i16>,
    pub q: Vec<i16>,
    pub gain: [f64; 2],
    pub offset: [f64; 2],
    pub sample_rate_hz: f64,
    /// Time of the first sample after the trigger (marker edge), seconds.
    pub first_point_s: f64,
}

impl RawWords {
    /// The samples of I and Q at the ADC's rails, and the rails in volts: one pass over the
    /// words, beside their conversion to volts in [`Pipeline::align_words`].
    pub(crate) fn clipping(&self, adc: &ScopeAdc) -> RecordClipping {
        let rails = adc.rails;
        RecordClipping {
            count: clipping::ClipCount {
                i: rails.count(&self.i),
                q: rails.count(&self.q),
                samples: self.i.len().min(self.q.len()),
            },
            rails_v: [
                rails.volts(self.gain[0], self.offset[0]),
                rails.volts(self.gain[1], self.offset[1]),
            ],
            scope: Some(*adc),
        }
    }
}

/// A capture [`Pipeline::align`] or `Pipeline::align_words` take.
pub trait Alignable {
    fn align_in(&self, pipeline: &mut Pipeline) -> Result<Aligned, MeasureError>;
}

impl Alignable for RawIq {
    fn align_in(&self, pipeline: &mut Pipeline) -> Result<Aligned, MeasureError> {
        pipeline.align(self)
    }
}

impl Alignable for RawWords {
    fn align_in(&self, pipeline: &mut Pipeline) -> Result<Aligned, MeasureError> {
        pipeline.align_words(self)
    }
}

/// One repetition at the waveform rate, aligned to the marker edge: sample `m` is at
/// `m / fs + residual_s` after it.
#[derive(Debug, Clone, PartialEq)]
pub struct Aligned {
    pub samples: Vec<Complex64>,
    pub residual_s: f64,
}

/// What the pipeline's record looks like.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RecordGeometry {
    /// Samples of one repetition at the waveform rate (the AWG's padded segment).
    pub period: usize,
    /// Correlation lags kept (0..lags), at most `period`.
    pub correlation_lags: usize,
}

impl RecordGeometry {
    /// A bench capture: lags up to the farthest range of interest plus the system delay and a
    /// margin.
    pub(crate) fn for_capture(
        period: usize,
        sample_rate_hz: f64,
        options: &ProcessOptions,
    ) -> Self {
        let max_delay = 2.0 * options.max_range_m.max(0.0) / C0
            + options.system_delay_s.max(0.0)
            + CORRELATION_MARGIN_S;
        let lags = (max_delay * sample_rate_hz).ceil();
        let lags = if lags.is_finite() {
            lags as usize
        } else {
            period
        };
        Self {
            period,
            correlation_lags: lags.clamp(2, period.max(2)),
        }
    }
}

/// Range processing and detection of one record.
#[derive(Debug, Clone)]
pub(crate) struct Analysis {
    pub range: RangeResult,
    pub detection: DetectionReport,
}

/// Everything the processing found.
#[derive(Debug, Clone)]
pub struct Processed {
    /// Primary profile first (MUSIC over Fourier when both), ranges from the antennas.
    pub profiles: Vec<Profile>,
    /// The primary profile's complex values on its scale (`|z|` is its amplitude): correlation
    /// and Fourier; `None` for the subspace estimators (MUSIC, root-MUSIC, ESPRIT).
    pub complex_profile: Option<Vec<Complex64>>,
    pub targets: Vec<Detection>,
    /// Main-lobe width of the strongest target, cm.
    pub width_3db_cm: Option<f64>,
    /// Peak side-lobe level around the strongest target, dB.
    pub sidelobe_db: Option<f64>,
    /// The strongest target's signal-to-noise ratio per profile cell, dB (the noise measured
    /// beside the band: [`Detection::snr_db`]).
    pub snr_db: Option<f64>,
    /// The strongest target over the detector's residual floor, dB
    /// ([`Detection::peak_to_floor_db`]).
    pub peak_to_floor_db: Option<f64>,
    /// What the processing costs in signal-to-noise ratio against a matched filter on the
    /// chain as it is, dB: the window's mismatch, and the receive correction's noise lift.
    pub losses_db: Losses,
    pub payload: Option<PayloadResult>,
    /// The detection threshold per primary-profile cell (amplitude; empty for the subspace
    /// estimators), reflectors outside the range window, the noise level.
    pub detection: DetectionReport,
    /// The range-Doppler map (OFDM frames of two symbols or more).
    pub range_doppler: Option<RangeDopplerMap>,
    /// Things a user should check (no target, clipping, ...).
    pub warnings: Vec<String>,
    /// Samples at the scope's ADC rails and what detection did about them (captures of the
    /// scope's words only).
    pub clipping: Option<Clipping>,
    /// The capture decimated to the waveform rate and aligned to the marker (background
    /// subtracted).
    pub aligned: Vec<Complex64>,
}

/// The spectrum of a correlation profile's point spread: `REF_k conj(FILTER_k)` (the filter is the
/// reference itself, or its weighted version).
fn echo_spectrum(reference: &[Complex64], filter: &[Complex64]) -> Vec<Complex64> {
    let n = reference.len();
    let fft = crate::dsp::plans::forward(n);
    let mut r = reference.to_vec();
    let mut f = filter.to_vec();
    fft.process(&mut r);
    fft.process(&mut f);
    r.iter().zip(&f).map(|(a, b)| a * b.conj()).collect()
}

/// The band shape of the profile's point spread (the transmitted spectrum and the window's
/// filter over one period), which the range uncertainty is made from; `None` for the subspace
/// estimators (no complex profile).
fn band_shape(
    tx: &Transmission,
    options: &ProcessOptions,
    period: usize,
) -> Option<crate::dsp::carrier_phase::BandShape> {
    if options.algorithm.is_subspace() {
        return None;
    }
    let fs = tx.sample_rate_hz();
    let mut reference = tx.reference.clone();
    reference.resize(period.max(tx.reference.len()), ZERO);
    let window = options.window.to_dsp();
    // The rectangular window's filter is the reference itself.
    let filter = if window == crate::dsp::Window::Rectangular {
        None
    } else {
        Some(weighted_filter(&reference, &window, tx.band_hz(), fs).ok()?)
    };
    // echo_spectrum's product, with the filter's spectrum kept for its power (one FFT fewer;
    // two fewer for the rectangular window).
    let fft = crate::dsp::plans::forward(reference.len());
    let mut r = reference;
    fft.process(&mut r);
    let f = match filter {
        None => r.clone(),
        Some(mut f) => {
            fft.process(&mut f);
            f
        }
    };
    let cross: Vec<Complex64> = r.iter().zip(&f).map(|(a, b)| a * b.conj()).collect();
    let power: Vec<f64> = f.iter().map(|v| v.norm_sqr()).collect();
    crate::dsp::carrier_phase::BandShape::of_spectrum(&cross, &power, fs)
}

/// Relative scale of the levels: 1 / (volts at the AWG output per unit of the reference).
fn level_scale(options: &ProcessOptions) -> f64 {
    match options.awg_amplitude_vpp {
        // A code c leaves the DAC as c * Vpp / 255 and the reference is codes / 127.
        Some(vpp) if vpp > 0.0 && vpp.is_finite() => 255.0 / (127.0 * vpp),
        _ => 1.0,
    }
}

/// The reference over one period and the correlation's filter (`None`: the reference itself,
/// the rectangular window).
struct EchoInputs {
    reference: Vec<Complex64>,
    filter: Option<Vec<Complex64>>,
}

impl EchoInputs {
    fn filter(&self) -> &[Complex64] {
        self.filter.as_deref().unwrap_or(&self.reference)
    }
}

/// The range processing of one algorithm, with its plans and workspaces.
enum RangeProcessor {
    Correlation {
        profiler: Box<CorrelationProfiler>,
        lags: usize,
        extended: Vec<Complex64>,
        /// What the detector's point spread is made from: the echo spectrum the profile sees
        /// (transmit spectrum times the conjugate filter spectrum, before the capture chain's
        /// response) is made from these only when the point spread is not in the cache.
        echo: EchoInputs,
    },
    Ofdm(Box<OfdmProcessor>),
}

struct OfdmProcessor {
    radar: OfdmRadar,
    symbols: Vec<Complex64>,
    idiv: IDiv,
    profile: RangeProfile,
    /// Peak of the transmitted frame processed alike: a unit-gain echo's level.
    unit: f64,
    /// MUSIC / root-MUSIC / ESPRIT (absent for Fourier).
    music: Option<Music>,
    spectrum: MusicSpectrum,
    df_hz: f64,
    /// Radial velocity per target from the slow time across symbols (frames of 2+ symbols).
    velocity: Option<VelocityEstimator>,
}

impl RangeProcessor {
    /// The correlation profiler over one period, with the window's filter.
    fn correlation(
        tx: &Transmission,
        options: &ProcessOptions,
        geometry: &RecordGeometry,
    ) -> Result<RangeProcessor, MeasureError> {
        let fs = tx.sample_rate_hz();
        let period = geometry.period;
        let lags = geometry.correlation_lags.clamp(2, period.max(2));
        let mut reference = tx.reference.clone();
        reference.resize(period, ZERO);
        let window = options.window.to_dsp();
        let filter = if window == crate::dsp::Window::Rectangular {
            None
        } else {
            Some(weighted_filter(&reference, &window, tx.band_hz(), fs)?)
        };
        let echo = EchoInputs { reference, filter };
        let profiler = CorrelationProfiler::with_filter(
            &echo.reference,
            echo.filter(),
            period + lags - 1,
            lags,
            fs,
        )?;
        Ok(RangeProcessor::Correlation {
            profiler: Box::new(profiler),
            lags,
            extended: Vec::with_capacity(period + lags - 1),
            echo,
        })
    }
}

impl OfdmProcessor {
    /// The OFDM radar receiver, its unit level, and the subspace estimator when the options'
    /// algorithm is one.
    fn new(
        tx: &Transmission,
        generator: &Ofdm,
        symbols: &SymbolMatrix,
        options: &ProcessOptions,
    ) -> Result<OfdmProcessor, MeasureError> {
        let params = *generator.params();
        let mut radar = OfdmRadar::new(OfdmRadarConfig {
            subcarriers: params.subcarriers,
            oversampling: params.oversampling,
            cp_fraction: params.cp_fraction,
            bandwidth_hz: params.bandwidth_hz,
            zero_pad: options.zero_pad,
            window: options.window.to_dsp(),
            fft_precision: options.fft_precision.to_dsp(),
            ..OfdmRadarConfig::default()
        })?;
        let mut idiv = IDiv::new();
        let mut profile = RangeProfile::new();
        // Levels relative to a unit-gain path: the transmitted frame itself, processed
        // alike, peaks at the normalising value.
        radar.process(
            &tx.reference,
            0,
            symbols.as_slice(),
            &mut idiv,
            &mut profile,
        )?;
        let unit = profile
            .amplitude
            .iter()
            .copied()
            .fold(0.0, f64::max)
            .max(1e-300);
        let music = if options.algorithm.is_subspace() {
            let n = params.subcarriers;
            Some(Music::new(MusicConfig {
                subcarriers: n,
                subarray: options.music_m,
                order: options
                    .music_p
                    .map(ModelOrder::Fixed)
                    .unwrap_or(ModelOrder::Estimated(OrderCriterion::Mdl)),
                forward_backward: options.forward_backward,
                grid_points: MUSIC_GRID_FACTOR * n,
                bandwidth_hz: params.bandwidth_hz,
            })?)
        } else {
            None
        };
        let velocity = (symbols.symbols() >= 2)
            .then(|| {
                VelocityEstimator::new(
                    symbols.symbols(),
                    radar.config().symbol_period_s(),
                    options.carrier_hz,
                )
            })
            .transpose()?;
        Ok(OfdmProcessor {
            radar,
            symbols: symbols.as_slice().to_vec(),
            idiv,
            profile,
            unit,
            music,
            spectrum: MusicSpectrum::default(),
            df_hz: generator.subcarrier_spacing_hz(),
            velocity,
        })
    }

    /// The Fourier profile, and the subspace estimator's result when one is configured.
    fn profiles(
        &mut self,
        rx: &[Complex64],
        options: &ProcessOptions,
        place: Placement,
    ) -> Result<RangeResult, MeasureError> {
        self.radar
            .process(rx, 0, &self.symbols, &mut self.idiv, &mut self.profile)?;
        let unit = self.unit;
        let fourier = place.place(Profile {
            label: format!("Fourier ({}-point IFFT)", self.profile.amplitude.len()),
            axis: self.profile.axis(),
            amplitude: self.profile.amplitude.iter().map(|a| a / unit).collect(),
        });
        let Some(music) = &mut self.music else {
            let mut z = Vec::new();
            self.radar.complex_profile(&self.idiv, &mut z)?;
            let k = place.scale / unit;
            for v in &mut z {
                *v *= k;
            }
            return Ok(RangeResult {
                profiles: vec![fourier],
                estimates_m: None,
                complex: Some(z),
            });
        };
        let idiv = self.idiv.as_slice();
        let (profiles, estimates) = match options.algorithm {
            Algorithm::Esprit => (vec![fourier], music.esprit(idiv)?),
            Algorithm::RootMusic => {
                music.estimate(idiv, &mut self.spectrum)?;
                let r = root_music_ranges(music, self.spectrum.order, self.df_hz)?;
                (vec![fourier], r)
            }
            // MUSIC. A subspace estimator is made only for the subspace methods, so Fourier and
            // correlation never get here; named rather than `_`, so that a new algorithm is a
            // compile error here instead of running as MUSIC.
            Algorithm::Music | Algorithm::Fourier | Algorithm::Correlation => {
                music.estimate(idiv, &mut self.spectrum)?;
                let mut mp = music_profile(
                    &self.spectrum.range_m,
                    &self.spectrum.pseudo_spectrum,
                    options.music_m,
                    self.spectrum.order,
                );
                mp.axis.start += place.offset_m;
                (vec![mp, fourier], self.spectrum.peaks_m.clone())
            }
        };
        Ok(RangeResult {
            profiles,
            estimates_m: Some(place.shift(estimates)),
            complex: None,
        })
    }
}

/// Where a profile goes: its amplitudes scaled to a unit-gain echo, its ranges shifted by the
/// bench's offset.
#[derive(Clone, Copy)]
struct Placement {
    scale: f64,
    offset_m: f64,
}

impl Placement {
    fn place(self, mut p: Profile) -> Profile {
        p.axis.start += self.offset_m;
        if self.scale != 1.0 {
            for a in &mut p.amplitude {
                *a *= self.scale;
            }
        }
        p
    }

    fn shift(self, ranges: Vec<f64>) -> Vec<f64> {
        ranges.into_iter().map(|r| r + self.offset_m).collect()
    }
}

/// The correlation profile: circular over the period (the record extended by its own start).
fn correlation_profile(
    profiler: &mut CorrelationProfiler,
    lags: usize,
    extended: &mut Vec<Complex64>,
    rx: &[Complex64],
    place: Placement,
) -> Result<RangeResult, MeasureError> {
    extended.clear();
    extended.extend_from_slice(rx);
    extended.extend_from_slice(&rx[..lags - 1]);
    let axis = profiler.axis();
    let z: Vec<Complex64> = profiler
        .complex_profile(extended)?
        .iter()
        .map(|v| v * place.scale)
        .collect();
    let p = Profile {
        label: "correlation".into(),
        axis: Axis {
            start: axis.start + place.offset_m,
            step: axis.step,
        },
        amplitude: z.iter().map(|v| v.norm()).collect(),
    };
    Ok(RangeResult {
        profiles: vec![p],
        estimates_m: None,
        complex: Some(z),
    })
}

/// [`PeriodicDecimator::new`], its filter's taps kept in the cache on disk (keyed by the
/// design's specification).
fn decimator(
    capture_rate_hz: f64,
    factor: usize,
    band_edge_hz: f64,
) -> Result<PeriodicDecimator, MeasureError> {
    use crate::storage::cache;
    const KIND: &str = "decimator-taps-v1";
    let config = DecimatorConfig::for_band(capture_rate_hz, factor, band_edge_hz)?;
    let s = &config.spec;
    let key = cache::Key::new(KIND).u64(config.factor as u64).f64s(&[
        s.pass_edge,
        s.stop_edge,
        s.stop_atten_db,
        s.pass_ripple_db,
    ]);
    let taps = cache::get_or_build(
        KIND,
        key,
        |taps: &Vec<f64>| cache::f64s_to_bytes(taps),
        cache::f64s_from_bytes,
        || PeriodicDecimator::design(&config),
    )?;
    Ok(PeriodicDecimator::from_design(&config, taps)?)
}

/// The point spread of a correlation profile: the echo spectrum weighted by the decimator's pass
/// band, tabulated over `span` lags; kept in the cache on disk, keyed by what the echo spectrum
/// is made from (the reference and the filter: the same build makes the same spectrum from them,
/// and the build is in every key), the decimator's taps and the span. The spectrum itself (two
/// FFTs) is made only when the piece is built.
fn detector_psf(
    echo: &EchoInputs,
    decimator: Option<&PeriodicDecimator>,
    span: usize,
) -> Result<TabulatedPsf, MeasureError> {
    use crate::storage::cache;
    cache::get_or_build(
        PSF_KIND,
        psf_key(echo, decimator, span),
        TabulatedPsf::to_bytes,
        TabulatedPsf::from_bytes,
        || {
            let mut spectrum = echo_spectrum(&echo.reference, echo.filter());
            if let Some(dec) = decimator {
                let gains = dec.response_at_output_bins(spectrum.len());
                for (v, g) in spectrum.iter_mut().zip(gains) {
                    *v *= g;
                }
            }
            Ok::<_, MeasureError>(TabulatedPsf::from_dft_spectrum(&spectrum, span)?)
        },
    )
}

/// The kind (name and format) of [`detector_psf`]'s cached pieces.
const PSF_KIND: &str = "correlation-psf-v2";

/// What [`detector_psf`]'s piece depends on: the reference, the filter (or that it is the
/// reference), the decimator's factor and taps, and the span.
fn psf_key(
    echo: &EchoInputs,
    decimator: Option<&PeriodicDecimator>,
    span: usize,
) -> crate::storage::cache::Key {
    use crate::storage::cache;
    let samples = |key: cache::Key, x: &[Complex64]| {
        let mut key = key.u64(x.len() as u64);
        let mut bytes = Vec::with_capacity(4096 * 16);
        for chunk in x.chunks(4096) {
            bytes.clear();
            bytes.extend(chunk.iter().flat_map(|z| {
                let (re, im) = (z.re.to_le_bytes(), z.im.to_le_bytes());
                re.into_iter().chain(im)
            }));
            key = key.bytes(&bytes);
        }
        key
    };
    let mut key = samples(cache::Key::new(PSF_KIND).u64(span as u64), &echo.reference);
    key = match &echo.filter {
        Some(filter) => samples(key.u64(1), filter),
        None => key.u64(0),
    };
    match decimator {
        Some(dec) => key.u64(dec.factor() as u64).f64s(dec.taps()),
        None => key.u64(0),
    }
}

/// The configured pipeline (see the module docs).
pub struct Pipeline {
    tx: Arc<Transmission>,
    options: ProcessOptions,
    geometry: RecordGeometry,
    range: RangeProcessor,
    decimator: Option<(f64, usize, PeriodicDecimator)>,
    /// The detector and the capture rate its point spread was made for.
    detector: Option<(f64, Detector)>,
    payload: PayloadDecoder,
    level_scale: f64,
    /// The receive correction (`options.correction`), made for this record's period, and what
    /// its calibration promised.
    equaliser: Option<RxEqualiser>,
    correction_check: Option<CorrectionCheck>,
    /// Each target's uncertainty and, with `--ranging phase`, its phase range.
    ranging: RangingModel,
}

/// What a calibration reached on its reference, to warn when a capture corrected with it does
/// much worse (the chain changed, or the calibration is another bench's).
#[derive(Debug, Clone)]
struct CorrectionCheck {
    path: String,
    band_hz: [f64; 2],
    sidelobe_db: Option<f64>,
    width_cm: Option<f64>,
    /// The calibration's reference was processed with the waveform's default processing (no
    /// window): its figures compare with a capture processed alike only.
    comparable: bool,
    /// The chain's discrete echoes the calibration measured: (delay s, level dB) behind every
    /// path.
    chain_echoes: Vec<(f64, f64)>,
    /// The calibration's reference as phase ranging takes it.
    anchor: Option<crate::measure::calibration::response::PhaseAnchor>,
    /// What the correction left on the calibration's reference, per window: the detector's
    /// residual floor.
    residual: Vec<crate::measure::calibration::response::ResidualSeen>,
}

/// What the calibration's correction left on its reference with `options`' window (its residual
/// profile): the detector's floor near strong targets, and phase ranging's coupling of a target
/// and its reference. `None` without a correction or a profile for this window.
fn residual_floor(
    check: Option<&CorrectionCheck>,
    options: &ProcessOptions,
) -> Option<crate::dsp::ResidualFloor> {
    check?
        .residual
        .iter()
        .find(|r| r.window == options.window.name())?
        .floor()
}

/// A corrected target's peak side-lobe may exceed the calibration's by this before a warning, dB,
/// and its -3 dB width by this, cm.
const CORRECTION_WORSE_DB: f64 = 1.5;
const CORRECTION_WIDER_CM: f64 = 0.2;

/// SNR losses of the processing, dB (positive: lost).
#[derive(Debug, Clone, Copy, Default, PartialEq, serde::Serialize)]
pub struct Losses {
    /// The window's mismatch against none (over a band of even power).
    pub window: f64,
    /// The receive correction's noise lift (absent without one).
    pub correction: Option<f64>,
}

/// The noise beside the band is taken from no higher than this fraction of the rate (the
/// decimator's response is still well above its stop band there).
const BESIDE_LIMIT: f64 = 0.35;
/// The decimator's roll-off beside the band is undone by at most this gain (20 dB).
const MAX_ROLL_OFF_GAIN: f64 = 10.0;
/// Frequencies across the band the roll-off is averaged over.
const ROLL_OFF_POINTS: usize = 32;
/// Samples per block of the frequency shift's phasor recurrence.
const PHASOR_BLOCK: usize = 4096;

/// Each target's signal-to-noise ratio from the noise power per cell (`None`: unknown).
fn set_snr(detection: &mut DetectionReport, noise_per_cell: Option<f64>) {
    for t in &mut detection.targets {
        t.snr_db = match (noise_per_cell, t.fitted) {
            (Some(noise), Some((_, a))) if a.norm_sqr() > 0.0 => {
                Some(10.0 * (a.norm_sqr() / noise).log10())
            }
            _ => None,
        };
    }
}

impl CorrectionCheck {
    fn warnings(
        &self,
        tx: &Transmission,
        strongest_sidelobe_db: Option<f64>,
        strongest_width_cm: Option<f64>,
    ) -> Vec<String> {
        let mut out = Vec::new();
        let [low, high] = tx.band_hz();
        // 2 % of slack: the band's edges are where the waveform's power is 20 dB down.
        let slack = 0.01 * tx.bandwidth_hz();
        if self.band_hz[0] > low + slack || self.band_hz[1] < high - slack {
            out.push(format!(
                "the response calibration {} covers {:.3} .. {:.3} GHz, this waveform {:.3} .. \
                 {:.3} GHz: outside it the correction is held at its edge value; calibrate with \
                 this waveform",
                self.path,
                self.band_hz[0] / 1e9,
                self.band_hz[1] / 1e9,
                low / 1e9,
                high / 1e9
            ));
        }
        if !self.comparable {
            return out;
        }
        let worse = |what: &str, now: String, then: String| {
            format!(
                "corrected, the strongest target's {what} is {now} where the calibration {} \
                 reached {then} on its reference: the chain may have changed or the calibration \
                 is another bench's (or this target is not alone); compare with --correction \
                 none and measure the response again",
                self.path
            )
        };
        if let (Some(cal), Some(now)) = (self.sidelobe_db, strongest_sidelobe_db) {
            if now > cal + CORRECTION_WORSE_DB {
                out.push(worse(
                    "peak side-lobe",
                    format!("{now:.1} dB"),
                    format!("{cal:.1} dB"),
                ));
            }
        }
        if let (Some(cal), Some(now)) = (self.width_cm, strongest_width_cm) {
            if now > cal + CORRECTION_WIDER_CM {
                out.push(worse(
                    "-3 dB width",
                    format!("{now:.2} cm"),
                    format!("{cal:.2} cm"),
                ));
            }
        }
        out
    }
}

impl std::fmt::Debug for Pipeline {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Pipeline")
            .field("waveform", &self.tx.name())
            .field("options", &self.options)
            .field("geometry", &self.geometry)
            .finish_non_exhaustive()
    }
}

/// Checks the processing options against the transmission before anything is built (and, on the
/// bench, before anything radiates).
pub(crate) fn validate(tx: &Transmission, options: &ProcessOptions) -> Result<(), MeasureError> {
    let alg = options.algorithm;
    if !alg.supports(tx.spec.kind()) {
        return Err(MeasureError::AlgorithmNeedsOfdm {
            algorithm: alg.name(),
        });
    }
    if options.zero_pad == 0 || options.zero_pad > MAX_ZERO_PAD {
        return Err(MeasureError::option(
            "zero-pad",
            options.zero_pad,
            format!("1..={MAX_ZERO_PAD} (1 = no zero-padding, 10 = the thesis)"),
        ));
    }
    if alg.is_subspace() {
        let n = tx
            .modulation
            .ofdm_frame()
            .map_or(0, |(generator, _)| generator.subcarriers());
        let m = options.music_m;
        if m < 2 || m > n {
            return Err(MeasureError::option(
                "m",
                m,
                format!("2..={n} (at most the subcarriers)"),
            ));
        }
        if let Some(p) = options.music_p {
            if p == 0 || p >= m {
                return Err(MeasureError::option("p", p, format!("1..{m} (below M)")));
            }
        }
    }
    let (lo, hi) = (options.min_range_m, options.max_range_m);
    for (name, v) in [("min-range", lo), ("max-range", hi)] {
        if !(v.is_finite() && (0.0..=1e4).contains(&v)) {
            return Err(MeasureError::option(
                name,
                format!("{v:?}"),
                "a finite range in metres, 0 ..= 10000",
            ));
        }
    }
    if lo >= hi {
        return Err(MeasureError::option(
            "min-range/max-range",
            format!("{lo}/{hi}"),
            "min below max",
        ));
    }
    if !(options.pfa > 0.0 && options.pfa < 0.1) {
        return Err(MeasureError::option(
            "pfa",
            options.pfa,
            "a false-alarm probability above 0 and below 0.1 (1e-6 by default)",
        ));
    }
    if let Some(sep) = options.min_separation_m {
        if !(sep.is_finite() && (0.0..=100.0).contains(&sep)) {
            return Err(MeasureError::option(
                "min-separation",
                sep,
                "a distance in metres, 0 to 100 (targets closer than this are reported as one)",
            ));
        }
    }
    if !options.system_delay_s.is_finite() || options.system_delay_s.abs() > 1e-6 {
        return Err(MeasureError::option(
            "system_delay_s",
            options.system_delay_s,
            "a delay within +-1 us (measure it with `radbench calibrate`)",
        ));
    }
    if let Some(vpp) = options.awg_amplitude_vpp {
        if !(vpp.is_finite() && vpp > 0.0) {
            return Err(MeasureError::option(
                "awg_amplitude_vpp",
                vpp,
                "a positive amplitude in volts",
            ));
        }
    }
    Ok(())
}

/// The equaliser of a correction, from the calibration its command loaded and checked (the
/// pipeline reads no file).
fn equaliser_for(
    used: &crate::measure::calibration::correction::CorrectionUsed,
    period: usize,
    fs: f64,
) -> Result<(Option<RxEqualiser>, CorrectionCheck), MeasureError> {
    use crate::measure::calibration::response::CorrectionMode;
    if used.mode == CorrectionMode::None {
        return Err(MeasureError::option(
            "correction",
            used.mode,
            "rx, tx or both with a calibration (none names none)",
        ));
    }
    let cal = used.loaded()?;
    let check = CorrectionCheck {
        path: used.calibration.clone(),
        band_hz: cal.header.band_hz,
        sidelobe_db: cal.header.reference.sidelobe_db_after,
        width_cm: cal.header.reference.width_cm_after,
        comparable: false,
        chain_echoes: cal
            .header
            .chain_echoes
            .iter()
            .map(|e| (e.delay_ns * 1e-9, e.level_db))
            .collect(),
        anchor: cal.header.reference.phase_anchor,
        residual: cal.header.residual.clone(),
    };
    let equaliser = match used.mode {
        CorrectionMode::Rx => Some(cal.response.equaliser(period, fs)?),
        // The transmitter's codes carry the response's inverse: the receiver takes out only its
        // own DC and I/Q imbalance.
        CorrectionMode::Both => Some(cal.response.receiver_only(period, fs)?),
        CorrectionMode::Tx | CorrectionMode::None => None,
    };
    Ok((equaliser, check))
}

impl Pipeline {
    /// Sets the receive equaliser directly (a calibration checking its own correction before
    /// it is stored); `options.correction` is left as it is.
    pub(crate) fn set_equaliser(&mut self, equaliser: Option<RxEqualiser>) {
        self.equaliser = equaliser;
    }

    /// Builds every plan and workspace for `tx` processed with `options` on records of
    /// `geometry`. Fails on options that do not fit the transmission (named, with what is
    /// allowed).
    pub fn new(
        tx: Arc<Transmission>,
        options: ProcessOptions,
        geometry: RecordGeometry,
    ) -> Result<Pipeline, MeasureError> {
        validate(&tx, &options)?;
        if geometry.period < tx.len() {
            return Err(MeasureError::RecordShorterThanWaveform {
                period: geometry.period,
                waveform: tx.len(),
            });
        }
        // The payload decoder's tables are built on a thread of their own meanwhile (they
        // depend on the transmission alone; an error is reported after the range processor's).
        let (range, payload) = std::thread::scope(|scope| {
            let payload = scope.spawn(|| PayloadDecoder::new(&tx, geometry.period));
            // Correlation takes every family; the other algorithms divide by an OFDM frame's
            // symbols.
            let range = match (options.algorithm, tx.modulation.ofdm_frame()) {
                (Algorithm::Correlation, _) => {
                    RangeProcessor::correlation(&tx, &options, &geometry)
                }
                (_, Some((generator, symbols))) => {
                    OfdmProcessor::new(&tx, generator, symbols, &options)
                        .map(|o| RangeProcessor::Ofdm(Box::new(o)))
                }
                (alg, None) => Err(MeasureError::AlgorithmNeedsOfdm {
                    algorithm: alg.name(),
                }),
            };
            let payload = payload
                .join()
                .unwrap_or_else(|panic| std::panic::resume_unwind(panic));
            (range, payload)
        });
        let range = range?;
        let payload = payload?;
        let (equaliser, correction_check) = match &options.correction {
            Some(used) => {
                let (eq, mut check) = equaliser_for(used, geometry.period, tx.sample_rate_hz())?;
                let default = ProcessOptions::for_waveform(tx.spec.kind());
                check.comparable = options.window == default.window
                    && options.algorithm == default.algorithm
                    && options.zero_pad == default.zero_pad;
                (eq, Some(check))
            }
            None => (None, None),
        };
        let band = band_shape(&tx, &options, geometry.period);
        let ranging = RangingModel::new(
            &options,
            band,
            correction_check.as_ref().and_then(|c| c.anchor),
            residual_floor(correction_check.as_ref(), &options),
        );
        Ok(Pipeline {
            ranging,
            equaliser,
            correction_check,
            level_scale: level_scale(&options),
            tx,
            options,
            geometry,
            range,
            decimator: None,
            detector: None,
            payload,
        })
    }

    /// Builds (or keeps) the detector for captures at `capture_rate_hz`: its point spread
    /// includes the decimator's pass band, so a fitted target leaves only noise behind.
    fn prepare_detector(&mut self, capture_rate_hz: f64) -> Result<(), MeasureError> {
        if matches!(&self.detector, Some((rate, _)) if *rate == capture_rate_hz) {
            return Ok(());
        }
        let mut options = detect::detect_options(&self.options);
        // Where the calibration measured what its correction leaves on its reference with this
        // window, the detector's floor near strong targets follows it.
        options.residual_floor = residual_floor(self.correction_check.as_ref(), &self.options);
        let detector = match &self.range {
            RangeProcessor::Correlation { echo, lags, .. } => {
                let decimator = self.decimator.as_ref().map(|(_, _, dec)| dec);
                let span = (*lags + 16).min(echo.reference.len() / 2 - 1);
                Detector::new(detector_psf(echo, decimator, span)?, options)?
            }
            RangeProcessor::Ofdm(o) => {
                if o.music.is_some() {
                    return Ok(());
                }
                let zero_pad = self.options.zero_pad;
                let lines = SpectralLines::ofdm(zero_pad, o.radar.normalised_window())?;
                let period = zero_pad * o.radar.config().subcarriers;
                Detector::new(TabulatedPsf::from_lines(&lines, Some(period))?, options)?
            }
        };
        self.detector = Some((capture_rate_hz, detector));
        Ok(())
    }

    /// The phase anchor of a calibration's corrected reference record `processed` (the
    /// reference at `reference_range_m` against the leakage, or where there is none the
    /// reflector named at `reflector_m`), `None` where either is missing.
    pub(crate) fn phase_anchor(
        &self,
        processed: &Processed,
        reference_range_m: f64,
        reflector_m: Option<f64>,
    ) -> Option<crate::measure::calibration::response::PhaseAnchor> {
        // The noise per cell the targets' SNR was measured against.
        let noise = processed.detection.targets.iter().find_map(|t| {
            let (_, a) = t.fitted?;
            Some(a.norm_sqr() / 10f64.powf(t.snr_db? / 10.0))
        });
        self.ranging
            .anchor_of(&processed.detection, noise, reference_range_m, reflector_m)
    }

    pub fn options(&self) -> &ProcessOptions {
        &self.options
    }

    pub fn transmission(&self) -> &Arc<Transmission> {
        &self.tx
    }

    pub fn geometry(&self) -> RecordGeometry {
        self.geometry
    }

    /// Profile amplitude per volt at the scope: 1 / (volts of a unit-gain echo per unit of the
    /// reference).
    pub(crate) fn level_scale(&self) -> f64 {
        self.level_scale
    }

    /// A campaign's previous step for the records processed next (empty: none), for
    /// `--ranging phase`'s unwrapping (`ranging::Previous`).
    pub(crate) fn set_previous_step(&mut self, previous: Vec<super::ranging::Previous>) {
        self.ranging.set_previous(previous);
    }

    /// The calibration's record as the step before a campaign's first, for targets set at `set`
    /// (`ranging::RangingModel::calibration_as_previous`).
    pub(crate) fn calibration_as_previous(&self, set: &[f64]) -> Vec<super::ranging::Previous> {
        self.ranging.calibration_as_previous(set)
    }

    /// Sets the AWG amplitude the levels refer to (what the AWG reported applying).
    pub(crate) fn set_awg_amplitude(&mut self, vpp: f64) -> Result<(), MeasureError> {
        let mut options = self.options.clone();
        options.awg_amplitude_vpp = Some(vpp);
        validate(&self.tx, &options)?;
        self.options = options;
        self.level_scale = level_scale(&self.options);
        Ok(())
    }

    /// The integer factor from the capture rate to the waveform rate.
    fn factor(&self, capture_rate_hz: f64) -> Result<usize, MeasureError> {
        let fs = self.tx.sample_rate_hz();
        let ratio = capture_rate_hz / fs;
        let factor = ratio.round();
        if !(factor >= 1.0 && (ratio - factor).abs() <= 1e-6 * ratio) {
            return Err(MeasureError::RateNotMultiple {
                capture_hz: capture_rate_hz,
                waveform_hz: fs,
            });
        }
        Ok(factor as usize)
    }

    /// Builds (or keeps) the decimator for captures at `capture_rate_hz`.
    pub(crate) fn prepare_capture_rate(
        &mut self,
        capture_rate_hz: f64,
    ) -> Result<(), MeasureError> {
        let factor = self.factor(capture_rate_hz)?;
        if factor == 1 {
            self.decimator = None;
            return self.prepare_detector(capture_rate_hz);
        }
        if let Some((rate, f, _)) = &self.decimator {
            if *rate == capture_rate_hz && *f == factor {
                return Ok(());
            }
        }
        // The pass band is a little wider than the signal's: MSK-LFM's skirts pass unharmed.
        let edge = self.tx.spec.band_edge_hz() + 0.05 * self.tx.bandwidth_hz();
        let dec = decimator(capture_rate_hz, factor, edge)?;
        self.decimator = Some((capture_rate_hz, factor, dec));
        self.prepare_detector(capture_rate_hz)
    }

    /// Decimates one repetition of `raw` to the waveform rate and rotates it to the marker edge.
    pub fn align(&mut self, raw: &RawIq) -> Result<Aligned, MeasureError> {
        let x = &raw.samples;
        self.align_map(x.len(), raw.sample_rate_hz, raw.first_point_s, |k| x[k])
    }

    /// [`align`](Self::align) of the scope's words, converted to volts as they are read (the
    /// same arithmetic as `measure::station::Captured::raw`, so the same result).
    pub(crate) fn align_words(&mut self, raw: &RawWords) -> Result<Aligned, MeasureError> {
        let words = ScaledWords {
            i: &raw.i,
            q: &raw.q,
            gain: raw.gain,
            offset: raw.offset,
        };
        self.align_map(
            raw.i.len().min(raw.q.len()),
            raw.sample_rate_hz,
            raw.first_point_s,
            words,
        )
    }

    fn align_map(
        &mut self,
        len: usize,
        sample_rate_hz: f64,
        first_point_s: f64,
        sample: impl Samples,
    ) -> Result<Aligned, MeasureError> {
        let factor = self.factor(sample_rate_hz)?;
        let period = self.geometry.period;
        let needed = period * factor;
        if len < needed {
            return Err(MeasureError::RecordTooShort {
                points: len,
                needed,
            });
        }
        self.prepare_capture_rate(sample_rate_hz)?;
        // Rotate so sample m sits at m / fs after the marker edge, up to a sub-sample residual.
        let fs = self.tx.sample_rate_hz();
        let shift = (first_point_s * fs).round();
        let residual_s = first_point_s - shift / fs;
        let s = (shift as i64).rem_euclid(period as i64) as usize;
        let samples = match self.decimator.as_mut() {
            None => {
                let y: Vec<Complex64> = (0..needed).map(|k| sample.at(k)).collect();
                let mut samples = vec![ZERO; period];
                let (head, tail) = y.split_at(period - s);
                samples[s..].copy_from_slice(head);
                samples[..s].copy_from_slice(tail);
                samples
            }
            // Decimated straight into place.
            Some((_, _, dec)) => dec.decimate_map_rotated(needed, sample, s),
        };
        Ok(Aligned {
            samples,
            residual_s,
        })
    }

    /// The range profiles of one aligned repetition; `offset_m` is added to every range.
    pub(crate) fn range_profiles(
        &mut self,
        rx: &[Complex64],
        offset_m: f64,
    ) -> Result<RangeResult, MeasureError> {
        if rx.len() != self.geometry.period {
            return Err(MeasureError::RecordTooShort {
                points: rx.len(),
                needed: self.geometry.period,
            });
        }
        let place = Placement {
            scale: self.level_scale,
            offset_m,
        };
        match &mut self.range {
            RangeProcessor::Correlation {
                profiler,
                lags,
                extended,
                ..
            } => correlation_profile(profiler, *lags, extended, rx, place),
            RangeProcessor::Ofdm(o) => o.profiles(rx, &self.options, place),
        }
    }

    /// Radial velocities of the detections from the last record's slow time (OFDM frames).
    fn velocities(
        &mut self,
        detection: &mut DetectionReport,
        offset_m: f64,
    ) -> Result<(), MeasureError> {
        let RangeProcessor::Ofdm(o) = &mut self.range else {
            return Ok(());
        };
        let Some(estimator) = &mut o.velocity else {
            return Ok(());
        };
        let k_len = o.radar.config().profile_len();
        let bin = o.radar.config().range_bin_m();
        for t in &mut detection.targets {
            let x = (t.range_m - offset_m) / bin;
            t.velocity_mps =
                Some(estimator.estimate(&o.idiv, o.radar.normalised_window(), x, k_len)?);
        }
        detection.velocity_resolution_mps = Some(estimator.resolution_mps());
        Ok(())
    }

    /// The range-Doppler map of the last record (OFDM frames of 2+ symbols), ranges from the
    /// antennas, amplitudes relative to a unit-gain path.
    pub(crate) fn range_doppler_map(
        &self,
        residual_s: f64,
    ) -> Option<Result<RangeDopplerMap, MeasureError>> {
        let RangeProcessor::Ofdm(o) = &self.range else {
            return None;
        };
        if o.idiv.symbols() < 2 {
            return None;
        }
        let offset = self.offset_m(residual_s);
        let scale = self.level_scale / o.unit;
        Some((|| {
            let mut rd = RangeDoppler::new(
                o.radar.config(),
                o.idiv.symbols(),
                &RangeDopplerConfig {
                    carrier_hz: self.options.carrier_hz,
                    doppler_bins: Some((4 * o.idiv.symbols()).next_power_of_two()),
                    ..RangeDopplerConfig::default()
                },
            )?;
            let mut map = RangeDopplerMap::default();
            rd.process(&o.idiv, &mut map)?;
            for r in &mut map.range_m {
                *r += offset;
            }
            for a in &mut map.amplitude {
                *a *= scale;
            }
            Ok(map)
        })())
    }

    /// The record's content beside the waveform's band, moved into it: what lay
    /// [`Pipeline::beside_shift_hz`] below the band (clear of the band and of its I/Q image) is
    /// the receiver's noise alone. The decimator's roll-off there is undone, so the noise is as
    /// strong as inside the band. `None` when the record has no room beside the band.
    fn noise_beside_band(&self, samples: &[Complex64]) -> Option<Vec<Complex64>> {
        let n = samples.len();
        let fs = self.tx.sample_rate_hz();
        let shift_hz = self.beside_shift_hz();
        let edge = self.tx.spec.band_edge_hz();
        if n < 16 || shift_hz + edge > BESIDE_LIMIT * fs {
            return None;
        }
        // A whole number of cycles over the record, so the shift stays circular.
        let shift = ((shift_hz / fs * n as f64).round()).max(1.0);
        let step = 2.0 * std::f64::consts::PI * shift / n as f64;
        // The decimator's roll-off where the noise came from against where it lands, as one
        // power ratio over the band (the roll-off is gentle there: a ratio per bin would cost
        // two filter responses per bin for a fraction of a dB).
        let gain = self.decimator.as_ref().map_or(1.0, |(_, _, d)| {
            let [lo, hi] = self.tx.band_hz();
            let (mut here, mut there) = (0.0, 0.0);
            for j in 0..ROLL_OFF_POINTS {
                let f = lo + (hi - lo) * (j as f64 + 0.5) / ROLL_OFF_POINTS as f64;
                here += d.response_at_output(f / fs).powi(2);
                there += d
                    .response_at_output((f - shift * fs / n as f64) / fs)
                    .powi(2);
            }
            if there > 0.0 {
                (here / there).sqrt().min(MAX_ROLL_OFF_GAIN)
            } else {
                0.0
            }
        });
        // The phasor by recurrence, anchored afresh every block against rounding.
        let mut moved = Vec::with_capacity(n);
        let turn = Complex64::from_polar(1.0, step);
        for (b, block) in samples.chunks(PHASOR_BLOCK).enumerate() {
            let mut phasor = Complex64::from_polar(gain, step * (b * PHASOR_BLOCK) as f64);
            for v in block {
                moved.push(v * phasor);
                phasor *= turn;
            }
        }
        Some(moved)
    }

    /// How far below the band the noise is taken from, Hz: past the band's lowest edge and its
    /// I/Q image, with a quarter band to spare.
    fn beside_shift_hz(&self) -> f64 {
        2.0 * self.tx.spec.band_edge_hz() + 0.25 * self.tx.bandwidth_hz()
    }

    /// The mean noise power per cell of the primary profile of a noise-only record (`None` for
    /// the algorithms without a complex profile).
    fn noise_per_cell(
        &mut self,
        noise: &[Complex64],
        residual_s: f64,
    ) -> Result<Option<f64>, MeasureError> {
        let range = self.range_profiles(noise, self.offset_m(residual_s))?;
        let Some(z) = range.complex else {
            return Ok(None);
        };
        let mut power: Vec<f64> = z.iter().map(|v| v.norm_sqr()).collect();
        if power.is_empty() {
            return Ok(None);
        }
        let mid = power.len() / 2;
        let median = *power.select_nth_unstable_by(mid, f64::total_cmp).1;
        // The median of an exponential (complex Gaussian noise's power) is ln 2 of its mean.
        Ok(Some(median / std::f64::consts::LN_2).filter(|p| *p > 0.0))
    }

    /// Range offset of an aligned record: the residual after the trigger minus the system delay.
    pub(crate) fn offset_m(&self, residual_s: f64) -> f64 {
        (residual_s - self.options.system_delay_s) * C0 / 2.0
    }

    /// Range profiles and detections of one aligned record.
    pub(crate) fn analyse(&mut self, aligned: &Aligned) -> Result<Analysis, MeasureError> {
        let offset = self.offset_m(aligned.residual_s);
        let range = self.range_profiles(&aligned.samples, offset)?;
        let detector = match range.complex {
            Some(_) => {
                if self.detector.is_none() {
                    // Records at the waveform rate (no decimation).
                    self.prepare_detector(self.tx.sample_rate_hz())?;
                }
                self.detector.as_mut().map(|(_, d)| d)
            }
            None => None,
        };
        let mut detection = detect::detect(&range, &self.options, detector)?;
        self.velocities(&mut detection, offset)?;
        Ok(Analysis { range, detection })
    }

    /// Processes one aligned repetition; `background` (aligned the same way) is subtracted first.
    pub fn process(
        &mut self,
        aligned: Aligned,
        background: Option<&Aligned>,
    ) -> Result<Processed, MeasureError> {
        self.process_clipped(aligned, background, None)
    }

    /// [`process`](Self::process) of a record whose samples at the ADC's rails were counted:
    /// when some clipped, detection is made conservative (`measure::clipping`) and a warning
    /// says what to change.
    pub(crate) fn process_clipped(
        &mut self,
        aligned: Aligned,
        background: Option<&Aligned>,
        clipped: Option<&RecordClipping>,
    ) -> Result<Processed, MeasureError> {
        let mut aligned = aligned;
        if let Some(bg) = background {
            if bg.samples.len() != aligned.samples.len() {
                return Err(MeasureError::BackgroundShape {
                    background: bg.samples.len(),
                    capture: aligned.samples.len(),
                });
            }
            for (a, b) in aligned.samples.iter_mut().zip(&bg.samples) {
                *a -= b;
            }
        }
        // The noise beside the band, taken before the correction (which then treats it as it
        // treats the band's own noise).
        let mut beside = self.noise_beside_band(&aligned.samples);
        if let Some(eq) = &mut self.equaliser {
            // The measured response holds the decimator's pass band, and so does the point spread
            // CLEAN subtracts: the correction leaves it in the record.
            if let Some((_, _, dec)) = &self.decimator {
                eq.keep_filter(|n| dec.response_at_output_bins(n));
            }
            // A subtracted background took the DC with it.
            eq.apply(&mut aligned.samples, background.is_none())?;
            if let Some(noise) = beside.as_mut() {
                eq.apply(noise, background.is_none())?;
            }
        }
        let analysis = self.analyse(&aligned)?;
        let Analysis {
            range,
            mut detection,
        } = analysis;
        // Before the clipping model runs through the range processing (it reuses its state).
        let range_doppler = self.range_doppler_map(aligned.residual_s).transpose()?;
        let mut warnings = Vec::new();
        let clipping = match clipped {
            Some(c) if c.count.any() => {
                let (conservative, warning) = clipping::mitigate(
                    self,
                    &aligned.samples,
                    aligned.residual_s,
                    &mut detection,
                    c,
                )?;
                warnings.push(warning);
                Some(Clipping::of(&c.count, conservative))
            }
            Some(c) => Some(Clipping::of(&c.count, None)),
            None => None,
        };
        let primary = range.primary();
        if let Some(check) = &self.correction_check {
            detect::flag_chain_echoes(&mut detection, &check.chain_echoes);
            for e in &detection.chain_echoes {
                warnings.push(format!(
                    "the echo at {:.4} m is taken for the chain's: it lies {:.1} ns behind the \
                     target at {:.4} m, where the calibration measured an echo of every path at \
                     {:.1} dB (listed in chain_echoes, not in targets)",
                    e.detection.range_m, e.echo_delay_ns, e.of_range_m, e.echo_level_db
                ));
            }
        }
        let per_cell = match beside {
            Some(noise) => self.noise_per_cell(&noise, aligned.residual_s)?,
            None => None,
        };
        if per_cell.is_some() {
            set_snr(&mut detection, per_cell);
        }
        warnings.extend(self.ranging.apply(&mut detection, per_cell));
        let strongest = detection.strongest.map(|i| &detection.targets[i]);
        let width_3db_cm = strongest.and_then(|t| t.width_3db_cm);
        let sidelobe_db = strongest.and_then(|t| t.sidelobe_db);
        let snr_db = strongest.and_then(|t| t.snr_db);
        let peak_to_floor_db = strongest.and_then(|t| t.peak_to_floor_db);
        if detection.targets.is_empty() {
            warnings.push(detect::no_target_hint(&aligned.samples, primary));
        }
        if let Some(check) = &self.correction_check {
            warnings.extend(check.warnings(&self.tx, sidelobe_db, width_3db_cm));
        }
        if detection.capped {
            warnings.push(
                "the detector stopped at its most targets: there may be more echoes than listed"
                    .into(),
            );
        }
        let lag = strongest.and_then(|t| t.cell);
        let payload = self.payload.decode(&aligned.samples, &self.tx, lag);
        if let Some(p) = payload
            .as_ref()
            .filter(|p| p.bits > 0 && p.ber > BER_WARNING)
        {
            let moving = strongest
                .and_then(|t| t.velocity_mps)
                .filter(|v| v.abs() > 1.0)
                .map(|v| {
                    format!(
                        "; the strongest target moves at {v:+.1} m/s, and its Doppler shift \
                         spoils the decoding, which assumes a still reflector"
                    )
                })
                .unwrap_or_default();
            warnings.push(format!(
                "the data did not decode: BER {:.1e} ({} of {} bits wrong){moving}",
                p.ber, p.bit_errors, p.bits
            ));
        }
        Ok(Processed {
            profiles: range.profiles,
            complex_profile: range.complex,
            targets: detection.targets.clone(),
            width_3db_cm,
            sidelobe_db,
            snr_db,
            peak_to_floor_db,
            losses_db: Losses {
                window: self.options.window.to_dsp().mismatch_loss_db(),
                correction: self.equaliser.as_ref().map(|e| e.snr_loss_db()),
            },
            payload,
            detection,
            range_doppler,
            warnings,
            clipping,
            aligned: aligned.samples,
        })
    }
}

/// The clipping model runs its modelled records through this pipeline's own range processing.
impl clipping::RangeProcessing for Pipeline {
    fn transmission(&self) -> &Arc<Transmission> {
        Pipeline::transmission(self)
    }
    fn period(&self) -> usize {
        self.geometry.period
    }
    fn level_scale(&self) -> f64 {
        Pipeline::level_scale(self)
    }
    fn offset_m(&self, residual_s: f64) -> f64 {
        Pipeline::offset_m(self, residual_s)
    }
    fn range_profiles(
        &mut self,
        samples: &[Complex64],
        offset_m: f64,
    ) -> Result<RangeResult, MeasureError> {
        Pipeline::range_profiles(self, samples, offset_m)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::measure::processing::transmit::Dac;
    use crate::measure::WindowName;
    use crate::waveform::WaveformSpec;

    fn tx(spec: WaveformSpec) -> Arc<Transmission> {
        Arc::new(Transmission::new(&spec, None, 1, Dac::default()).unwrap())
    }

    #[test]
    fn the_point_spreads_key_follows_the_reference_the_filter_and_the_span() {
        let reference: Vec<Complex64> = (0..5000)
            .map(|k| Complex64::from_polar(1.0, 1e-4 * (k * k) as f64))
            .collect();
        let echo = |reference: &[Complex64], filter: Option<Vec<Complex64>>| EchoInputs {
            reference: reference.to_vec(),
            filter,
        };
        let key = |e: &EchoInputs, span: usize| psf_key(e, None, span).digest();
        let rect = key(&echo(&reference, None), 100);
        assert_eq!(rect, key(&echo(&reference, None), 100));
        // The same values as a filter of their own are another key (never mistaken for the
        // reference standing in for itself), as is a filter that differs in one sample.
        assert_ne!(rect, key(&echo(&reference, Some(reference.clone())), 100));
        let mut weighted = reference.clone();
        weighted[2500] *= 0.5;
        let a = key(&echo(&reference, Some(weighted.clone())), 100);
        weighted[2500] *= 0.5;
        assert_ne!(a, key(&echo(&reference, Some(weighted)), 100));
        let mut other = reference.clone();
        other[4999].im = -other[4999].im;
        assert_ne!(rect, key(&echo(&other, None), 100));
        assert_ne!(rect, key(&echo(&reference[..4999], None), 100));
        assert_ne!(rect, key(&echo(&reference, None), 101));
    }

    fn geometry(tx: &Transmission) -> RecordGeometry {
        RecordGeometry::for_capture(tx.len(), tx.sample_rate_hz(), &ProcessOptions::default())
    }

    #[test]
    fn options_that_do_not_fit_are_refused_with_the_option_named() {
        let msk = tx(WaveformSpec::msk_lfm_default());
        let music = ProcessOptions {
            algorithm: Algorithm::Music,
            ..ProcessOptions::default()
        };
        let err = Pipeline::new(msk.clone(), music, geometry(&msk)).unwrap_err();
        assert!(
            matches!(err, MeasureError::AlgorithmNeedsOfdm { .. }),
            "{err}"
        );
        let ofdm = tx(WaveformSpec::ofdm_default());
        for (options, named) in [
            (
                ProcessOptions {
                    algorithm: Algorithm::Music,
                    music_m: 200,
                    ..ProcessOptions::default()
                },
                "--m 200",
            ),
            (
                ProcessOptions {
                    algorithm: Algorithm::Esprit,
                    music_p: Some(64),
                    ..ProcessOptions::default()
                },
                "--p 64",
            ),
            (
                ProcessOptions {
                    algorithm: Algorithm::Fourier,
                    zero_pad: 0,
                    ..ProcessOptions::default()
                },
                "--zero-pad 0",
            ),
            (
                ProcessOptions {
                    pfa: 0.5,
                    ..ProcessOptions::default()
                },
                "--pfa 0.5",
            ),
        ] {
            let err = Pipeline::new(ofdm.clone(), options, geometry(&ofdm))
                .unwrap_err()
                .to_string();
            assert!(err.starts_with(named), "{err}");
        }
    }

    /// A noise-free echo of the transmitted codes through a path of unit voltage gain, delayed by
    /// whole samples, at the waveform rate.
    fn unit_echo(tx: &Transmission, delay: usize, vpp: f64) -> RawIq {
        let volts = 127.0 * vpp / 255.0;
        let n = tx.len();
        let samples = (0..n)
            .map(|k| tx.reference[(k + n - delay) % n] * volts)
            .collect();
        RawIq {
            samples,
            sample_rate_hz: tx.sample_rate_hz(),
            first_point_s: 0.0,
        }
    }

    #[test]
    fn a_unit_gain_echo_is_reported_at_0_db_and_its_range() {
        for spec in [
            WaveformSpec::msk_lfm_default(),
            WaveformSpec::ofdm_default(),
        ] {
            let tx = tx(spec);
            let options = ProcessOptions::for_waveform(spec.kind());
            let mut p = Pipeline::new(tx.clone(), options, geometry(&tx)).unwrap();
            p.set_awg_amplitude(0.5).unwrap();
            let delay = 107; // 1.0028 m at 16 GSa/s
            let aligned = p.align(&unit_echo(&tx, delay, 0.5)).unwrap();
            let out = p.process(aligned, None).unwrap();
            assert_eq!(out.targets.len(), 1, "{}: {:?}", spec.name(), out.targets);
            let expect = delay as f64 * C0 / (2.0 * 16e9);
            assert!(
                (out.targets[0].range_m - expect).abs() < 1e-4,
                "{:?}",
                out.targets
            );
            assert!(out.targets[0].level_db.abs() < 0.05, "{:?}", out.targets);
            assert_eq!(out.payload.as_ref().unwrap().bit_errors, 0);
        }
    }

    #[test]
    fn a_window_on_the_matched_filter_lowers_the_side_lobes() {
        let tx = tx(WaveformSpec::msk_lfm_default());
        let psl = |window: WindowName| {
            let options = ProcessOptions {
                window,
                ..ProcessOptions::default()
            };
            let mut p = Pipeline::new(tx.clone(), options, geometry(&tx)).unwrap();
            let aligned = p.align(&unit_echo(&tx, 300, 0.5)).unwrap();
            let out = p.process(aligned, None).unwrap();
            (out.sidelobe_db.unwrap(), out.width_3db_cm.unwrap())
        };
        let (rect_psl, rect_width) = psl(WindowName::Rect);
        let (hann_psl, hann_width) = psl(WindowName::Hann);
        assert!(rect_psl > -14.0 && rect_psl < -12.5, "{rect_psl}");
        assert!(
            hann_psl < rect_psl - 10.0,
            "Hann {hann_psl} dB vs rect {rect_psl} dB"
        );
        assert!(
            hann_width > 1.4 * rect_width,
            "{hann_width} vs {rect_width}"
        );
    }

    #[test]
    fn alignment_rotates_to_the_marker_edge_and_keeps_the_residual() {
        let tx = tx(WaveformSpec::ofdm_default());
        let options = ProcessOptions::for_waveform(tx.spec.kind());
        let mut p = Pipeline::new(tx.clone(), options, geometry(&tx)).unwrap();
        let mut raw = unit_echo(&tx, 0, 0.5);
        // The record starts 10.25 samples after the marker edge.
        let fs = tx.sample_rate_hz();
        raw.first_point_s = 10.25 / fs;
        let aligned = p.align(&raw).unwrap();
        assert!((aligned.residual_s * fs - 0.25).abs() < 1e-9);
        assert_eq!(aligned.samples[10], raw.samples[0]);
        let short = RawIq {
            samples: raw.samples[..100].to_vec(),
            ..raw
        };
        assert!(matches!(
            p.align(&short),
            Err(MeasureError::RecordTooShort { .. })
        ));
    }
}
