//! A waveform as users ask for it: the thesis' defaults with some parameters changed. The command
//! line (`--bandwidth`, ...) and campaign specs (`[waveform] bandwidth_hz`, ...) both go through
//! [`WaveformOverrides::apply`], so the two accept and refuse exactly the same things; each names
//! the field in its own spelling ([`OverrideError::field`]). What each family takes and how it
//! applies them is its room's ([`Family::apply`](super::Family::apply)).

use crate::waveform::SweepBand;

/// Largest number of samples one repetition may have: the AWG could hold more (16 G samples),
/// but beyond this it fits neither the scope's record nor the host usefully.
pub(crate) const MAX_SAMPLES_PER_REPETITION: f64 = 64e6;

/// Parameters changed from the thesis' defaults; `None` keeps the default. A new family's
/// parameters are added here (and to the command line's and the campaign spec's waveform options).
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub(crate) struct WaveformOverrides {
    /// Both families. For OFDM without `oversampling` the sample rate stays and the
    /// oversampling follows (the rate must then be a whole multiple of the bandwidth).
    pub bandwidth_hz: Option<f64>,
    /// MSK-LFM only.
    pub sample_rate_hz: Option<f64>,
    /// MSK-LFM only.
    pub pulse_s: Option<f64>,
    /// MSK-LFM only.
    pub bits_per_pulse: Option<usize>,
    /// MSK-LFM only: where the sweep lies (`centred`, `upper`, `lower`).
    pub band: Option<SweepBand>,
    /// OFDM only.
    pub subcarriers: Option<usize>,
    /// OFDM only.
    pub oversampling: Option<usize>,
    /// OFDM only.
    pub cp_fraction: Option<f64>,
    /// OFDM only.
    pub symbols: Option<usize>,
    /// OFDM only.
    pub preamble_symbols: Option<usize>,
}

/// A parameter that cannot be applied; [`field`](Self::field) is the parameter's name as in
/// [`WaveformOverrides`].
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub(crate) enum OverrideError {
    #[error("{value}: must be a positive number of {unit}")]
    NotPositive {
        field: &'static str,
        value: f64,
        unit: &'static str,
    },
    #[error("applies to {applies_to} only; this waveform is {kind}")]
    Misapplied {
        field: &'static str,
        /// The families that take it (`MSK-LFM`, `OFDM`).
        applies_to: String,
        kind: &'static str,
    },
    #[error(
        "{bandwidth_hz}: OFDM keeps its sample rate of {rate_hz} Sa/s, which must be a whole \
         multiple of the bandwidth (e.g. 1e9, 2e9, 4e9); or give the oversampling too"
    )]
    BandwidthNotDivisor { bandwidth_hz: f64, rate_hz: f64 },
    #[error(
        "one repetition of {samples:.3e} samples; allowed at most {MAX_SAMPLES_PER_REPETITION:.0e} \
         samples per repetition"
    )]
    TooLong {
        /// The parameters whose product it is.
        field: &'static str,
        samples: f64,
    },
    #[error("{value:?}: {allowed}")]
    OutOfRange {
        field: &'static str,
        value: f64,
        allowed: &'static str,
    },
}

impl OverrideError {
    /// The parameter (or, for a repetition too long, the parameters) to blame.
    pub(crate) fn field(&self) -> &'static str {
        match self {
            OverrideError::NotPositive { field, .. }
            | OverrideError::Misapplied { field, .. }
            | OverrideError::TooLong { field, .. }
            | OverrideError::OutOfRange { field, .. } => field,
            OverrideError::BandwidthNotDivisor { .. } => "bandwidth_hz",
        }
    }
}

impl WaveformOverrides {
    // `WaveformOverrides::apply` (these parameters on the thesis' waveform of a kind) asks the
    // families' table which family takes which field: it is written with the table (`family`),
    // which these plain overrides sit below.

    /// The checks of the values given that hold for every family: lengths and rates positive,
    /// the cyclic prefix shorter than the symbol.
    pub(super) fn check_values(&self) -> Result<(), OverrideError> {
        for (value, field, unit) in [
            (self.bandwidth_hz, "bandwidth_hz", "Hz"),
            (self.sample_rate_hz, "sample_rate_hz", "Sa/s"),
            (self.pulse_s, "pulse_s", "seconds"),
        ] {
            if let Some(x) = value {
                if !(x.is_finite() && x > 0.0) {
                    return Err(OverrideError::NotPositive {
                        field,
                        value: x,
                        unit,
                    });
                }
            }
        }
        // Checked here, before it multiplies into the repetition's length (and is blamed on
        // the others).
        if let Some(cp) = self.cp_fraction {
            if !(cp.is_finite() && (0.0..1.0).contains(&cp)) {
                return Err(OverrideError::OutOfRange {
                    field: "cp_fraction",
                    value: cp,
                    allowed: "at least 0 and below 1 (the cyclic prefix shorter than the symbol)",
                });
            }
        }
        Ok(())
    }

    /// Every field by name (as [`OverrideError::field`] names it), and whether it is given.
    pub(super) fn given(&self) -> [(&'static str, bool); 10] {
        [
            ("bandwidth_hz", self.bandwidth_hz.is_some()),
            ("sample_rate_hz", self.sample_rate_hz.is_some()),
            ("pulse_s", self.pulse_s.is_some()),
            ("bits_per_pulse", self.bits_per_pulse.is_some()),
            ("band", self.band.is_some()),
            ("subcarriers", self.subcarriers.is_some()),
            ("oversampling", self.oversampling.is_some()),
            ("cp_fraction", self.cp_fraction.is_some()),
            ("symbols", self.symbols.is_some()),
            ("preamble_symbols", self.preamble_symbols.is_some()),
        ]
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::waveform::WaveformKind;

    #[test]
    fn nothing_given_is_the_thesis_waveform() {
        for kind in [WaveformKind::MskLfm, WaveformKind::Ofdm] {
            assert_eq!(
                WaveformOverrides::default().apply(kind),
                Ok(kind.thesis_default())
            );
        }
    }

    #[test]
    fn ofdm_bandwidth_keeps_the_rate_unless_the_oversampling_is_given() {
        let two = WaveformOverrides {
            bandwidth_hz: Some(2e9),
            ..Default::default()
        };
        let spec = two.apply(WaveformKind::Ofdm).unwrap();
        assert_eq!(spec.sample_rate_hz(), 16e9);
        let odd = WaveformOverrides {
            bandwidth_hz: Some(3e9),
            ..Default::default()
        };
        assert_eq!(
            odd.apply(WaveformKind::Ofdm).unwrap_err().field(),
            "bandwidth_hz"
        );
        let with_os = WaveformOverrides {
            oversampling: Some(4),
            ..odd
        };
        assert_eq!(
            with_os.apply(WaveformKind::Ofdm).unwrap().sample_rate_hz(),
            12e9
        );
    }

    #[test]
    fn a_parameter_of_the_other_family_or_too_large_is_named() {
        let cp = WaveformOverrides {
            cp_fraction: Some(0.5),
            ..Default::default()
        };
        let err = cp.apply(WaveformKind::MskLfm).unwrap_err();
        assert_eq!(err.field(), "cp_fraction");
        assert_eq!(
            err.to_string(),
            "applies to OFDM only; this waveform is msk-lfm"
        );
        let band = WaveformOverrides {
            band: Some(SweepBand::Upper),
            ..Default::default()
        };
        assert_eq!(
            band.apply(WaveformKind::Ofdm).unwrap_err().to_string(),
            "applies to MSK-LFM only; this waveform is ofdm"
        );
        let long = WaveformOverrides {
            pulse_s: Some(1.0),
            ..Default::default()
        };
        assert!(matches!(
            long.apply(WaveformKind::MskLfm),
            Err(OverrideError::TooLong {
                field: "pulse_s",
                ..
            })
        ));
        let negative = WaveformOverrides {
            bandwidth_hz: Some(-1.0),
            ..Default::default()
        };
        assert_eq!(
            negative.apply(WaveformKind::Ofdm).unwrap_err().field(),
            "bandwidth_hz"
        );
    }
}
