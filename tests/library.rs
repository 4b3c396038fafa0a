//! Signal processing, waveforms, the thesis' simulations and the layer rules: no instrument, no process.
//!
//! One test binary for many suites: each file below was its own binary, linked separately.

#[path = "../detect_support/mod.rs"]
mod detect_support;
#[path = "../dsp_support/mod.rs"]
mod dsp_support;

mod catalog_validation;
mod circles;
mod dsp_detect;
mod dsp_metrics;
mod dsp_music;
mod dsp_ofdm_radar;
mod layers;
mod pipeline_one;
mod public_api;
mod simulate_figures;
mod waveform_ber;
mod waveform_chain;
mod waveform_msk_lfm;
mod waveform_ofdm;
mod waveform_quantise;
