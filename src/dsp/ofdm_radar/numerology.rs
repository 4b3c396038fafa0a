//! The OFDM numerology (subcarriers, oversampling, cyclic prefix, bandwidth), checked once here:
//! the radar receiver ([`OfdmRadarConfig`](super::OfdmRadarConfig)) and the waveform's generator
//! (`waveform::ofdm::Ofdm::new`) both ask [`Numerology::check`] and each words the [`Fault`] in its
//! own messages. Rules only one of them needs (the generator's even subcarrier count, the radar's
//! zero padding and window) stay with it.

/// Largest useful symbol (`subcarriers * oversampling`) in samples.
const MAX_FFT_LEN: usize = 1 << 28;

/// The numbers both ends of an OFDM link must agree on.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct Numerology {
    pub(crate) subcarriers: usize,
    pub(crate) oversampling: usize,
    pub(crate) cp_fraction: f64,
    pub(crate) bandwidth_hz: f64,
}

/// The first rule a [`Numerology`] breaks, in the order they are checked.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) enum Fault {
    /// Fewer than 2 subcarriers.
    Subcarriers,
    /// The bandwidth is not positive and finite.
    Bandwidth,
    /// Oversampling 0.
    Oversampling,
    /// `subcarriers * oversampling` above [`MAX_FFT_LEN`] (or overflowing).
    SymbolTooLong,
    /// The cyclic prefix is not in `[0, 1)` of the symbol.
    CpFraction,
    /// The cyclic prefix is not a whole number of samples: `samples` of a `fft_len` symbol.
    CpNotWhole { samples: f64, fft_len: usize },
}

/// The sizes a valid numerology gives, samples.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) struct Sizes {
    /// The useful symbol, `subcarriers * oversampling` (the FFT size).
    pub(crate) fft_len: usize,
    /// The cyclic prefix.
    pub(crate) cp_len: usize,
}

impl Numerology {
    /// Checks every shared rule (first failure reported) and returns the symbol's sizes.
    pub(crate) fn check(&self) -> Result<Sizes, Fault> {
        let n = self.subcarriers;
        if n < 2 {
            return Err(Fault::Subcarriers);
        }
        let b = self.bandwidth_hz;
        if !(b.is_finite() && b > 0.0) {
            return Err(Fault::Bandwidth);
        }
        let os = self.oversampling;
        if os == 0 {
            return Err(Fault::Oversampling);
        }
        let fft_len = n
            .checked_mul(os)
            .filter(|&l| l <= MAX_FFT_LEN)
            .ok_or(Fault::SymbolTooLong)?;
        let cp = self.cp_fraction;
        if !(cp.is_finite() && (0.0..1.0).contains(&cp)) {
            return Err(Fault::CpFraction);
        }
        let samples = cp * fft_len as f64;
        let cp_len = samples.round() as usize;
        if (samples - cp_len as f64).abs() > 1e-9 * fft_len as f64 {
            return Err(Fault::CpNotWhole { samples, fft_len });
        }
        Ok(Sizes { fft_len, cp_len })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_first_broken_rule_is_named() {
        let ok = Numerology {
            subcarriers: 128,
            oversampling: 16,
            cp_fraction: 0.25,
            bandwidth_hz: 1e9,
        };
        assert_eq!(
            ok.check(),
            Ok(Sizes {
                fft_len: 2048,
                cp_len: 512
            })
        );
        let bad = |edit: fn(&mut Numerology)| {
            let mut n = ok;
            edit(&mut n);
            n.check().unwrap_err()
        };
        assert_eq!(bad(|n| n.subcarriers = 1), Fault::Subcarriers);
        assert_eq!(bad(|n| n.bandwidth_hz = f64::NAN), Fault::Bandwidth);
        assert_eq!(bad(|n| n.oversampling = 0), Fault::Oversampling);
        assert_eq!(bad(|n| n.oversampling = usize::MAX), Fault::SymbolTooLong);
        assert_eq!(bad(|n| n.cp_fraction = 1.0), Fault::CpFraction);
        assert!(matches!(
            bad(|n| n.cp_fraction = 0.3),
            Fault::CpNotWhole { fft_len: 2048, .. }
        ));
        // An odd count is the generator's own rule, not a shared one.
        assert!(Numerology {
            subcarriers: 7,
            oversampling: 2,
            cp_fraction: 0.0,
            bandwidth_hz: 1e9
        }
        .check()
        .is_ok());
    }
}
