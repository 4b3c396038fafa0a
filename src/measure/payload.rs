//! The communication half of the pipeline: the data carried by the waveform, decoded from the
//! strongest echo by its family's decoder (`family`), and counted. Receivers and FFT plans are
//! built once per pipeline.

use super::error::MeasureError;
use super::family::DecodePayload;
use super::transmit::Transmission;
use crate::dsp::link_quality::LinkQuality;
use crate::waveform::bits::{count_bit_errors, unframe_payload};
use num_complex::Complex64;
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

/// Unwrapped phase in degrees.
pub(crate) fn unwrapped_deg(z: &[Complex64]) -> Vec<f64> {
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

/// What a family's decoder recovered before the bits are counted.
pub(crate) struct Decoded {
    pub(crate) bits: Vec<u8>,
    pub(crate) quality: Option<LinkQuality>,
    pub(crate) trace: Option<LinkTrace>,
}

/// The receiver of one transmission: its family's decoder (`family::DecodePayload`, plans made
/// once), then the bits counted against those sent and the payload unframed.
pub(crate) struct PayloadDecoder(Box<dyn DecodePayload>);

impl PayloadDecoder {
    pub(crate) fn new(tx: &Transmission, period: usize) -> Result<Self, MeasureError> {
        Ok(PayloadDecoder(tx.modulation.payload_decoder(period)))
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
        let result = self.0.decode(rx, tx, lag)?;
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
