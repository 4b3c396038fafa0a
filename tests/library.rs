//! The library in process, no instrument and no process: signal processing, the measurement
//! pipeline and the thesis' simulations (`tests/dsp/`), the waveforms (`tests/waveform/`), the
//! instrument catalog (`tests/catalog/`) and the house rules over the sources: layer map,
//! public-API audit, import circles, processing reading no file (`tests/house/`).
//!
//! One test binary for all of them (each binary costs a link): each file below was its own
//! binary once. Module names are the file names, so test names do not depend on the folders.

#[path = "support/detect/mod.rs"]
mod detect_support;
#[path = "support/dsp/mod.rs"]
mod dsp_support;

#[path = "catalog/catalog_validation.rs"]
mod catalog_validation;
#[path = "house/circles.rs"]
mod circles;
#[path = "dsp/dsp_detect.rs"]
mod dsp_detect;
#[path = "dsp/dsp_metrics.rs"]
mod dsp_metrics;
#[path = "dsp/dsp_music.rs"]
mod dsp_music;
#[path = "dsp/dsp_ofdm_radar.rs"]
mod dsp_ofdm_radar;
#[path = "house/layers.rs"]
mod layers;
#[path = "dsp/pipeline_one.rs"]
mod pipeline_one;
#[path = "house/public_api.rs"]
mod public_api;
#[path = "house/reads_no_file.rs"]
mod reads_no_file;
#[path = "dsp/simulate_figures.rs"]
mod simulate_figures;
#[path = "waveform/waveform_ber.rs"]
mod waveform_ber;
#[path = "waveform/waveform_chain.rs"]
mod waveform_chain;
#[path = "waveform/waveform_msk_lfm.rs"]
mod waveform_msk_lfm;
#[path = "waveform/waveform_ofdm.rs"]
mod waveform_ofdm;
#[path = "waveform/waveform_quantise.rs"]
mod waveform_quantise;
