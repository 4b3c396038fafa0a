//! Pure waveform code: MSK-LFM and OFDM generators, DAC quantisation, communication receivers.
//!
//! | module | what it holds |
//! |---|---|
//! | `bits` | bit sources (seeded PRBS or a user payload), payload framing and recovery, error counting |
//! | `msk_lfm` | MSK-LFM pulse generator and its dechirp + half-sine integrate-and-dump receiver |
//! | `ofdm` | OFDM frame generator (QPSK Gray, CP, ideal interpolation) and its receiver |
//! | `ber` | `erfc`, the theoretical BER curves and the Monte-Carlo BER helper |
//! | [`quantise`] | quantisation to the M8195A's signed 8-bit codes with back-off, clipping report |
//! | `spec` | [`spec::WaveformSpec`]: which waveform with which parameters, as plain data (TOML) |
//!
//! Conventions (sample order, scaling, bit order) follow `CONVENTIONS.md` of the project: complex
//! baseband `Complex64`, unit mean power per sample, bits as `u8` values 0/1 taken least significant
//! bit first. Nothing here does I/O or allocates behind the caller's back beyond the returned buffers.

#![warn(clippy::missing_errors_doc, clippy::missing_panics_doc)]

use crate::exit::{Classify, ExitClass};

/// A waveform parameter that cannot be used; the message names the parameter and what is allowed.
#[derive(Debug, thiserror::Error)]
#[error("{message}")]
pub struct ParamError {
    pub message: String,
}

impl ParamError {
    /// `parameter` is `got`, but only `allowed` is accepted.
    pub(crate) fn out_of_range(
        parameter: &str,
        got: impl std::fmt::Display,
        allowed: &str,
    ) -> Self {
        Self {
            message: format!("{parameter} = {got} is not allowed: {allowed}"),
        }
    }
}

impl Classify for ParamError {
    fn exit_class(&self) -> ExitClass {
        ExitClass::BadInput
    }
}

/// Received data that cannot be turned back into a payload (corrupted length header, too few bits).
///
/// This is a processing failure (exit code 4), not bad input: the parameters were fine, the channel
/// was not.
#[derive(Debug, thiserror::Error)]
#[error("{message}")]
pub struct DecodeError {
    pub message: String,
}

impl Classify for DecodeError {
    fn exit_class(&self) -> ExitClass {
        ExitClass::Processing
    }
}

pub(crate) mod ber;
pub(crate) mod bits;
pub(crate) mod msk_lfm;
pub(crate) mod ofdm;
pub(crate) mod quantise;
pub(crate) mod spec;

pub use ber::{
    ber_msk_lfm_theory, ber_ofdm_theory, measure_ber_msk_lfm, measure_ber_ofdm, BerBudget, BerPoint,
};
pub use bits::{unframe_payload, BitSource};
pub use msk_lfm::{MskLfm, MskLfmParams, MskLfmSignal, PulseLength};
pub use ofdm::{
    Equalisation, Ofdm, OfdmParams, OfdmReceiver, OfdmReception, OfdmSignal, SymbolMatrix,
};
pub use quantise::{quantise, BackoffReference, Quantised};
pub use spec::{SweepBand, WaveformKind, WaveformSpec};
