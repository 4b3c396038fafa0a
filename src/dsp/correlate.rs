//! FFT cross-correlation with the transmit spectrum computed once.
