//! OFDM radar: framing, CP removal, spectral division, zero-padded IFFT, range-Doppler.
