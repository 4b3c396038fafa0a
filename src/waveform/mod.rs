//! Pure waveform code: MSK-LFM and OFDM generators, DAC quantisation, communication receivers.

use crate::exit::{Classify, ExitClass};

/// A waveform parameter that cannot be used; the message names the parameter and what is allowed.
#[derive(Debug, thiserror::Error)]
#[error("{message}")]
pub struct ParamError {
    pub message: String,
}

impl Classify for ParamError {
    fn exit_class(&self) -> ExitClass {
        ExitClass::BadInput
    }
}

pub mod msk_lfm;
pub mod ofdm;
pub mod quantise;
