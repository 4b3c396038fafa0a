//! The communication half of the pipeline: the data carried by the waveform, decoded from the
//! strongest echo by its family's decoder (`receiver::DecodePayload`, which the transmission's
//! generator makes), and counted. Receivers and FFT plans are built once per pipeline.

use super::receiver::{DecodePayload, Decoded, LinkTrace};
use super::transmit::Transmission;
use crate::measure::error::MeasureError;
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

/// The receiver of one transmission: its family's decoder (`receiver::DecodePayload`, plans made
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
        let result = self.0.decode(rx, &tx.reference, &tx.bits, lag)?;
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
