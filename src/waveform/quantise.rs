//! Quantisation to the AWG's signed 8-bit codes with back-off; clipping report.
//!
//! The M8195A takes signed 8-bit DAC codes, -128..=127, separately for I and Q (two channels). Both
//! components share one scale (codes per unit amplitude) so the complex waveform keeps its shape;
//! the scale puts the chosen reference level `backoff_db` below full scale, where full scale is
//! code 127 (the largest code symmetric about zero):
//!
//! * [`BackoffReference::Peak`]: the largest `|I|` or `|Q|` sits at `127 * 10^(-backoff/20)`. With a
//!   back-off of 0 dB or more nothing clips.
//! * [`BackoffReference::Rms`]: the RMS of one component, `sqrt(mean(|s|^2) / 2)`, sits there; peaks
//!   above full scale clip. Use it for high-crest-factor signals like OFDM, trading clipping against
//!   quantisation noise.
//!
//! Codes are rounded to nearest (halves away from zero) and saturated to -128..=127; a sample whose
//! rounded code falls outside that range counts as clipped.

use num_complex::Complex64;

use super::ParamError;

/// Code of full scale.
pub(crate) const FULL_SCALE_CODE: f64 = 127.0;

/// What the back-off is measured from.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum BackoffReference {
    /// The signal's largest component magnitude (default).
    #[default]
    Peak,
    /// The signal's RMS per component.
    Rms,
}

/// Signed 8-bit codes for I and Q and what quantising cost.
#[derive(Debug, Clone, PartialEq)]
pub struct Quantised {
    /// In-phase codes.
    pub i: Vec<i8>,
    /// Quadrature codes.
    pub q: Vec<i8>,
    /// Codes per unit amplitude: code = round(scale * component).
    pub scale: f64,
    /// I samples that saturated.
    pub clipped_i: usize,
    /// Q samples that saturated.
    pub clipped_q: usize,
    /// Largest `|I|` in codes before saturation.
    pub peak_i_codes: f64,
    /// Largest `|Q|` in codes before saturation.
    pub peak_q_codes: f64,
    /// Signal power over the power of the quantisation error (rounding and clipping), in dB.
    pub sqnr_db: f64,
}

impl Quantised {
    /// Total saturated components.
    pub fn clipped(&self) -> usize {
        self.clipped_i + self.clipped_q
    }

    /// Largest component before saturation relative to full scale, dBFS (above 0 means clipping).
    pub fn peak_dbfs(&self) -> f64 {
        20.0 * (self.peak_i_codes.max(self.peak_q_codes) / FULL_SCALE_CODE).log10()
    }

    /// The waveform the DAC codes represent, in the input's units (codes / scale).
    pub fn to_complex(&self) -> Vec<Complex64> {
        self.i
            .iter()
            .zip(&self.q)
            .map(|(&i, &q)| Complex64::new(f64::from(i), f64::from(q)) / self.scale)
            .collect()
    }
}

/// Quantises `signal` to 8-bit codes with `backoff_db` (finite, -40..=100 dB) below full scale
/// measured from `reference`. Fails on an empty, all-zero or non-finite signal.
///
/// # Errors
///
/// [`ParamError`] when `backoff_db` is not finite or outside -40..=100 dB, a sample is not
/// finite, or the reference level is zero (an empty or all-zero signal).
pub fn quantise(
    signal: &[Complex64],
    backoff_db: f64,
    reference: BackoffReference,
) -> Result<Quantised, ParamError> {
    if !(backoff_db.is_finite() && (-40.0..=100.0).contains(&backoff_db)) {
        return Err(ParamError::out_of_range(
            "backoff_db",
            backoff_db,
            "must be between -40 and 100 dB below full scale",
        ));
    }
    if signal.iter().any(|z| !z.is_finite()) {
        return Err(ParamError::out_of_range(
            "signal",
            "a NaN or infinite sample",
            "every sample must be finite",
        ));
    }
    let level = match reference {
        BackoffReference::Peak => signal
            .iter()
            .map(|z| z.re.abs().max(z.im.abs()))
            .fold(0.0, f64::max),
        BackoffReference::Rms => (signal.iter().map(|z| z.norm_sqr()).sum::<f64>()
            / (2 * signal.len().max(1)) as f64)
            .sqrt(),
    };
    if level <= 0.0 {
        return Err(ParamError::out_of_range(
            "signal",
            "empty or all zeros",
            "needs at least one non-zero sample to set the DAC scale",
        ));
    }
    let scale = FULL_SCALE_CODE * 10f64.powf(-backoff_db / 20.0) / level;
    let mut out = Quantised {
        i: Vec::with_capacity(signal.len()),
        q: Vec::with_capacity(signal.len()),
        scale,
        clipped_i: 0,
        clipped_q: 0,
        peak_i_codes: 0.0,
        peak_q_codes: 0.0,
        sqnr_db: 0.0,
    };
    let (mut power, mut err) = (0.0, 0.0);
    for z in signal {
        let (vi, vq) = (z.re * scale, z.im * scale);
        out.peak_i_codes = out.peak_i_codes.max(vi.abs());
        out.peak_q_codes = out.peak_q_codes.max(vq.abs());
        let (ci, clip_i) = to_code(vi);
        let (cq, clip_q) = to_code(vq);
        out.clipped_i += usize::from(clip_i);
        out.clipped_q += usize::from(clip_q);
        out.i.push(ci);
        out.q.push(cq);
        power += vi * vi + vq * vq;
        err += (vi - f64::from(ci)).powi(2) + (vq - f64::from(cq)).powi(2);
    }
    out.sqnr_db = if err > 0.0 {
        10.0 * (power / err).log10()
    } else {
        f64::INFINITY
    };
    Ok(out)
}

fn to_code(v: f64) -> (i8, bool) {
    let r = v.round();
    if r > 127.0 {
        (127, true)
    } else if r < -128.0 {
        (-128, true)
    } else {
        (r as i8, false)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn peak_reference_never_clips_and_hits_the_backoff() {
        let s: Vec<Complex64> = (0..1000)
            .map(|n| Complex64::from_polar(1.0, 0.0123 * n as f64))
            .collect();
        let q = quantise(&s, 6.0, BackoffReference::Peak).unwrap();
        assert_eq!(q.clipped(), 0);
        assert!((q.peak_dbfs() + 6.0).abs() < 1e-9);
        // 8 bits at -6 dBFS: SQNR around 6.02 * 8 + 1.76 - 6 - (crest) > 35 dB.
        assert!(q.sqnr_db > 35.0, "{}", q.sqnr_db);
        let back = q.to_complex();
        let worst = back
            .iter()
            .zip(&s)
            .map(|(a, b)| (a - b).norm())
            .fold(0.0, f64::max);
        assert!(worst <= 0.5 * std::f64::consts::SQRT_2 / q.scale + 1e-12);
    }

    #[test]
    fn rms_reference_reports_clipping() {
        let mut s = vec![Complex64::new(0.1, -0.1); 99];
        s.push(Complex64::new(5.0, -0.2)); // a lone peak far above the RMS
        let q = quantise(&s, 0.0, BackoffReference::Rms).unwrap();
        assert_eq!(q.clipped_i, 1);
        assert_eq!(q.clipped_q, 0);
        assert_eq!(q.i[99], 127);
        assert!(q.peak_dbfs() > 0.0);
        let q = quantise(&[Complex64::new(-3.0, 3.0)], -3.0, BackoffReference::Peak).unwrap();
        assert_eq!((q.i[0], q.q[0], q.clipped()), (-128, 127, 2));
    }

    #[test]
    fn bad_inputs_are_errors() {
        let s = [Complex64::new(1.0, 0.0)];
        assert!(quantise(&s, f64::NAN, BackoffReference::Peak).is_err());
        assert!(quantise(&[], 0.0, BackoffReference::Peak).is_err());
        assert!(quantise(&[Complex64::new(0.0, 0.0)], 0.0, BackoffReference::Rms).is_err());
        assert!(quantise(&[Complex64::new(f64::NAN, 0.0)], 0.0, BackoffReference::Rms).is_err());
    }
}
