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
//! | `contract.rs` | what a family room answers ([`Family`]) and what its transmission and receiver are |
//!
//! The generators and the spec's own numbers (rate, bandwidth, unambiguous range) stay in the pure
//! `waveform` layer; a room decides what radbench does with them.

mod msk_lfm;
mod ofdm;
pub(crate) mod overrides;

mod contract;

use super::options::Algorithm;
use crate::waveform::{WaveformKind, WaveformSpec};
pub(crate) use contract::{Family, Modulated, ThesisWidths};
use overrides::{OverrideError, WaveformOverrides};
use strum::VariantArray;

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

// What the table answers about the plain types below it, written here so that they need not
// import it (the options and the overrides are data the rooms are built on).

impl Algorithm {
    /// Whether this algorithm can process this waveform (the subspace methods and Fourier need
    /// OFDM symbols; correlation works for both).
    pub fn supports(self, waveform: WaveformKind) -> bool {
        of_kind(waveform).algorithms().contains(&self)
    }

    /// The default algorithm of a waveform (its family's room says): correlation for MSK-LFM,
    /// Fourier for OFDM.
    pub(crate) fn default_for(waveform: WaveformKind) -> Algorithm {
        of_kind(waveform).default_algorithm()
    }
}

impl WaveformOverrides {
    /// The thesis' `kind` with these parameters. A parameter of another family is refused, so
    /// nothing given is silently ignored; sizes are checked before anything is allocated. The
    /// generators check the rest (even bit counts, CP range, ...) when the waveform is built.
    pub(crate) fn apply(&self, kind: WaveformKind) -> Result<WaveformSpec, OverrideError> {
        self.check_values()?;
        let family = of_kind(kind);
        for (field, given) in self.given() {
            if given && !family.parameters().contains(&field) {
                return Err(OverrideError::Misapplied {
                    field,
                    applies_to: families_taking(field),
                    kind: kind.name(),
                });
            }
        }
        family.apply(self)
    }
}

/// The labels of the families that take override `field`, for messages ("MSK-LFM").
fn families_taking(field: &str) -> String {
    let labels: Vec<&str> = WaveformKind::VARIANTS
        .iter()
        .map(|&kind| of_kind(kind))
        .filter(|f| f.parameters().contains(&field))
        .map(|f| f.label())
        .collect();
    labels.join(" and ")
}

#[cfg(test)]
mod tests {
    use super::overrides::WaveformOverrides;
    use super::*;

    #[test]
    fn every_room_applies_nothing_as_the_thesis_and_defaults_to_an_algorithm_it_takes() {
        for &kind in WaveformKind::VARIANTS {
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
