//! The communication half of the pipeline: the data carried by the waveform, decoded from the
//! strongest echo. Receivers and FFT plans are built once per pipeline.

use super::transmit::{Modulation, Transmission};
use super::MeasureError;
use crate::dsp::link_quality::{link_quality, LinkQuality};
use crate::waveform::bits::{count_bit_errors, unframe_payload};
use crate::waveform::ofdm::{qpsk_map, Equalisation, OfdmReceiver};
use num_complex::Complex64;
use rustfft::{Fft, FftPlanner};
use serde::Serialize;
use std::sync::Arc;

/// Decoded data.
#[derive(Debug, Clone, PartialEq, Serialize)]
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
    /// RMS error-vector magnitude of the data symbols against those sent, percent.
    pub evm_rms_pct: Option<f64>,
    /// The 95th percentile of the symbols' EVM, percent.
    pub evm_p95_pct: Option<f64>,
    /// Modulation error ratio, dB.
    pub mer_db: Option<f64>,
    /// What the plots of the link show (constellation, channel, phase trajectory).
    #[serde(skip)]
    pub(crate) trace: Option<Arc<LinkTrace>>,
}

/// The received symbols and what the receiver learnt, for the link's plots.
#[derive(Debug, Clone, PartialEq)]
pub(crate) enum LinkTrace {
    /// OFDM: equalised data symbols, and the first frame's channel estimate per subcarrier
    /// (ascending frequency) with the subcarriers' offsets from the centre, Hz.
    Ofdm {
        constellation: Vec<Complex64>,
        channel: Vec<Complex64>,
        subcarrier_hz: Vec<f64>,
    },
    /// MSK-LFM: each symbol pair (I, Q) scaled to the ideal +-1, and the phase of the
    /// dechirped signal over the first bits with that of the transmitted reference, degrees,
    /// `samples_per_bit` points per bit.
    MskLfm {
        constellation: Vec<Complex64>,
        phase_deg: Vec<f64>,
        ideal_phase_deg: Vec<f64>,
        samples_per_bit: f64,
    },
}

/// Symbols drawn in a constellation at most (evenly picked from all of them).
const CONSTELLATION_MAX: usize = 4000;

impl LinkTrace {
    /// The link's figure: the constellation, and the channel (OFDM) or the phase trajectory
    /// (MSK-LFM).
    pub(crate) fn figure(&self, title: String) -> crate::storage::plot::link::LinkPlot {
        use crate::storage::plot::link::{LinkPlot, Panel, PanelLine};
        let thin = |c: &[Complex64]| -> Vec<(f64, f64)> {
            let step = c.len().div_ceil(CONSTELLATION_MAX).max(1);
            c.iter().step_by(step).map(|z| (z.re, z.im)).collect()
        };
        let line = |label: &str, points: Vec<(f64, f64)>, dashed: bool| PanelLine {
            label: label.into(),
            points,
            dashed,
        };
        match self {
            LinkTrace::Ofdm {
                constellation,
                channel,
                subcarrier_hz,
            } => {
                let r = std::f64::consts::FRAC_1_SQRT_2;
                let f: Vec<f64> = subcarrier_hz.iter().map(|h| h / 1e6).collect();
                let mut phase = unwrapped_deg(channel);
                // The echo's delay is a phase slope: drawn as measured (unwrapped).
                if let Some(first) = phase.first().copied() {
                    let turns = (first / 360.0).round() * 360.0;
                    phase.iter_mut().for_each(|p| *p -= turns);
                }
                LinkPlot {
                    title,
                    symbols: thin(constellation),
                    ideal: vec![(r, r), (-r, r), (-r, -r), (r, -r)],
                    panels: vec![
                        Panel {
                            title: "Channel estimate: magnitude".into(),
                            x_label: "subcarrier offset (MHz)".into(),
                            y_label: "|H| (dB)".into(),
                            lines: vec![line(
                                "|H|",
                                f.iter()
                                    .zip(channel)
                                    .map(|(x, h)| (*x, 20.0 * h.norm().max(1e-12).log10()))
                                    .collect(),
                                false,
                            )],
                        },
                        Panel {
                            title: "Channel estimate: phase (unwrapped)".into(),
                            x_label: "subcarrier offset (MHz)".into(),
                            y_label: "arg H (deg)".into(),
                            lines: vec![line(
                                "arg H",
                                f.iter().copied().zip(phase).collect(),
                                false,
                            )],
                        },
                    ],
                }
            }
            LinkTrace::MskLfm {
                constellation,
                phase_deg,
                ideal_phase_deg,
                samples_per_bit,
            } => {
                let t = |k: usize| k as f64 / samples_per_bit;
                let offset = phase_deg.first().copied().unwrap_or(0.0)
                    - ideal_phase_deg.first().copied().unwrap_or(0.0);
                let thin_line = |p: &[f64], shift: f64| -> Vec<(f64, f64)> {
                    let step = p.len().div_ceil(2000).max(1);
                    p.iter()
                        .enumerate()
                        .step_by(step)
                        .map(|(k, v)| (t(k), v - shift))
                        .collect()
                };
                LinkPlot {
                    title,
                    symbols: thin(constellation),
                    ideal: vec![(1.0, 1.0), (-1.0, 1.0), (-1.0, -1.0), (1.0, -1.0)],
                    panels: vec![Panel {
                        title: "Phase trajectory (dechirped, first bits)".into(),
                        x_label: "time (bits)".into(),
                        y_label: "phase (deg)".into(),
                        lines: vec![
                            line("received", thin_line(phase_deg, offset), false),
                            line("sent", thin_line(ideal_phase_deg, 0.0), true),
                        ],
                    }],
                }
            }
        }
    }
}

/// Bits of the MSK-LFM phase trajectory drawn.
const TRAJECTORY_BITS: f64 = 32.0;

/// Points of the MSK-LFM phase trajectory drawn (per line).
const TRAJECTORY_POINTS: usize = 2000;

/// Unwrapped phase in degrees.
fn unwrapped_deg(z: &[Complex64]) -> Vec<f64> {
    let mut out = Vec::with_capacity(z.len());
    let mut last = 0.0;
    let mut offset = 0.0;
    for (k, v) in z.iter().enumerate() {
        let p = v.arg();
        if k > 0 {
            let d = p - last;
            if d > std::f64::consts::PI {
                offset -= 2.0 * std::f64::consts::PI;
            } else if d < -std::f64::consts::PI {
                offset += 2.0 * std::f64::consts::PI;
            }
        }
        last = p;
        out.push((p + offset).to_degrees());
    }
    out
}

/// What the decoder recovered before the bits are counted.
struct Decoded {
    bits: Vec<u8>,
    quality: Option<LinkQuality>,
    trace: Option<LinkTrace>,
}

/// The receiver of one transmission.
pub(crate) enum PayloadDecoder {
    /// MSK-LFM: advance the capture by the strongest echo's (fractional) lag, remove its carrier
    /// phase, demodulate. The FFT plans of the shift are made once.
    MskLfm {
        forward: Arc<dyn Fft<f64>>,
        inverse: Arc<dyn Fft<f64>>,
        buf: Vec<Complex64>,
        scratch: Vec<Complex64>,
    },
    /// OFDM: the frame-aligned receiver, equalised from the preamble.
    Ofdm(Box<OfdmReceiver>),
}

impl PayloadDecoder {
    pub(crate) fn new(tx: &Transmission, period: usize) -> Result<Self, MeasureError> {
        Ok(match &tx.modulation {
            Modulation::MskLfm(_) => {
                let mut planner = FftPlanner::<f64>::new();
                let forward = planner.plan_fft_forward(period);
                let inverse = planner.plan_fft_inverse(period);
                let scratch_len = forward
                    .get_inplace_scratch_len()
                    .max(inverse.get_inplace_scratch_len());
                PayloadDecoder::MskLfm {
                    forward,
                    inverse,
                    buf: Vec::with_capacity(period),
                    scratch: vec![Complex64::new(0.0, 0.0); scratch_len],
                }
            }
            Modulation::Ofdm { generator, .. } => {
                PayloadDecoder::Ofdm(Box::new(generator.receiver()))
            }
        })
    }

    /// Decodes the data of one aligned repetition `rx` from the strongest echo, at fractional
    /// lag `lag` (samples; the correlation profile's cell); `None` when there is nothing to decode
    /// from (MSK-LFM without a target).
    pub(crate) fn decode(
        &mut self,
        rx: &[Complex64],
        tx: &Transmission,
        lag: Option<f64>,
    ) -> Option<PayloadResult> {
        let result = match (self, &tx.modulation) {
            (
                PayloadDecoder::MskLfm {
                    forward,
                    inverse,
                    buf,
                    scratch,
                },
                Modulation::MskLfm(gen),
            ) => {
                // The correlation profile's cell is the echo's lag in samples of the aligned
                // repetition: advance the capture by it so the echo starts at sample 0.
                let lag = lag?;
                buf.clear();
                buf.extend_from_slice(rx);
                fractional_shift(buf, -lag, forward.as_ref(), inverse.as_ref(), scratch);
                // Remove the echo's carrier phase: correlate with the reference at lag 0.
                let c: Complex64 = buf
                    .iter()
                    .zip(&tx.reference)
                    .map(|(a, b)| a * b.conj())
                    .sum();
                let derot = if c.norm() > 0.0 {
                    c.conj() / c.norm()
                } else {
                    Complex64::new(1.0, 0.0)
                };
                let used = tx.reference.len().min(buf.len());
                for v in &mut buf[..used] {
                    *v *= derot;
                }
                gen.soft_symbols(&buf[..used])
                    .map(|soft| msk_decoded(gen, &soft, &buf[..used], &tx.reference, &tx.bits))
                    .map_err(|e| e.to_string())
            }
            (PayloadDecoder::Ofdm(receiver), Modulation::Ofdm { .. }) => {
                let used = tx.reference.len();
                let n = receiver.waveform().subcarriers();
                let spacing =
                    receiver.waveform().sample_rate_hz() / receiver.waveform().fft_len() as f64;
                receiver
                    .receive(&rx[..used.min(rx.len())], &Equalisation::Preamble)
                    .map(|r| {
                        let ideal: Vec<Complex64> = tx
                            .bits
                            .chunks_exact(2)
                            .map(|b| qpsk_map(b[0], b[1]))
                            .collect();
                        let quality = link_quality(&r.equalised, &ideal);
                        let centre = (n as f64 - 1.0) / 2.0;
                        Decoded {
                            trace: Some(LinkTrace::Ofdm {
                                channel: r.channel[..n.min(r.channel.len())].to_vec(),
                                subcarrier_hz: (0..n)
                                    .map(|k| (k as f64 - centre) * spacing)
                                    .collect(),
                                constellation: r.equalised,
                            }),
                            bits: r.bits,
                            quality,
                        }
                    })
                    .map_err(|e| e.to_string())
            }
            _ => return None,
        };
        Some(match result {
            Ok(Decoded {
                bits,
                quality,
                trace,
            }) => {
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
                    evm_rms_pct: quality.map(|q| q.evm_rms_pct),
                    evm_p95_pct: quality.map(|q| q.evm_p95_pct),
                    mer_db: quality.map(|q| q.mer_db).filter(|m| m.is_finite()),
                    trace: trace.map(Arc::new),
                }
            }
            Err(e) => PayloadResult {
                bytes: None,
                text: None,
                bit_errors: 0,
                bits: 0,
                ber: 0.0,
                error: Some(e),
                evm_rms_pct: None,
                evm_p95_pct: None,
                mer_db: None,
                trace: None,
            },
        })
    }
}

/// The MSK-LFM decoder's figures from the matched-filter outputs `soft` (every symbol, bit
/// order) of the aligned, derotated pulses `pulses` that carried `sent`: hard decisions, EVM and
/// MER of the (I, Q) symbol pairs against the sent ones with the echo's amplitude taken out
/// (data-aided), and the first pulse's phase trajectory.
fn msk_decoded(
    gen: &crate::waveform::MskLfm,
    soft: &[f64],
    pulses: &[Complex64],
    reference: &[Complex64],
    sent: &[u8],
) -> Decoded {
    let bits: Vec<u8> = soft.iter().map(|&v| u8::from(v < 0.0)).collect();
    let n = soft.len().min(sent.len()) / 2 * 2;
    let sign = |b: u8| 1.0 - 2.0 * f64::from(b & 1);
    let (num, den) = soft[..n]
        .iter()
        .zip(&sent[..n])
        .fold((0.0, 0.0), |(a, b), (v, &s)| (a + v * sign(s), b + 1.0));
    let gain = if den > 0.0 { num / den } else { 0.0 };
    let (mut quality, mut constellation) = (None, Vec::new());
    if gain.abs() > 0.0 && gain.is_finite() {
        constellation = soft[..n]
            .chunks_exact(2)
            .map(|p| Complex64::new(p[0], p[1]) / gain)
            .collect();
        let ideal: Vec<Complex64> = sent[..n]
            .chunks_exact(2)
            .map(|b| Complex64::new(sign(b[0]), sign(b[1])))
            .collect();
        quality = link_quality(&constellation, &ideal);
    }
    let spb = gen.samples_per_bit();
    let shown = ((TRAJECTORY_BITS * spb).ceil() as usize).min(pulses.len());
    // The phase is taken at the points drawn, not at every sample: a bit turns it by 90 degrees
    // over `spb` samples, so a step of a few degrees unwraps as at the full rate.
    let stride = shown.div_ceil(TRAJECTORY_POINTS).max(1);
    let phase_deg = unwrapped_deg(&gen.dechirped(pulses, shown, stride));
    // What was sent: the transmitted reference (the first pulse, as the AWG's codes play it).
    let ideal_phase_deg = unwrapped_deg(&gen.dechirped(reference, shown, stride));
    Decoded {
        bits,
        quality,
        trace: Some(LinkTrace::MskLfm {
            constellation,
            phase_deg,
            ideal_phase_deg,
            samples_per_bit: spb / stride as f64,
        }),
    }
}

/// `x` advanced by `shift` samples in place (circularly, band-limited): out[n] = x[n - shift].
fn fractional_shift(
    x: &mut [Complex64],
    shift: f64,
    forward: &dyn Fft<f64>,
    inverse: &dyn Fft<f64>,
    scratch: &mut [Complex64],
) {
    let n = x.len();
    forward.process_with_scratch(x, scratch);
    let step = -2.0 * std::f64::consts::PI * shift / n as f64;
    // The phase ramp by recurrence (one complex product per bin), restarted from an exact
    // phasor every EXACT_EVERY bins so rounding cannot accumulate: no sin/cos per bin.
    const EXACT_EVERY: usize = 1024;
    let rotate = Complex64::from_polar(1.0, step);
    let mut phasor = Complex64::new(0.0, 0.0);
    let scale = 1.0 / n as f64;
    for (k, v) in x.iter_mut().enumerate() {
        if k % EXACT_EVERY == 0 || k == n / 2 + 1 {
            let signed = if k <= n / 2 {
                k as f64
            } else {
                k as f64 - n as f64
            };
            phasor = Complex64::from_polar(scale, step * signed);
        }
        *v *= phasor;
        phasor *= rotate;
    }
    inverse.process_with_scratch(x, scratch);
}
