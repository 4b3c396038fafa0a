//! The communication half of the pipeline: the data carried by the waveform, decoded from the
//! strongest echo. Receivers and FFT plans are built once per pipeline.

use super::transmit::{Modulation, Transmission};
use super::MeasureError;
use crate::waveform::bits::{count_bit_errors, unframe_payload};
use crate::waveform::ofdm::{Equalisation, OfdmReceiver};
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
                gen.demodulate(&buf[..used]).map_err(|e| e.to_string())
            }
            (PayloadDecoder::Ofdm(receiver), Modulation::Ofdm { .. }) => {
                let used = tx.reference.len();
                receiver
                    .receive(&rx[..used.min(rx.len())], &Equalisation::Preamble)
                    .map(|r| r.bits)
                    .map_err(|e| e.to_string())
            }
            _ => return None,
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
