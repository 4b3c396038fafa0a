//! What the AWG plays: the waveform (made by its family's room, `family`), its 8-bit codes and
//! marker, and what the receiver needs to know about it (the transmitted reference, the bits).

use super::family::{self, Modulated};
use super::receiver::Modulation;
use crate::driver::IqWaveform;
use crate::measure::error::MeasureError;
use crate::waveform::BitSource;
use crate::waveform::WaveformSpec;
use crate::waveform::{quantise, BackoffReference};
use num_complex::Complex64;
use serde::Serialize;
use std::sync::Arc;

/// The marker is high on the first this-many samples of each repetition: 4 ns at 16 GSa/s, well
/// above the M8195A's minimum marker pulse of 128 DAC samples (32 memory samples at DIV4).
pub(crate) const MARKER_SAMPLES: usize = 64;

/// Back-off of the DAC codes below full scale, dB (peak reference): no clipping.
pub(crate) const DEFAULT_BACKOFF_DB: f64 = 0.5;

/// Most samples one repetition (all pulses or frames of a payload) may hold: 64 M samples at
/// 16 GSa/s is 4 ms, 1 GB as complex doubles.
pub(crate) const MAX_SAMPLES: usize = 64_000_000;

/// How the transmitted reference is modelled.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Dac {
    /// The AWG's 8-bit codes, `backoff_db` below full scale: the reference is what the codes
    /// represent (the bench).
    Codes { backoff_db: f64 },
    /// The ideal waveform (simulations of the thesis, which does not quantise); codes are still
    /// made for completeness.
    Ideal,
}

impl Default for Dac {
    fn default() -> Self {
        Dac::Codes {
            backoff_db: DEFAULT_BACKOFF_DB,
        }
    }
}

/// What quantising to the DAC cost.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct QuantisationReport {
    pub backoff_db: f64,
    pub clipped_samples: usize,
    pub peak_dbfs: f64,
    pub sqnr_db: f64,
}

/// The transmission, ready for the AWG and the receiver.
#[derive(Debug, Clone)]
pub struct Transmission {
    /// The parameters it was made from.
    pub spec: WaveformSpec,
    /// The generator, as the family's receivers use it.
    pub(crate) modulation: Arc<dyn Modulation>,
    /// The codes and marker downloaded to the AWG.
    pub iq: IqWaveform,
    /// The transmitted signal per unit full scale (codes / 127 on the bench): the correlation
    /// reference, one repetition (all pulses or frames of the payload).
    pub reference: Vec<Complex64>,
    /// All transmitted bits (framing included).
    pub bits: Vec<u8>,
    /// The user payload, if one was sent.
    pub payload: Option<Vec<u8>>,
    /// The PRBS seed of the bits when no payload was sent.
    pub seed: u64,
    /// How the reference was modelled.
    pub dac: Dac,
    /// What quantising to the DAC cost.
    pub quantised: QuantisationReport,
    /// The chain's response pre-distorted out of the codes (`--correction tx|both`).
    pub predistortion: Option<PredistortionReport>,
}

/// What pre-distorting the waveform for the chain's measured response cost.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct PredistortionReport {
    /// The calibration it came from.
    pub calibration: String,
    /// How much more back-off the pre-distorted waveform needs to keep its peak within the DAC's
    /// range: its peak-to-average ratio against the original's, dB.
    pub extra_backoff_db: f64,
    /// Quantisation SQNR of the codes before and after, dB.
    pub sqnr_db_before: f64,
    pub sqnr_db_after: f64,
    /// Largest boost of the inverse response over the band, dB.
    pub peak_boost_db: f64,
    /// The transmitter's I/Q errors pre-distorted out: Q's gain and phase relative to I, and
    /// its skew (0 when the calibration could not tell it from the receiver's).
    pub tx_iq_gain_db: f64,
    pub tx_iq_phase_deg: f64,
    pub tx_iq_skew_ps: f64,
}

impl Transmission {
    /// The waveform of `spec` carrying `payload` (or PRBS bits from `seed`).
    pub fn new(
        spec: &WaveformSpec,
        payload: Option<&[u8]>,
        seed: u64,
        dac: Dac,
    ) -> Result<Transmission, MeasureError> {
        let source = match payload {
            Some(p) => BitSource::Payload(p.to_vec()),
            None => BitSource::Prbs { seed },
        };
        if let Some(p) = payload {
            check_payload(spec, p.len())?;
        }
        let Modulated {
            samples,
            bits,
            modulation,
        } = family::of(spec).modulate(&source)?;
        let backoff_db = match dac {
            Dac::Codes { backoff_db } => backoff_db,
            Dac::Ideal => DEFAULT_BACKOFF_DB,
        };
        let q = quantise(&samples, backoff_db, BackoffReference::Peak)?;
        let reference = match dac {
            Dac::Codes { .. } => as_reference(&q),
            Dac::Ideal => samples,
        };
        Ok(Transmission {
            spec: *spec,
            quantised: QuantisationReport::of(&q, backoff_db),
            iq: IqWaveform {
                i: q.i,
                q: q.q,
                marker_high_samples: MARKER_SAMPLES,
            },
            reference,
            bits,
            payload: payload.map(<[u8]>::to_vec),
            seed,
            dac,
            modulation,
            predistortion: None,
        })
    }

    /// This transmission as `options.correction` wants it: pre-distorted for the chain's
    /// response with `tx` and `both` (by the calibration the options carry: no file is read),
    /// unchanged otherwise.
    pub(crate) fn with_correction(
        self,
        options: &super::options::ProcessOptions,
    ) -> Result<Transmission, MeasureError> {
        match &options.correction {
            Some(used) if used.mode.predistorts() => self.predistorted(
                used.loaded()?,
                used.mode == crate::measure::calibration::response::CorrectionMode::Both,
            ),
            _ => Ok(self),
        }
    }

    /// The codes pre-distorted by the inverse of `cal`'s measured response (magnitude and phase
    /// over the band) and of the transmitter's I/Q errors (gain, phase, skew): what leaves the
    /// transmitter and the chain is then the waveform as designed. The receiver's reference
    /// becomes what the measured chain makes of the new codes (up to where the receiver's own
    /// corrections leave it: `rx_corrected` when the receiver undoes its skew), so the matched
    /// filter and the OFDM division fit what arrives.
    pub(crate) fn predistorted(
        &self,
        cal: &crate::measure::calibration::response::Calibration,
        rx_corrected: bool,
    ) -> Result<Transmission, MeasureError> {
        use crate::dsp::response::RxEqualiser;
        if matches!(self.dac, Dac::Ideal) {
            return Err(MeasureError::option(
                "correction",
                "tx",
                "tx and both pre-distort the AWG's codes: a bench transmission (8-bit codes)",
            ));
        }
        let n = self.len();
        let fs = self.sample_rate_hz();
        let rf = cal.response.rf_table();
        let tx_iq = cal.response.tx_iq();
        let mut x = self.reference.clone();
        let zero = num_complex::Complex64::new(0.0, 0.0);
        RxEqualiser::new(&rf, zero, None, n, fs)?.apply(&mut x, false)?;
        in_spectrum(&mut x, |s| tx_iq.undo(s, fs));
        let backoff_db = match self.dac {
            Dac::Codes { backoff_db } => backoff_db,
            Dac::Ideal => DEFAULT_BACKOFF_DB,
        };
        let q = quantise(&x, backoff_db, BackoffReference::Peak)?;
        let after_tx = cal.response.after_transmitter(rx_corrected);
        let mut reference = as_reference(&q);
        in_spectrum(&mut reference, |s| tx_iq.apply(s, fs));
        let reference = through_table(&reference, &after_tx, fs);
        let papr = |v: &[Complex64]| {
            let peak = v.iter().map(|z| z.norm_sqr()).fold(0.0, f64::max);
            let mean = v.iter().map(|z| z.norm_sqr()).sum::<f64>() / v.len().max(1) as f64;
            10.0 * (peak / mean.max(1e-300)).max(1e-300).log10()
        };
        let peak_boost_db = rf
            .response
            .iter()
            .map(|h| -20.0 * h.norm().max(1e-300).log10())
            .fold(f64::NEG_INFINITY, f64::max);
        let report = PredistortionReport {
            calibration: cal.path.display().to_string(),
            extra_backoff_db: papr(&x) - papr(&self.reference),
            sqnr_db_before: self.quantised.sqnr_db,
            sqnr_db_after: q.sqnr_db,
            peak_boost_db,
            tx_iq_gain_db: 20.0 * tx_iq.gain.log10(),
            tx_iq_phase_deg: tx_iq.phase.to_degrees(),
            tx_iq_skew_ps: tx_iq.skew_s * 1e12,
        };
        Ok(Transmission {
            quantised: QuantisationReport::of(&q, backoff_db),
            iq: IqWaveform {
                i: q.i,
                q: q.q,
                marker_high_samples: self.iq.marker_high_samples,
            },
            reference,
            predistortion: Some(report),
            ..self.clone()
        })
    }

    /// Samples per second of the segment.
    pub fn sample_rate_hz(&self) -> f64 {
        self.spec.sample_rate_hz()
    }

    pub fn bandwidth_hz(&self) -> f64 {
        self.spec.bandwidth_hz()
    }

    /// The band the waveform occupies in baseband, `[low, high]` Hz (centred unless an MSK-LFM
    /// sweep is `upper` or `lower`).
    pub(crate) fn band_hz(&self) -> [f64; 2] {
        self.spec.band_hz()
    }

    pub fn name(&self) -> &'static str {
        self.spec.name()
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
            "waveform": self.name(),
            "sample_rate_hz": self.sample_rate_hz(),
            "bandwidth_hz": self.bandwidth_hz(),
            "samples_per_repetition": self.len(),
            "marker_high_samples": self.iq.marker_high_samples,
            "bits": self.bits.len(),
            "payload_bytes": self.payload.as_ref().map(Vec::len),
            "quantisation": self.quantised,
            "predistortion": self.predistortion,
            "spec": self.spec,
            // Enough to make the same transmission again (re-processing).
            "seed": self.seed,
            "payload_hex": self.payload.as_ref().map(|p| hex(p)),
            "dac": match self.dac {
                Dac::Codes { backoff_db } => serde_json::json!({"codes": {"backoff_db": backoff_db}}),
                Dac::Ideal => serde_json::json!("ideal"),
            },
        });
        family::of(&self.spec).describe(&mut v);
        v
    }
}

/// What the codes represent, per unit full scale (code / 127).
fn as_reference(q: &crate::waveform::Quantised) -> Vec<Complex64> {
    q.i.iter()
        .zip(&q.q)
        .map(|(&i, &q)| Complex64::new(f64::from(i), f64::from(q)) / 127.0)
        .collect()
}

impl QuantisationReport {
    fn of(q: &crate::waveform::Quantised, backoff_db: f64) -> Self {
        QuantisationReport {
            backoff_db,
            clipped_samples: q.clipped(),
            peak_dbfs: q.peak_dbfs(),
            sqnr_db: q.sqnr_db,
        }
    }
}

/// `x` (one period) through the response `table` (per bin, held at its ends).
fn through_table(
    x: &[Complex64],
    table: &crate::dsp::response::ResponseTable,
    fs: f64,
) -> Vec<Complex64> {
    let n = x.len();
    let mut planner = rustfft::FftPlanner::<f64>::new();
    let mut s = x.to_vec();
    planner.plan_fft_forward(n).process(&mut s);
    for (k, v) in s.iter_mut().enumerate() {
        let signed = if k <= n / 2 {
            k as f64
        } else {
            k as f64 - n as f64
        };
        *v *= table.at(signed * fs / n as f64) / n as f64;
    }
    planner.plan_fft_inverse(n).process(&mut s);
    s
}

/// `edit` applied to the spectrum of one period `x` (in place).
fn in_spectrum(x: &mut [Complex64], edit: impl FnOnce(&mut [Complex64])) {
    let n = x.len();
    let mut planner = rustfft::FftPlanner::<f64>::new();
    planner.plan_fft_forward(n).process(x);
    edit(x);
    planner.plan_fft_inverse(n).process(x);
    for v in x.iter_mut() {
        *v /= n as f64;
    }
}

/// A payload too long for one repetition is refused before anything is generated, naming the
/// longest that fits.
fn check_payload(spec: &WaveformSpec, bytes: usize) -> Result<(), MeasureError> {
    use crate::waveform::bits::HEADER_BITS;
    let per_unit_samples = spec.samples_per_repetition()?;
    let bits_per_unit = family::of(spec).bits_per_repetition();
    if bits_per_unit == 0 || per_unit_samples == 0 {
        return Ok(());
    }
    let units = (HEADER_BITS + 8 * bytes).div_ceil(bits_per_unit);
    if units.saturating_mul(per_unit_samples) > MAX_SAMPLES {
        let max_units = MAX_SAMPLES / per_unit_samples;
        let max_bytes = (max_units * bits_per_unit).saturating_sub(HEADER_BITS) / 8;
        return Err(MeasureError::option(
            "payload",
            format!("of {bytes} bytes"),
            format!(
                "at most {max_bytes} bytes with this {} waveform ({units} pulses or frames of \
                 {per_unit_samples} samples would exceed {MAX_SAMPLES} samples per repetition)",
                spec.name()
            ),
        ));
    }
    Ok(())
}

fn hex(bytes: &[u8]) -> String {
    bytes.iter().map(|b| format!("{b:02x}")).collect()
}

/// The bytes of a hex string (two digits a byte), `None` when it is not one.
pub(crate) fn from_hex(text: &str) -> Option<Vec<u8>> {
    if text.len() % 2 != 0 {
        return None;
    }
    (0..text.len())
        .step_by(2)
        .map(|i| u8::from_str_radix(text.get(i..i + 2)?, 16).ok())
        .collect()
}

/// The transmission a capture's `radbench:waveform` description (from [`Transmission::describe`])
/// was made from: spec, bits (seed or payload) and DAC model. `None` when something is missing.
pub(crate) fn from_description(
    v: &serde_json::Value,
) -> Option<Result<Transmission, MeasureError>> {
    let spec: WaveformSpec = serde_json::from_value(v.get("spec")?.clone()).ok()?;
    let seed = v.get("seed")?.as_u64()?;
    let payload = match v.get("payload_hex") {
        Some(serde_json::Value::String(h)) => Some(from_hex(h)?),
        _ => None,
    };
    let dac = match v.get("dac")? {
        serde_json::Value::String(s) if s == "ideal" => Dac::Ideal,
        other => Dac::Codes {
            backoff_db: other.get("codes")?.get("backoff_db")?.as_f64()?,
        },
    };
    Some(Transmission::new(&spec, payload.as_deref(), seed, dac))
}
