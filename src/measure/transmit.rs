//! What the AWG plays: the waveform, its 8-bit codes and marker, and what the receiver needs to
//! know about it (the transmitted reference, the OFDM symbols, the bits).

use super::MeasureError;
use crate::driver::IqWaveform;
use crate::waveform::bits::BitSource;
use crate::waveform::msk_lfm::{MskLfm, MskLfmParams};
use crate::waveform::ofdm::{Ofdm, OfdmParams, SymbolMatrix};
use crate::waveform::quantise::{quantise, BackoffReference, Quantised};
use num_complex::Complex64;

/// Which waveform to play.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum, serde::Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum WaveformKind {
    /// MSK-LFM: a 1 GHz chirp carrying 128 MSK bits per 10 us pulse (thesis Table 4.1).
    MskLfm,
    /// OFDM: 128 QPSK subcarriers over 1 GHz, 100 symbols per frame (thesis Table 4.2).
    Ofdm,
}

impl WaveformKind {
    pub fn name(self) -> &'static str {
        match self {
            WaveformKind::MskLfm => "msk-lfm",
            WaveformKind::Ofdm => "ofdm",
        }
    }
}

/// The marker is high on the first this-many samples of each repetition: 4 ns at 16 GSa/s, well
/// above the M8195A's minimum marker pulse of 128 DAC samples (32 memory samples at DIV4).
pub const MARKER_SAMPLES: usize = 64;

/// Back-off of the DAC codes below full scale, dB (peak reference): no clipping.
pub const DEFAULT_BACKOFF_DB: f64 = 0.5;

/// The transmission, ready for the AWG and the receiver.
#[derive(Debug, Clone)]
pub struct Transmission {
    pub kind: WaveformKind,
    /// Samples per second of the segment.
    pub sample_rate_hz: f64,
    pub bandwidth_hz: f64,
    /// The codes and marker downloaded to the AWG.
    pub iq: IqWaveform,
    /// What the codes represent, per unit full-scale (codes / 127): the correlation reference.
    pub reference: Vec<Complex64>,
    /// All transmitted bits (framing included).
    pub bits: Vec<u8>,
    /// The user payload, if one was sent.
    pub payload: Option<Vec<u8>>,
    /// OFDM only: the transmitted symbols, symbol-major, ascending subcarrier frequency.
    pub symbols: Option<SymbolMatrix>,
    pub msk: Option<MskLfmParams>,
    pub ofdm: Option<OfdmParams>,
    /// Quantisation report (clipping, SQNR).
    pub quantised: QuantisationReport,
}

/// What quantising to the DAC cost.
#[derive(Debug, Clone, serde::Serialize)]
pub struct QuantisationReport {
    pub backoff_db: f64,
    pub clipped_samples: usize,
    pub peak_dbfs: f64,
    pub sqnr_db: f64,
}

impl Transmission {
    /// The thesis' waveform of `kind` carrying `payload` (or PRBS bits from `seed`).
    pub fn new(
        kind: WaveformKind,
        payload: Option<&[u8]>,
        seed: u64,
        backoff_db: f64,
    ) -> Result<Transmission, MeasureError> {
        let source = match payload {
            Some(p) => BitSource::Payload(p.to_vec()),
            None => BitSource::Prbs { seed },
        };
        let (samples, bits, symbols, msk, ofdm, fs, bw) = match kind {
            WaveformKind::MskLfm => {
                let params = MskLfmParams::default();
                let gen = MskLfm::new(params)?;
                let sig = gen.generate(&source, 1)?;
                (
                    sig.samples,
                    sig.bits,
                    None,
                    Some(params),
                    None,
                    params.sample_rate_hz,
                    params.bandwidth_hz,
                )
            }
            WaveformKind::Ofdm => {
                let params = OfdmParams::default();
                let gen = Ofdm::new(params)?;
                let sig = gen.generate(&source, 1)?;
                (
                    sig.samples,
                    sig.bits,
                    Some(sig.symbols),
                    None,
                    Some(params),
                    gen.sample_rate_hz(),
                    params.bandwidth_hz,
                )
            }
        };
        let q: Quantised = quantise(&samples, backoff_db, BackoffReference::Peak)?;
        let reference =
            q.i.iter()
                .zip(&q.q)
                .map(|(&i, &q)| Complex64::new(f64::from(i), f64::from(q)) / 127.0)
                .collect();
        Ok(Transmission {
            kind,
            sample_rate_hz: fs,
            bandwidth_hz: bw,
            quantised: QuantisationReport {
                backoff_db,
                clipped_samples: q.clipped(),
                peak_dbfs: q.peak_dbfs(),
                sqnr_db: q.sqnr_db,
            },
            iq: IqWaveform {
                i: q.i,
                q: q.q,
                marker_high_samples: MARKER_SAMPLES,
            },
            reference,
            bits,
            payload: payload.map(<[u8]>::to_vec),
            symbols,
            msk,
            ofdm,
        })
    }

    /// Samples of one repetition as given (before the AWG pads to its granularity).
    pub fn len(&self) -> usize {
        self.reference.len()
    }

    pub fn is_empty(&self) -> bool {
        self.reference.is_empty()
    }

    /// Plain-data description for the run's files.
    pub fn describe(&self) -> serde_json::Value {
        let mut v = serde_json::json!({
            "waveform": self.kind.name(),
            "sample_rate_hz": self.sample_rate_hz,
            "bandwidth_hz": self.bandwidth_hz,
            "samples_per_repetition": self.len(),
            "marker_high_samples": self.iq.marker_high_samples,
            "bits": self.bits.len(),
            "payload_bytes": self.payload.as_ref().map(Vec::len),
            "quantisation": self.quantised,
        });
        if let Some(m) = &self.msk {
            v["bits_per_pulse"] = m.bits_per_pulse.into();
        }
        if let Some(o) = &self.ofdm {
            v["subcarriers"] = o.subcarriers.into();
            v["cp_fraction"] = o.cp_fraction.into();
            v["symbols_per_frame"] = o.symbols_per_frame.into();
            v["oversampling"] = o.oversampling.into();
        }
        v
    }
}
