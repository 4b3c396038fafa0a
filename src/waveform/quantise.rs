//! Quantisation to the AWG's signed 8-bit codes with back-off; clipping report.
