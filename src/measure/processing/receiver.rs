//! One family's communication receiver, the contract between the family rooms (`family`), which
//! implement it, and the payload stage (`payload`), which drives it: the generator as the
//! receivers use it ([`Modulation`], kept in the transmission), the decoder ([`DecodePayload`]),
//! what it recovered ([`Decoded`]) and what the link's plots show ([`LinkTrace`]). Below both, so
//! that neither imports the other.

use crate::dsp::link_quality::LinkQuality;
use crate::waveform::{Ofdm, SymbolMatrix};
use num_complex::Complex64;

/// A transmission's generator, as its family's receivers use it.
pub(crate) trait Modulation: std::fmt::Debug + Send + Sync {
    /// The communication receiver for aligned records of `period` samples (plans made once).
    fn payload_decoder(&self, period: usize) -> Box<dyn DecodePayload>;

    /// The OFDM frame (generator and every symbol sent) the subcarrier algorithms divide by;
    /// `None` for a family without one (correlation only).
    fn ofdm_frame(&self) -> Option<(&Ofdm, &SymbolMatrix)> {
        None
    }
}

/// One family's communication receiver.
pub(crate) trait DecodePayload: Send + Sync {
    /// The bits of one aligned repetition `rx` from the strongest echo at fractional lag `lag`
    /// (samples), against the transmission's `reference` (one repetition) and the `bits` it sent;
    /// `None` when there is nothing to decode from, `Some(Err)` with the reason when decoding
    /// failed.
    fn decode(
        &mut self,
        rx: &[Complex64],
        reference: &[Complex64],
        bits: &[u8],
        lag: Option<f64>,
    ) -> Option<Result<Decoded, String>>;
}

/// What a family's decoder recovered before the bits are counted.
pub(crate) struct Decoded {
    pub(crate) bits: Vec<u8>,
    pub(crate) quality: Option<LinkQuality>,
    pub(crate) trace: Option<LinkTrace>,
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
