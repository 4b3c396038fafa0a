//! What a family room answers ([`Family`]) and what it modulates ([`Modulated`]): the contract the
//! rooms implement, in a file of its own so that they need not import their parent (`family`,
//! which names them). How its receiver decodes is `receiver`'s contract, below the transmission
//! and the payload stage.

use super::overrides::{OverrideError, WaveformOverrides};
use crate::measure::error::MeasureError;
use crate::measure::processing::options::{Algorithm, ProcessOptions};
use crate::measure::processing::receiver::Modulation;
use crate::waveform::{BitSource, ParamError, WaveformSpec};
use num_complex::Complex64;
use std::collections::BTreeMap;
use std::sync::Arc;

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
