//! Peak detection, CFAR, sub-sample interpolation, -3 dB width, side-lobe levels, the "resolved" rule.
