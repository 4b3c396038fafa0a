//! MSK-LFM: generator and communication receiver (thesis 2.2, 3.1).
