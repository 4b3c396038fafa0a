//! From one captured repetition to targets: decimate 80 -> 16 GSa/s, align to the marker, subtract
//! a background, compute the range profile, detect targets, measure them, decode the payload.
//!
//! The AWG loops its segment, so the received signal is periodic: one repetition captured from the
//! marker edge holds every echo (wrapped), and correlation is taken circularly over it. Ranges are
//! measured from the antennas: the time of the first sample after the trigger (the scope's
//! HORIZ_OFFSET) is added and the calibrated system delay subtracted.

use super::transmit::{Transmission, WaveformKind};
use super::MeasureError;
use crate::dsp::decimate::PeriodicDecimator;
use crate::dsp::metrics::{
    find_peaks, interpolate_peak, sidelobe_levels, width_3db, Axis, CaCfar, Interpolation,
};
use crate::dsp::music::root_music_ranges;
use crate::dsp::music::{ModelOrder, Music, MusicConfig, MusicSpectrum, OrderCriterion};
use crate::dsp::ofdm_radar::{IDiv, OfdmRadar, OfdmRadarConfig, RangeProfile};
use crate::dsp::range_profile::{music_profile, CorrelationProfiler, Profile};
use crate::dsp::C0;
use crate::processing::{Algorithm, FftPrecisionName, WindowName};
use crate::waveform::bits::{count_bit_errors, unframe_payload};
use crate::waveform::msk_lfm::MskLfm;
use crate::waveform::ofdm::{Equalisation, Ofdm};
use num_complex::Complex64;
use rustfft::FftPlanner;
use serde::Serialize;

/// How to process a capture (recorded as `processing` in summary.json and the SigMF metadata).
#[derive(Debug, Clone, Serialize)]
pub struct ProcessOptions {
    pub algorithm: Algorithm,
    /// MUSIC sub-vector length M.
    pub music_m: usize,
    /// Number of targets for MUSIC/root-MUSIC/ESPRIT; `None` = estimated (MDL).
    pub music_p: Option<usize>,
    /// OFDM Fourier zero padding.
    pub zero_pad: usize,
    pub window: WindowName,
    /// Precision of the OFDM receiver's per-symbol FFT.
    pub fft_precision: FftPrecisionName,
    /// Fixed delay of the bench (calibration), seconds.
    pub system_delay_s: f64,
    /// Detections closer than this are ignored (the direct Tx -> Rx leakage sits near 0 m).
    pub min_range_m: f64,
    /// Detections farther than this are ignored.
    pub max_range_m: f64,
    /// Probability of false alarm of the CFAR detector.
    pub pfa: f64,
    /// The AWG's I/Q amplitude (peak to peak, volts): echo levels are given relative to a path
    /// of unit voltage gain from the AWG output to the scope input.
    pub awg_amplitude_vpp: f64,
}

impl Default for ProcessOptions {
    fn default() -> Self {
        Self {
            algorithm: Algorithm::Correlation,
            music_m: 64,
            music_p: None,
            zero_pad: 10,
            window: WindowName::Rect,
            fft_precision: FftPrecisionName::Single,
            system_delay_s: 0.0,
            min_range_m: 0.15,
            max_range_m: 10.0,
            pfa: 1e-6,
            awg_amplitude_vpp: 2.0 * 127.0 / 255.0,
        }
    }
}

/// The capture in volts at the scope's rate.
#[derive(Debug, Clone)]
pub struct RawIq {
    pub samples: Vec<Complex64>,
    pub sample_rate_hz: f64,
    /// Time of the first sample after the trigger (marker edge), seconds.
    pub first_point_s: f64,
}

/// One detected target.
#[derive(Debug, Clone, Serialize)]
pub struct Detection {
    pub range_m: f64,
    /// Echo amplitude relative to a unit-gain path from AWG output to scope input, dB.
    pub level_db: f64,
    /// Height above the CFAR threshold, dB (absent for grid-free estimators).
    pub above_threshold_db: Option<f64>,
}

/// Decoded data.
#[derive(Debug, Clone, Serialize)]
pub struct PayloadResult {
    /// The payload bytes when the framing decoded.
    #[serde(skip)]
    pub bytes: Option<Vec<u8>>,
    /// The payload as text (lossy UTF-8).
    pub text: Option<String>,
    pub bit_errors: usize,
    pub bits: usize,
    pub ber: f64,
    /// Why decoding failed, if it did.
    pub error: Option<String>,
}

/// Everything the processing found.
#[derive(Debug, Clone)]
pub struct Processed {
    /// Primary profile first (MUSIC over Fourier when both), ranges from the antennas.
    pub profiles: Vec<Profile>,
    pub targets: Vec<Detection>,
    /// Main-lobe width of the strongest target, cm.
    pub width_3db_cm: Option<f64>,
    /// Peak side-lobe level around the strongest target, dB.
    pub sidelobe_db: Option<f64>,
    /// Strongest peak over the median of the profile, dB.
    pub snr_db: Option<f64>,
    pub payload: Option<PayloadResult>,
    /// Things a user should check (no target, clipping, ...).
    pub warnings: Vec<String>,
    /// The capture decimated to the waveform rate and aligned to the marker (for plots/files).
    pub aligned: Vec<Complex64>,
}

/// Side-lobe mask margin: a peak within this of the mask of a stronger target is a side-lobe.
const SIDELOBE_MARGIN_DB: f64 = 3.0;

/// Decimates and aligns a capture to the waveform rate: sample `m` of the result is at
/// `m / fs + residual_s` after the marker edge.
pub fn align(
    raw: &RawIq,
    tx: &Transmission,
    period: usize,
) -> Result<(Vec<Complex64>, f64), MeasureError> {
    let factor = (raw.sample_rate_hz / tx.sample_rate_hz).round() as usize;
    if factor == 0
        || (factor as f64 * tx.sample_rate_hz - raw.sample_rate_hz).abs()
            > 1e-6 * raw.sample_rate_hz
    {
        return Err(MeasureError::Processing(format!(
            "the scope rate {} Sa/s is not an integer multiple of the waveform rate {} Sa/s",
            raw.sample_rate_hz, tx.sample_rate_hz
        )));
    }
    let needed = period * factor;
    if raw.samples.len() < needed {
        return Err(MeasureError::Processing(format!(
            "the capture holds {} points but one repetition needs {needed}: lengthen the scope's record",
            raw.samples.len()
        )));
    }
    let one = &raw.samples[..needed];
    let y = if factor == 1 {
        one.to_vec()
    } else {
        let mut dec = PeriodicDecimator::new(raw.sample_rate_hz, factor, 0.55 * tx.bandwidth_hz)
            .map_err(|e| MeasureError::Processing(e.to_string()))?;
        dec.decimate(one)
    };
    // Rotate so sample m sits at m / fs after the marker edge, up to a sub-sample residual.
    let fs = tx.sample_rate_hz;
    let shift = (raw.first_point_s * fs).round();
    let residual = raw.first_point_s - shift / fs;
    let s = (shift as i64).rem_euclid(period as i64) as usize;
    let mut aligned = vec![Complex64::new(0.0, 0.0); period];
    for (k, v) in y.iter().enumerate() {
        aligned[(k + s) % period] = *v;
    }
    Ok((aligned, residual))
}

/// Processes one aligned repetition (see [`align`]); `background` (aligned the same way) is
/// subtracted first.
pub fn process(
    aligned: Vec<Complex64>,
    residual_s: f64,
    background: Option<&[Complex64]>,
    tx: &Transmission,
    period: usize,
    options: &ProcessOptions,
) -> Result<Processed, MeasureError> {
    let mut rx = aligned;
    if let Some(bg) = background {
        if bg.len() != rx.len() {
            return Err(MeasureError::Processing(format!(
                "the background capture holds {} samples per repetition, this one {}: capture the \
                 background with the same waveform",
                bg.len(),
                rx.len()
            )));
        }
        for (a, b) in rx.iter_mut().zip(bg) {
            *a -= b;
        }
    }
    let fs = tx.sample_rate_hz;
    // Range of a profile position = axis range + this offset.
    let offset_m = (residual_s - options.system_delay_s) * C0 / 2.0;
    // The reference in volts at the AWG output (a code c leaves the DAC as c * Vpp / 255).
    let volts_per_unit = 127.0 * options.awg_amplitude_vpp / 255.0;
    let mut reference: Vec<Complex64> = tx.reference.iter().map(|v| v * volts_per_unit).collect();
    reference.resize(period, Complex64::new(0.0, 0.0));

    let mut warnings = Vec::new();
    let (profiles, grid_free) = match (options.algorithm, tx.kind) {
        (Algorithm::Correlation, _) => {
            let max_delay =
                2.0 * options.max_range_m / C0 + options.system_delay_s.max(0.0) + 20e-9;
            let lags = ((max_delay * fs).ceil() as usize).clamp(2, period);
            let mut ext = rx.clone();
            ext.extend_from_slice(&rx[..lags - 1]);
            let mut corr = CorrelationProfiler::new(&reference, ext.len(), lags, fs)
                .map_err(|e| MeasureError::Processing(e.to_string()))?;
            let p = corr
                .profile(&ext)
                .map_err(|e| MeasureError::Processing(e.to_string()))?;
            (vec![shifted(p, offset_m)], None)
        }
        (_, WaveformKind::MskLfm) => {
            return Err(MeasureError::Param(format!(
                "--algorithm {} needs OFDM symbols; MSK-LFM uses 'correlation'",
                options.algorithm.name()
            )))
        }
        (alg, WaveformKind::Ofdm) => {
            let params = tx.ofdm.expect("an OFDM transmission keeps its parameters");
            let symbols = tx
                .symbols
                .as_ref()
                .expect("an OFDM transmission keeps its symbols");
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
            // Levels relative to a unit-gain path: the transmitted frame itself, processed alike,
            // peaks at the normalising value.
            radar.process(&reference, 0, symbols.as_slice(), &mut idiv, &mut profile)?;
            let unit = profile
                .amplitude
                .iter()
                .copied()
                .fold(0.0, f64::max)
                .max(1e-300);
            radar.process(&rx, 0, symbols.as_slice(), &mut idiv, &mut profile)?;
            let fourier = shifted(
                Profile {
                    label: format!("Fourier ({}-point IFFT)", profile.amplitude.len()),
                    axis: profile.axis(),
                    amplitude: profile.amplitude.iter().map(|a| a / unit).collect(),
                },
                offset_m,
            );
            if alg == Algorithm::Fourier {
                (vec![fourier], None)
            } else {
                let n = params.subcarriers;
                let mut music = Music::new(MusicConfig {
                    subcarriers: n,
                    subarray: options.music_m,
                    order: options
                        .music_p
                        .map(ModelOrder::Fixed)
                        .unwrap_or(ModelOrder::Estimated(OrderCriterion::Mdl)),
                    forward_backward: true,
                    grid_points: 100 * n,
                    bandwidth_hz: params.bandwidth_hz,
                })?;
                let mut spectrum = MusicSpectrum::default();
                let df = params.bandwidth_hz / n as f64;
                match alg {
                    Algorithm::Esprit => {
                        let r = music.esprit(idiv.as_slice())?;
                        (
                            vec![fourier],
                            Some(r.into_iter().map(|x| x + offset_m).collect()),
                        )
                    }
                    Algorithm::RootMusic => {
                        music.estimate(idiv.as_slice(), &mut spectrum)?;
                        let r = root_music_ranges(&music, spectrum.order, df)
                            .map_err(|e| MeasureError::Processing(e.to_string()))?;
                        (
                            vec![fourier],
                            Some(r.into_iter().map(|x| x + offset_m).collect::<Vec<f64>>()),
                        )
                    }
                    _ => {
                        music.estimate(idiv.as_slice(), &mut spectrum)?;
                        let mp = music_profile(
                            &spectrum.range_m,
                            &spectrum.pseudo_spectrum,
                            options.music_m,
                            spectrum.order,
                        );
                        let peaks: Vec<f64> =
                            spectrum.peaks_m.iter().map(|x| x + offset_m).collect();
                        (vec![shifted(mp, offset_m), fourier], Some(peaks))
                    }
                }
            }
        }
    };

    let primary = &profiles[0];
    let (mut targets, strongest) = match &grid_free {
        Some(ranges) => (
            ranges
                .iter()
                .filter(|r| (options.min_range_m..=options.max_range_m).contains(*r))
                .map(|&range_m| Detection {
                    range_m,
                    level_db: level_at(&profiles[profiles.len() - 1], range_m),
                    above_threshold_db: None,
                })
                .collect::<Vec<_>>(),
            None,
        ),
        None => detect(primary, options)?,
    };
    targets.sort_by(|a, b| a.range_m.total_cmp(&b.range_m));

    let (mut width_3db_cm, mut sidelobe_db, mut snr_db) = (None, None, None);
    if let Some(index) = strongest {
        let amp = &primary.amplitude;
        let (_, height) = interpolate_peak(amp, index, Interpolation::ParabolicDb);
        width_3db_cm = width_3db(amp, index, height).map(|w| w * primary.axis.step * 100.0);
        sidelobe_db = sidelobe_levels(amp, index, Interpolation::ParabolicDb).map(|s| s.psl_db);
        let mut sorted: Vec<f64> = amp.iter().map(|a| a * a).collect();
        sorted.sort_by(f64::total_cmp);
        let median = sorted[sorted.len() / 2].max(1e-300);
        snr_db = Some(10.0 * (height * height / median).log10());
    }
    if targets.is_empty() {
        warnings.push(no_target_hint(&rx, primary));
    }

    let payload = decode_payload(&rx, tx, period, primary, strongest);
    Ok(Processed {
        profiles,
        targets,
        width_3db_cm,
        sidelobe_db,
        snr_db,
        payload,
        warnings,
        aligned: rx,
    })
}

fn shifted(mut p: Profile, offset_m: f64) -> Profile {
    p.axis = Axis {
        start: p.axis.start + offset_m,
        step: p.axis.step,
    };
    p
}

fn level_at(p: &Profile, range_m: f64) -> f64 {
    let idx = ((range_m - p.axis.start) / p.axis.step).round();
    let i = (idx.max(0.0) as usize).min(p.amplitude.len().saturating_sub(1));
    20.0 * p
        .amplitude
        .get(i)
        .copied()
        .unwrap_or(0.0)
        .max(1e-300)
        .log10()
}

/// Peaks with >= 3 dB prominence that pass the CFAR test, lie in the range window and are not
/// side-lobes of a stronger target. Returns them and the index of the strongest.
fn detect(
    p: &Profile,
    options: &ProcessOptions,
) -> Result<(Vec<Detection>, Option<usize>), MeasureError> {
    let amp = &p.amplitude;
    let db: Vec<f64> = amp.iter().map(|a| 20.0 * a.max(1e-300).log10()).collect();
    let power: Vec<f64> = amp.iter().map(|a| a * a).collect();
    // Training cells span several resolution cells so a target's own main lobe does not mask it.
    let cells_per_resolution = ((C0 / 2e9) / p.axis.step).max(1.0);
    let guard = (2.0 * cells_per_resolution).ceil() as usize;
    let training = (8.0 * cells_per_resolution).ceil() as usize;
    let mut cfar = CaCfar::new(guard, training, options.pfa)?;
    let mut thresholds = vec![0.0; power.len()];
    cfar.detect(&power, &mut thresholds)?;
    let mut candidates: Vec<(usize, f64, f64)> = find_peaks(&db, 3.0)
        .into_iter()
        .filter_map(|pk| {
            let range = p.axis.at(pk.index as f64);
            let above = 10.0 * (power[pk.index] / thresholds[pk.index]).log10();
            ((options.min_range_m..=options.max_range_m).contains(&range) && above > 0.0)
                .then_some((pk.index, pk.value, above))
        })
        .collect();
    candidates.sort_by(|a, b| b.1.total_cmp(&a.1));
    let mut kept: Vec<(usize, f64, f64)> = Vec::new();
    for c in candidates {
        let masked = kept.iter().any(|k| {
            let cells = (c.0 as f64 - k.0 as f64).abs() / cells_per_resolution;
            let mask = if cells < 1.0 {
                0.0
            } else {
                -20.0 * (std::f64::consts::PI * cells).log10()
            };
            c.1 < k.1 + mask + SIDELOBE_MARGIN_DB
        });
        if !masked {
            kept.push(c);
        }
    }
    let strongest = kept.first().map(|k| k.0);
    let targets = kept
        .iter()
        .map(|&(index, _, above)| {
            let (x, height) = interpolate_peak(amp, index, Interpolation::ParabolicDb);
            Detection {
                range_m: p.axis.at(x),
                level_db: 20.0 * height.max(1e-300).log10(),
                above_threshold_db: Some(above),
            }
        })
        .collect();
    Ok((targets, strongest))
}

/// Why a capture may show no target, from what it holds.
fn no_target_hint(rx: &[Complex64], profile: &Profile) -> String {
    let rms = (rx.iter().map(|v| v.norm_sqr()).sum::<f64>() / rx.len().max(1) as f64).sqrt();
    let max = profile.amplitude.iter().copied().fold(0.0, f64::max);
    let mut sorted = profile.amplitude.clone();
    sorted.sort_by(f64::total_cmp);
    let median = sorted
        .get(sorted.len() / 2)
        .copied()
        .unwrap_or(0.0)
        .max(1e-300);
    let contrast_db = 20.0 * (max / median).log10();
    if max == 0.0 {
        "no target found: the capture is all zeros after background subtraction; the background \
         holds the same samples (a simulated bench replays its noise when restarted with the same \
         seed), or the scope saw nothing"
            .to_string()
    } else if contrast_db < 15.0 {
        format!(
            "no target found: the range profile is flat (peak {contrast_db:.1} dB over its median, \
             capture RMS {:.2} mV), so the capture looks like noise only. Check that the \
             transmitter and receiver are enabled (pass --allow-rf; a --tx-off capture measures \
             the noise floor), that the AWG outputs I/Q, and that the antennas face the target",
            rms * 1e3
        )
    } else {
        format!(
            "no target found in the range window: the strongest echo is outside it or below the \
             CFAR threshold (peak {contrast_db:.1} dB over the median). Check --min-range/--max-range \
             and the calibration"
        )
    }
}

/// Decodes the data carried by the waveform from the strongest echo.
fn decode_payload(
    rx: &[Complex64],
    tx: &Transmission,
    period: usize,
    primary: &Profile,
    strongest: Option<usize>,
) -> Option<PayloadResult> {
    let result = match tx.kind {
        WaveformKind::MskLfm => {
            let index = strongest?;
            // The correlation profile's index is the echo's lag in samples of the aligned
            // repetition: advance the capture by it so the echo starts at sample 0.
            let (lag, _) = interpolate_peak(&primary.amplitude, index, Interpolation::ParabolicDb);
            let gen = MskLfm::new(tx.msk?).ok()?;
            let aligned = fractional_shift(&rx[..period.min(rx.len())], -lag);
            // Remove the echo's carrier phase: correlate with the reference at lag 0.
            let c: Complex64 = aligned
                .iter()
                .zip(&tx.reference)
                .map(|(a, b)| a * b.conj())
                .sum();
            let derot = if c.norm() > 0.0 {
                c.conj() / c.norm()
            } else {
                Complex64::new(1.0, 0.0)
            };
            let used = tx.reference.len();
            let pulse: Vec<Complex64> = aligned[..used].iter().map(|v| v * derot).collect();
            gen.demodulate(&pulse).map_err(|e| e.to_string())
        }
        WaveformKind::Ofdm => {
            let gen = Ofdm::new(tx.ofdm?).ok()?;
            let used = tx.reference.len();
            let mut rxr = gen.receiver();
            rxr.receive(&rx[..used.min(rx.len())], &Equalisation::Preamble)
                .map(|r| r.bits)
                .map_err(|e| e.to_string())
        }
    };
    Some(match result {
        Ok(bits) => {
            let n = bits.len().min(tx.bits.len());
            let errors = count_bit_errors(&bits[..n], &tx.bits[..n]);
            let bytes = tx
                .payload
                .as_ref()
                .and_then(|_| unframe_payload(&bits).ok());
            PayloadResult {
                text: bytes
                    .as_ref()
                    .map(|b| String::from_utf8_lossy(b).into_owned()),
                error: match (&tx.payload, &bytes) {
                    (Some(_), None) => Some("the payload framing did not decode".into()),
                    _ => None,
                },
                bytes,
                bit_errors: errors,
                bits: n,
                ber: if n > 0 { errors as f64 / n as f64 } else { 0.0 },
            }
        }
        Err(e) => PayloadResult {
            bytes: None,
            text: None,
            bit_errors: 0,
            bits: 0,
            ber: 0.0,
            error: Some(e),
        },
    })
}

/// `x` advanced by `shift` samples (circularly, band-limited): out[n] = x[n - shift].
fn fractional_shift(x: &[Complex64], shift: f64) -> Vec<Complex64> {
    let n = x.len();
    let mut planner = FftPlanner::<f64>::new();
    let mut buf = x.to_vec();
    planner.plan_fft_forward(n).process(&mut buf);
    for (k, v) in buf.iter_mut().enumerate() {
        let signed = if k <= n / 2 {
            k as f64
        } else {
            k as f64 - n as f64
        };
        *v *= Complex64::from_polar(
            1.0 / n as f64,
            -2.0 * std::f64::consts::PI * signed * shift / n as f64,
        );
    }
    planner.plan_fft_inverse(n).process(&mut buf);
    buf
}
