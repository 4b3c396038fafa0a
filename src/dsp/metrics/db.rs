//! Amplitudes in dB.

/// 20 log10 of an amplitude, floored at -400 dB so a zero stays finite.
pub(crate) fn amplitude_db(amplitude: f64) -> f64 {
    20.0 * amplitude.max(1e-20).log10()
}

/// Fills `out` with [`amplitude_db`] of `amplitude`.
pub(crate) fn to_db(amplitude: &[f64], out: &mut [f64]) {
    for (o, &a) in out.iter_mut().zip(amplitude) {
        *o = amplitude_db(a);
    }
}
