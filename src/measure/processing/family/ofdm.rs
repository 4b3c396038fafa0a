//! OFDM's room: QPSK subcarriers with a cyclic prefix (thesis 2.3). Every range algorithm takes it
//! (Fourier by default; correlation, MUSIC, root-MUSIC and ESPRIT divide by its symbols); its data
//! is decoded by the frame-aligned receiver, equalised from the preamble.

use super::contract::{Family, Modulated, ThesisWidths};
use super::overrides::{OverrideError, WaveformOverrides, MAX_SAMPLES_PER_REPETITION};
use crate::dsp::link_quality::link_quality;
use crate::measure::error::MeasureError;
use crate::measure::processing::receiver::{DecodePayload, Decoded, LinkTrace, Modulation};
use crate::measure::{Algorithm, ProcessOptions};
use crate::waveform::ber_ofdm_theory;
use crate::waveform::ofdm::{qpsk_map, Equalisation, Ofdm, OfdmParams, OfdmReceiver, SymbolMatrix};
use crate::waveform::BitSource;
use crate::waveform::ParamError;
use crate::waveform::WaveformSpec;
use num_complex::Complex64;
use std::collections::BTreeMap;
use std::sync::Arc;

/// The parameters of an OFDM spec.
pub(super) struct OfdmRoom {
    pub(super) bandwidth_hz: f64,
    pub(super) subcarriers: usize,
    pub(super) oversampling: usize,
    pub(super) cp_fraction: f64,
    pub(super) symbols: usize,
    pub(super) preamble_symbols: usize,
}

impl OfdmRoom {
    fn params(&self) -> OfdmParams {
        OfdmParams {
            subcarriers: self.subcarriers,
            bandwidth_hz: self.bandwidth_hz,
            oversampling: self.oversampling,
            cp_fraction: self.cp_fraction,
            symbols_per_frame: self.symbols,
            preamble_symbols: self.preamble_symbols,
        }
    }
}

impl Family for OfdmRoom {
    fn label(&self) -> &'static str {
        "OFDM"
    }

    fn parameters(&self) -> &'static [&'static str] {
        &[
            "bandwidth_hz",
            "subcarriers",
            "oversampling",
            "cp_fraction",
            "symbols",
            "preamble_symbols",
        ]
    }

    /// Without `oversampling`, a new bandwidth keeps the sample rate and the oversampling follows
    /// (the rate must then be a whole multiple of the bandwidth).
    fn apply(&self, o: &WaveformOverrides) -> Result<WaveformSpec, OverrideError> {
        let (mut bandwidth_hz, mut oversampling) = (self.bandwidth_hz, self.oversampling);
        match (o.bandwidth_hz, o.oversampling) {
            (Some(b), Some(os)) => {
                bandwidth_hz = b;
                oversampling = os;
            }
            (Some(b), None) => {
                let rate_hz = bandwidth_hz * oversampling as f64;
                let ratio = rate_hz / b;
                if ratio < 1.0 || (ratio - ratio.round()).abs() > 1e-9 * ratio {
                    return Err(OverrideError::BandwidthNotDivisor {
                        bandwidth_hz: b,
                        rate_hz,
                    });
                }
                bandwidth_hz = b;
                oversampling = ratio.round() as usize;
            }
            (None, Some(os)) => oversampling = os,
            (None, None) => {}
        }
        let subcarriers = o.subcarriers.unwrap_or(self.subcarriers);
        let cp_fraction = o.cp_fraction.unwrap_or(self.cp_fraction);
        let symbols = o.symbols.unwrap_or(self.symbols);
        let samples = (subcarriers as f64)
            * (oversampling as f64)
            * (1.0 + cp_fraction.abs())
            * (symbols as f64);
        if samples > MAX_SAMPLES_PER_REPETITION {
            return Err(OverrideError::TooLong {
                field: "symbols",
                samples,
            });
        }
        Ok(WaveformSpec::Ofdm {
            bandwidth_hz,
            subcarriers,
            oversampling,
            cp_fraction,
            symbols,
            preamble_symbols: o.preamble_symbols.unwrap_or(self.preamble_symbols),
        })
    }

    fn check(&self) -> Result<(), ParamError> {
        Ofdm::new(self.params()).map(|_| ())
    }

    fn modulate(&self, source: &BitSource) -> Result<Modulated, MeasureError> {
        let generator = Ofdm::new(self.params())?;
        let signal = generator.generate(source, 1)?;
        Ok(Modulated {
            samples: signal.samples,
            bits: signal.bits,
            modulation: Arc::new(OfdmModulation {
                generator,
                symbols: signal.symbols,
            }),
        })
    }

    fn bits_per_repetition(&self) -> usize {
        2 * self.subcarriers * self.symbols.saturating_sub(self.preamble_symbols)
    }

    fn describe(&self, v: &mut serde_json::Value) {
        v["subcarriers"] = self.subcarriers.into();
        v["cp_fraction"] = self.cp_fraction.into();
        v["symbols_per_frame"] = self.symbols.into();
        v["oversampling"] = self.oversampling.into();
        v["preamble_symbols"] = self.preamble_symbols.into();
    }

    fn algorithms(&self) -> &'static [Algorithm] {
        <Algorithm as strum::VariantArray>::VARIANTS
    }

    fn default_algorithm(&self) -> Algorithm {
        Algorithm::Fourier
    }

    fn is_periodic(&self) -> bool {
        true
    }

    fn own_settings(&self, options: &ProcessOptions) -> BTreeMap<String, serde_json::Value> {
        BTreeMap::from([(
            "fft_precision".to_string(),
            serde_json::json!(options.fft_precision),
        )])
    }

    fn ber_theory(&self, ebn0_db: f64) -> f64 {
        ber_ofdm_theory(ebn0_db, self.cp_fraction)
    }

    fn ber_theory_formula(&self) -> &'static str {
        "Q(sqrt(2 Eb/N0 / (1 + CP)))"
    }

    fn thesis_widths(&self) -> Option<ThesisWidths> {
        // Table 4.7 and the lab section 4.5.1.
        Some(ThesisWidths {
            simulation: (13.2, -13.24, "Table 4.7"),
            lab: (13.42, -14.19, "4.5.1"),
        })
    }

    /// Without a preamble: the radar knows every symbol.
    fn as_simulated(&self) -> WaveformSpec {
        WaveformSpec::Ofdm {
            bandwidth_hz: self.bandwidth_hz,
            subcarriers: self.subcarriers,
            oversampling: self.oversampling,
            cp_fraction: self.cp_fraction,
            symbols: self.symbols,
            preamble_symbols: 0,
        }
    }

    fn subcarriers(&self) -> Option<usize> {
        Some(self.subcarriers)
    }
}

/// OFDM frames with every transmitted symbol (symbol-major, ascending subcarrier frequency).
#[derive(Debug)]
struct OfdmModulation {
    generator: Ofdm,
    symbols: SymbolMatrix,
}

impl Modulation for OfdmModulation {
    fn payload_decoder(&self, _period: usize) -> Box<dyn DecodePayload> {
        Box::new(OfdmDecoder(self.generator.receiver()))
    }

    fn ofdm_frame(&self) -> Option<(&Ofdm, &SymbolMatrix)> {
        Some((&self.generator, &self.symbols))
    }
}

/// The frame-aligned receiver, equalised from the preamble.
struct OfdmDecoder(OfdmReceiver);

impl DecodePayload for OfdmDecoder {
    fn decode(
        &mut self,
        rx: &[Complex64],
        reference: &[Complex64],
        bits: &[u8],
        _lag: Option<f64>,
    ) -> Option<Result<Decoded, String>> {
        let receiver = &mut self.0;
        let used = reference.len();
        let n = receiver.waveform().subcarriers();
        let spacing = receiver.waveform().sample_rate_hz() / receiver.waveform().fft_len() as f64;
        Some(
            receiver
                .receive(&rx[..used.min(rx.len())], &Equalisation::Preamble)
                .map(|r| {
                    let ideal: Vec<Complex64> =
                        bits.chunks_exact(2).map(|b| qpsk_map(b[0], b[1])).collect();
                    let quality = link_quality(&r.equalised, &ideal);
                    let centre = (n as f64 - 1.0) / 2.0;
                    Decoded {
                        trace: Some(LinkTrace::Ofdm {
                            channel: r.channel[..n.min(r.channel.len())].to_vec(),
                            subcarrier_hz: (0..n).map(|k| (k as f64 - centre) * spacing).collect(),
                            constellation: r.equalised,
                        }),
                        bits: r.bits,
                        quality,
                    }
                })
                .map_err(|e| e.to_string()),
        )
    }
}
