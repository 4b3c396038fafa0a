//! Windows: Hann, Taylor, Chebyshev.
