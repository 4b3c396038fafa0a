//! Simulations: the thesis' chapter-4 scenarios and free-form runs, built on `waveform` and `dsp`.
