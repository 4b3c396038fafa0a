//! OFDM: generator and communication receiver (thesis 2.3, 3.2).
