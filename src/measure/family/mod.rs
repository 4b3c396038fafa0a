//! Each waveform family's behaviour, one room per family: what users may change of it
//! (overrides), how it is transmitted, how its data is decoded, which range algorithms take it
//! (and which by default), and the few facts simulations and reports ask of it. [`of`] is the one
//! `match` over the families; every other place asks the [`Family`] it returns.
//!
//! | file | what it holds |
//! |---|---|
//! | `msk_lfm.rs` | MSK-LFM: a chirp carrying MSK bits; its decoder (shift, derotate, integrate and dump) |
//! | `ofdm.rs` | OFDM: QPSK subcarriers with a cyclic prefix; its preamble-equalised decoder, the subcarrier algorithms |
//! | `overrides.rs` | the parameters users change from the thesis' defaults (command line and campaign specs alike) |
//!
//! The generators and the spec's own numbers (rate, bandwidth, unambiguous range) stay in the pure
//! `waveform` layer; a room decides what radbench does with them.

mod msk_lfm;
mod ofdm;
pub(crate) mod overrides;

use super::error::MeasureError;
use super::options::{Algorithm, ProcessOptions};
use super::payload::Decoded;
use super::transmit::Transmission;
use crate::waveform::BitSource;
use crate::waveform::ParamError;
use crate::waveform::{Ofdm, SymbolMatrix};
use crate::waveform::{WaveformKind, WaveformSpec};
use num_complex::Complex64;
use overrides::{OverrideError, WaveformOverrides};
use std::collections::BTreeMap;
use std::sync::Arc;

/// The room of `spec`'s family, holding its parameters: the one place that names every family.
pub(crate) fn of(spec: &WaveformSpec) -> Box<dyn Family> {
    match *spec {
        WaveformSpec::MskLfm {
            sample_rate_hz,
            bandwidth_hz,
            pulse_s,
            bits_per_pulse,
            band,
        } => Box::new(msk_lfm::MskLfmRoom {
            sample_rate_hz,
            bandwidth_hz,
            pulse_s,
            bits_per_pulse,
            band,
        }),
        WaveformSpec::Ofdm {
            bandwidth_hz,
            subcarriers,
            oversampling,
            cp_fraction,
            symbols,
            preamble_symbols,
        } => Box::new(ofdm::OfdmRoom {
            bandwidth_hz,
            subcarriers,
            oversampling,
            cp_fraction,
            symbols,
            preamble_symbols,
        }),
    }
}

/// The room of `kind` with the thesis' parameters (for what does not depend on them).
pub(crate) fn of_kind(kind: WaveformKind) -> Box<dyn Family> {
    of(&kind.thesis_default())
}

/// What one waveform family decides, for one set of its parameters.
pub(crate) trait Family {
    /// The family as messages name it (`MSK-LFM`, `OFDM`).
    fn label(&self) -> &'static str;

    /// The [`WaveformOverrides`] fields this family takes (as `WaveformOverrides` names them).
    fn parameters(&self) -> &'static [&'static str];

    /// These parameters with `overrides` applied (only fields of [`parameters`](Self::parameters)
    /// are given); a repetition too long is refused before anything is allocated.
    fn apply(&self, overrides: &WaveformOverrides) -> Result<WaveformSpec, OverrideError>;

    /// Checks every parameter as the generator does (named, with what is allowed), without
    /// generating anything.
    fn check(&self) -> Result<(), ParamError>;

    /// The generator and one repetition (all pulses or frames) carrying `source`.
    fn modulate(&self, source: &BitSource) -> Result<Modulated, MeasureError>;

    /// Data bits one pulse or frame carries (what sizes a payload).
    fn bits_per_repetition(&self) -> usize;

    /// The family's own parameters in a transmission's description (`describe`).
    fn describe(&self, description: &mut serde_json::Value);

    /// The range algorithms that can process this family.
    fn algorithms(&self) -> &'static [Algorithm];

    /// The algorithm used when none is asked for.
    fn default_algorithm(&self) -> Algorithm;

    /// Whether one repetition is a period of a continuous transmission (a cyclic-prefixed frame,
    /// whose echo wraps around) rather than a pulse (whose echo runs past its end).
    fn is_periodic(&self) -> bool;

    /// Processing settings only this family uses, recorded with its results.
    fn own_settings(&self, options: &ProcessOptions) -> BTreeMap<String, serde_json::Value>;

    /// The theoretical bit error rate at `ebn0_db`.
    fn ber_theory(&self, ebn0_db: f64) -> f64;

    /// The theory's formula, as the reports write it.
    fn ber_theory_formula(&self) -> &'static str;

    /// The thesis' single-target figures of this family at 1 GHz; `None` when the thesis did not
    /// measure it.
    fn thesis_widths(&self) -> Option<ThesisWidths>;

    /// These parameters as a simulation transmits them: every symbol data known to the radar
    /// (the communication receiver is not simulated).
    fn as_simulated(&self) -> WaveformSpec;

    /// The subcarriers that bound the subspace methods' M; `None` for a family without them.
    fn subcarriers(&self) -> Option<usize>;
}

/// The thesis' single-target figures: (simulation width cm, PSL dB, where), (lab width, PSL,
/// where).
pub(crate) struct ThesisWidths {
    pub(crate) simulation: (f64, f64, &'static str),
    pub(crate) lab: (f64, f64, &'static str),
}

/// What [`Family::modulate`] makes: the samples, the bits they carry, and the generator.
pub(crate) struct Modulated {
    pub(crate) samples: Vec<Complex64>,
    pub(crate) bits: Vec<u8>,
    pub(crate) modulation: Arc<dyn Modulation>,
}

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
    /// (samples); `None` when there is nothing to decode from, `Some(Err)` with the reason when
    /// decoding failed.
    fn decode(
        &mut self,
        rx: &[Complex64],
        tx: &Transmission,
        lag: Option<f64>,
    ) -> Option<Result<Decoded, String>>;
}

/// The labels of the families that take override `field`, for messages ("MSK-LFM").
fn families_taking(field: &str) -> String {
    let labels: Vec<&str> = WaveformKind::ALL
        .into_iter()
        .map(of_kind)
        .filter(|f| f.parameters().contains(&field))
        .map(|f| f.label())
        .collect();
    labels.join(" and ")
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_room_applies_nothing_as_the_thesis_and_defaults_to_an_algorithm_it_takes() {
        for kind in WaveformKind::ALL {
            let room = of_kind(kind);
            assert_eq!(
                room.apply(&WaveformOverrides::default()),
                Ok(kind.thesis_default()),
                "{kind}"
            );
            assert!(
                room.algorithms().contains(&room.default_algorithm()),
                "{kind}"
            );
            assert!(room.check().is_ok(), "{kind}");
            // A parameter the room takes is one `WaveformOverrides` knows (else it would always
            // be refused as another family's).
            let known: Vec<&str> = WaveformOverrides::default()
                .given()
                .iter()
                .map(|(field, _)| *field)
                .collect();
            for p in room.parameters() {
                assert!(known.contains(p), "{kind}: {p}");
            }
        }
    }

    #[test]
    fn the_room_is_the_one_of_its_spec() {
        assert_eq!(of_kind(WaveformKind::MskLfm).label(), "MSK-LFM");
        assert_eq!(of_kind(WaveformKind::Ofdm).label(), "OFDM");
        assert_eq!(families_taking("bandwidth_hz"), "MSK-LFM and OFDM");
        assert_eq!(families_taking("pulse_s"), "MSK-LFM");
        assert!(!of_kind(WaveformKind::MskLfm).is_periodic());
        assert!(of_kind(WaveformKind::Ofdm).is_periodic());
    }
}
