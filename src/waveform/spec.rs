//! What to transmit, as plain data: the waveform and its parameters ([`WaveformSpec`]), shared by
//! simulations, bench captures and campaign specs (TOML).
//!
//! Defaults are the thesis' (Tables 4.1 and 4.2 as read in the README): MSK-LFM 1 GHz, 10 us, 128
//! bits at 16 GSa/s; OFDM 128 QPSK subcarriers over 1 GHz, 16x oversampling (16 GSa/s), cyclic
//! prefix 1/4, 100 symbols of which 1 is a known preamble.

use super::msk_lfm::{MskLfmParams, PulseLength};
use super::ParamError;
use serde::{Deserialize, Serialize};

/// Which waveform, with its parameters.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "kebab-case", deny_unknown_fields)]
pub enum WaveformSpec {
    MskLfm {
        /// Samples per second (the AWG's playback rate).
        sample_rate_hz: f64,
        /// Chirp sweep width B.
        bandwidth_hz: f64,
        /// One pulse, seconds (a whole number of samples).
        pulse_s: f64,
        /// MSK bits per pulse (even).
        bits_per_pulse: usize,
        /// Where the sweep lies in baseband: -B/2 .. +B/2 (default) or 0 .. B as the thesis'
        /// equation (2.4) has it. Written only when not the default, so older files read the same.
        #[serde(default, skip_serializing_if = "SweepBand::is_centred")]
        band: SweepBand,
    },
    Ofdm {
        /// Occupied bandwidth B = N df.
        bandwidth_hz: f64,
        /// Subcarriers N (even).
        subcarriers: usize,
        /// Sample rate = oversampling x bandwidth.
        oversampling: usize,
        /// Cyclic prefix as a fraction of the useful symbol.
        cp_fraction: f64,
        /// Symbols per frame, preamble included.
        symbols: usize,
        /// Known symbols at the start of the frame for the communication receiver's channel
        /// estimate (the radar knows every symbol).
        #[serde(default = "default_preamble")]
        preamble_symbols: usize,
    },
}

fn default_preamble() -> usize {
    1
}

impl std::str::FromStr for SweepBand {
    type Err = String;

    /// One of [`SweepBand::NAMES`], as TOML spells it.
    fn from_str(name: &str) -> Result<Self, String> {
        match name {
            "centred" => Ok(SweepBand::Centred),
            "upper" => Ok(SweepBand::Upper),
            "lower" => Ok(SweepBand::Lower),
            _ => Err(format!(
                "'{name}' is not a sweep band; allowed: {}",
                SweepBand::NAMES.join(", ")
            )),
        }
    }
}

/// Where an MSK-LFM chirp sweeps, relative to the carrier.
///
/// The thesis' chirp (its equation 2.4) starts at the carrier and sweeps B above it, while its
/// OFDM subcarriers are centred on the carrier: the two waveforms met different parts of the
/// chain's response. `upper` reproduces the thesis' sweep.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum SweepBand {
    /// -B/2 .. +B/2 around the carrier.
    #[default]
    Centred,
    /// 0 .. B above the carrier (the thesis' equation 2.4).
    Upper,
    /// -B .. 0 below the carrier.
    Lower,
}

impl SweepBand {
    pub const NAMES: [&'static str; 3] = ["centred", "upper", "lower"];

    pub fn is_centred(&self) -> bool {
        *self == SweepBand::Centred
    }

    pub fn name(self) -> &'static str {
        match self {
            SweepBand::Centred => "centred",
            SweepBand::Upper => "upper",
            SweepBand::Lower => "lower",
        }
    }

    /// The sweep's centre for a bandwidth `b`, Hz.
    pub fn centre_hz(self, b: f64) -> f64 {
        match self {
            SweepBand::Centred => 0.0,
            SweepBand::Upper => b / 2.0,
            SweepBand::Lower => -b / 2.0,
        }
    }
}

/// The waveform family, without parameters.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
#[derive(strum::VariantArray, strum::IntoStaticStr, strum::EnumMessage)]
#[strum(serialize_all = "kebab-case")]
pub enum WaveformKind {
    /// MSK-LFM: a chirp carrying MSK bits (thesis Table 4.1: 1 GHz, 10 us, 128 bits).
    MskLfm,
    /// OFDM: QPSK subcarriers (thesis Table 4.2: 128 over 1 GHz, 100 symbols).
    Ofdm,
}

impl WaveformKind {
    /// The thesis' parameters of this family.
    pub fn thesis_default(self) -> WaveformSpec {
        match self {
            WaveformKind::MskLfm => WaveformSpec::msk_lfm_default(),
            WaveformKind::Ofdm => WaveformSpec::ofdm_default(),
        }
    }
}

named_enum!(WaveformKind, "waveform");

impl WaveformSpec {
    /// Thesis Table 4.1: 16 GSa/s, 1 GHz, 10 us, 128 bits.
    pub fn msk_lfm_default() -> Self {
        WaveformSpec::MskLfm {
            sample_rate_hz: 16e9,
            bandwidth_hz: 1e9,
            pulse_s: 10e-6,
            bits_per_pulse: 128,
            band: SweepBand::Centred,
        }
    }

    /// Thesis Table 4.2: 128 subcarriers, 1 GHz, x16, CP 1/4, 100 symbols (1 preamble).
    pub fn ofdm_default() -> Self {
        WaveformSpec::Ofdm {
            bandwidth_hz: 1e9,
            subcarriers: 128,
            oversampling: 16,
            cp_fraction: 0.25,
            symbols: 100,
            preamble_symbols: 1,
        }
    }

    pub fn kind(&self) -> WaveformKind {
        match self {
            WaveformSpec::MskLfm { .. } => WaveformKind::MskLfm,
            WaveformSpec::Ofdm { .. } => WaveformKind::Ofdm,
        }
    }

    pub fn name(&self) -> &'static str {
        self.kind().name()
    }

    pub fn bandwidth_hz(&self) -> f64 {
        match *self {
            WaveformSpec::MskLfm { bandwidth_hz, .. } | WaveformSpec::Ofdm { bandwidth_hz, .. } => {
                bandwidth_hz
            }
        }
    }

    /// The highest baseband frequency the waveform occupies, Hz (`|f0| + B/2`): what the
    /// decimator's pass band must keep.
    pub fn band_edge_hz(&self) -> f64 {
        match *self {
            WaveformSpec::MskLfm {
                bandwidth_hz, band, ..
            } => band.centre_hz(bandwidth_hz).abs() + bandwidth_hz / 2.0,
            WaveformSpec::Ofdm { bandwidth_hz, .. } => bandwidth_hz / 2.0,
        }
    }

    /// The band the waveform occupies in baseband, `[low, high]` Hz.
    pub(crate) fn band_hz(&self) -> [f64; 2] {
        let b = self.bandwidth_hz();
        let f0 = self.sweep_band().map_or(0.0, |band| band.centre_hz(b));
        [f0 - b / 2.0, f0 + b / 2.0]
    }

    /// This spec with an MSK-LFM sweep in `band` (OFDM is returned as it is: it is always centred).
    pub fn with_sweep_band(mut self, band: SweepBand) -> Self {
        if let WaveformSpec::MskLfm { band: b, .. } = &mut self {
            *b = band;
        }
        self
    }

    /// The MSK-LFM sweep's band (`None` for OFDM).
    pub fn sweep_band(&self) -> Option<SweepBand> {
        match *self {
            WaveformSpec::MskLfm { band, .. } => Some(band),
            WaveformSpec::Ofdm { .. } => None,
        }
    }

    /// The waveform's own sample rate (the AWG rate), Hz.
    pub fn sample_rate_hz(&self) -> f64 {
        match *self {
            WaveformSpec::MskLfm { sample_rate_hz, .. } => sample_rate_hz,
            WaveformSpec::Ofdm {
                bandwidth_hz,
                oversampling,
                ..
            } => bandwidth_hz * oversampling as f64,
        }
    }

    /// This spec with another bandwidth, keeping the sample rate: an OFDM frame changes its
    /// oversampling (which must stay whole), an MSK-LFM pulse its sweep.
    pub(crate) fn with_bandwidth(&self, bandwidth_hz: f64) -> Result<Self, ParamError> {
        let fs = self.sample_rate_hz();
        if !(bandwidth_hz.is_finite() && bandwidth_hz > 0.0 && bandwidth_hz <= fs) {
            return Err(ParamError::out_of_range(
                "bandwidth",
                format!("{bandwidth_hz:?} Hz"),
                &format!(
                    "must be a positive frequency in Hz up to the sample rate ({fs:e} Sa/s), \
                     e.g. 1e9 or 2e9"
                ),
            ));
        }
        Ok(match *self {
            WaveformSpec::MskLfm {
                sample_rate_hz,
                pulse_s,
                bits_per_pulse,
                band,
                ..
            } => WaveformSpec::MskLfm {
                sample_rate_hz,
                bandwidth_hz,
                pulse_s,
                bits_per_pulse,
                band,
            },
            WaveformSpec::Ofdm {
                subcarriers,
                cp_fraction,
                symbols,
                preamble_symbols,
                ..
            } => {
                let fs = self.sample_rate_hz();
                let ratio = fs / bandwidth_hz;
                let oversampling = ratio.round();
                if (ratio - oversampling).abs() > 1e-9 * ratio || oversampling < 1.0 {
                    return Err(ParamError::out_of_range(
                        "bandwidth",
                        format!("{bandwidth_hz} Hz"),
                        &format!(
                            "the OFDM sample rate {fs} Sa/s must be a whole multiple of the \
                             bandwidth (e.g. 1e9, 2e9, 4e9 at 16 GSa/s)"
                        ),
                    ));
                }
                WaveformSpec::Ofdm {
                    bandwidth_hz,
                    subcarriers,
                    oversampling: oversampling as usize,
                    cp_fraction,
                    symbols,
                    preamble_symbols,
                }
            }
        })
    }

    /// The MSK-LFM generator parameters (`None` for OFDM).
    pub(crate) fn msk_lfm_params(&self) -> Option<MskLfmParams> {
        match *self {
            WaveformSpec::MskLfm {
                sample_rate_hz,
                bandwidth_hz,
                pulse_s,
                bits_per_pulse,
                band,
            } => Some(MskLfmParams {
                sample_rate_hz,
                bandwidth_hz,
                centre_hz: band.centre_hz(bandwidth_hz),
                pulse: PulseLength::Seconds(pulse_s),
                bits_per_pulse,
            }),
            WaveformSpec::Ofdm { .. } => None,
        }
    }

    /// Samples of one repetition (pulse or frame) at the waveform rate, without building the
    /// waveform; the generators check the parameters themselves.
    pub(crate) fn samples_per_repetition(&self) -> Result<usize, ParamError> {
        match *self {
            WaveformSpec::MskLfm { .. } => self
                .msk_lfm_params()
                .expect("an MSK-LFM spec")
                .samples_per_pulse(),
            WaveformSpec::Ofdm {
                subcarriers,
                oversampling,
                cp_fraction,
                symbols,
                ..
            } => {
                let fft = subcarriers as f64 * oversampling as f64;
                let per_symbol = fft + (cp_fraction * fft).round();
                let total = per_symbol * symbols as f64;
                if !(total.is_finite() && total >= 1.0) {
                    return Err(ParamError::out_of_range(
                        "OFDM frame",
                        format!("{total} samples"),
                        "must hold at least one sample",
                    ));
                }
                Ok(total as usize)
            }
        }
    }

    /// Ranges this waveform can measure without ambiguity: MSK-LFM, an echo within one pulse;
    /// OFDM, `c0 / (2 df)` (19.2 m by default).
    pub(crate) fn max_range_m(&self) -> f64 {
        use crate::physics::C0;
        match *self {
            WaveformSpec::MskLfm { pulse_s, .. } => C0 * pulse_s / 2.0,
            WaveformSpec::Ofdm {
                bandwidth_hz,
                subcarriers,
                ..
            } => match subcarriers {
                0 => f64::INFINITY,
                n => C0 / (2.0 * bandwidth_hz / n as f64),
            },
        }
    }

    /// What bounds [`max_range_m`](Self::max_range_m), for messages.
    pub(crate) fn max_range_reason(&self) -> &'static str {
        match self {
            WaveformSpec::MskLfm { .. } => "the echo must start within one pulse length",
            WaveformSpec::Ofdm { .. } => "the unambiguous range c0 / (2 df)",
        }
    }

    /// OFDM: ranges beyond which the echo is longer than the cyclic prefix (inter-symbol
    /// interference); `None` for MSK-LFM.
    pub(crate) fn cp_range_m(&self) -> Option<f64> {
        match *self {
            WaveformSpec::Ofdm {
                bandwidth_hz,
                subcarriers,
                cp_fraction,
                ..
            } => Some(crate::physics::C0 * cp_fraction * subcarriers as f64 / bandwidth_hz / 2.0),
            WaveformSpec::MskLfm { .. } => None,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn toml_round_trip_with_defaulted_preamble() {
        #[derive(Deserialize)]
        struct Doc {
            waveform: WaveformSpec,
        }
        let doc: Doc = toml::from_str(
            "[waveform]\nkind = \"ofdm\"\nbandwidth_hz = 1e9\nsubcarriers = 128\noversampling = 16\n\
             cp_fraction = 0.25\nsymbols = 100\n",
        )
        .unwrap();
        assert_eq!(doc.waveform, WaveformSpec::ofdm_default());
        let err = toml::from_str::<Doc>("[waveform]\nkind = \"msk-lfm\"\nbandwidth = 1\n")
            .err()
            .unwrap();
        assert!(err.to_string().contains("bandwidth"), "{err}");
    }

    #[test]
    fn bandwidth_change_keeps_the_rate() {
        let two = WaveformSpec::ofdm_default().with_bandwidth(2e9).unwrap();
        assert_eq!(two.sample_rate_hz(), 16e9);
        assert!(matches!(
            two,
            WaveformSpec::Ofdm {
                oversampling: 8,
                ..
            }
        ));
        assert!(WaveformSpec::ofdm_default().with_bandwidth(3e9).is_err());
        let msk = WaveformSpec::msk_lfm_default().with_bandwidth(2e9).unwrap();
        assert_eq!(msk.bandwidth_hz(), 2e9);
        assert_eq!(msk.samples_per_repetition().unwrap(), 160_000);
        assert_eq!(
            WaveformSpec::ofdm_default()
                .samples_per_repetition()
                .unwrap(),
            256_000
        );
    }
}
