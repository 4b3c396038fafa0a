//! How a capture is processed: the algorithm and its settings ([`ProcessOptions`]), recorded as
//! `processing` in `summary.json` and the SigMF metadata so a capture can be re-processed
//! identically. Library types only: the CLI maps its own argument enums onto these.

use crate::dsp::FftPrecision;
use crate::dsp::Window;
use crate::waveform::WaveformKind;
use serde::{Deserialize, Serialize};

/// Range-processing algorithm.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
#[derive(strum::VariantArray, strum::IntoStaticStr, strum::EnumMessage)]
#[strum(serialize_all = "kebab-case")]
pub enum Algorithm {
    /// FFT cross-correlation with the transmit signal (any waveform; the MSK-LFM radar).
    Correlation,
    /// OFDM: spectral division and zero-padded IFFT over the subcarriers.
    Fourier,
    /// OFDM: MUSIC pseudo-spectrum (spatial smoothing, forward-backward).
    Music,
    /// OFDM: root-MUSIC, ranges from polynomial roots (no grid).
    RootMusic,
    /// OFDM: ESPRIT, ranges from the shift invariance (no grid).
    Esprit,
}

impl Algorithm {
    /// The algorithms that return ranges without a profile.
    pub(crate) fn is_grid_free(self) -> bool {
        matches!(self, Algorithm::RootMusic | Algorithm::Esprit)
    }

    /// The subspace methods (they need M and p).
    pub(crate) fn is_subspace(self) -> bool {
        matches!(
            self,
            Algorithm::Music | Algorithm::RootMusic | Algorithm::Esprit
        )
    }

    // Which waveforms an algorithm takes, and each waveform's default, are their families' rooms'
    // to say: `Algorithm::supports` and `Algorithm::default_for` are written with the families'
    // table (`family`), which these plain options sit below.
}

named_enum!(Algorithm, "algorithm");

/// Precision of the OFDM receiver's per-symbol FFT; the rest is double.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
#[derive(strum::VariantArray, strum::IntoStaticStr, strum::EnumMessage)]
#[strum(serialize_all = "lowercase")]
pub enum FftPrecisionName {
    /// Single precision (default): rounding ~130 dB under the signal, about twice as fast.
    #[default]
    Single,
    /// Double precision, for noise-free studies that look below -130 dB.
    Double,
}

impl FftPrecisionName {
    pub(crate) fn to_dsp(self) -> FftPrecision {
        match self {
            Self::Single => FftPrecision::Single,
            Self::Double => FftPrecision::Double,
        }
    }
}

named_enum!(FftPrecisionName, "FFT precision");

/// Window on the range processing, trading side-lobes for width.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
#[derive(strum::VariantArray, strum::IntoStaticStr, strum::EnumMessage)]
#[strum(serialize_all = "lowercase")]
pub enum WindowName {
    /// No window (rectangular): narrowest main lobe, -13.3 dB side-lobes.
    #[strum(message = "No window: narrowest main lobe, -13.3 dB side-lobes")]
    #[default]
    Rect,
    Hann,
    /// Taylor, 4 nearly equal side-lobes at -35 dB.
    Taylor,
    /// Dolph-Chebyshev, equal side-lobes at -50 dB.
    Chebyshev,
}

impl WindowName {
    /// The `dsp` window: Taylor nbar 4 at -35 dB, Chebyshev at -50 dB.
    pub(crate) fn to_dsp(self) -> Window {
        match self {
            WindowName::Rect => Window::Rectangular,
            WindowName::Hann => Window::Hann,
            WindowName::Taylor => Window::Taylor {
                nbar: 4,
                sll_db: -35.0,
            },
            WindowName::Chebyshev => Window::Chebyshev { sll_db: -50.0 },
        }
    }
}

named_enum!(WindowName, "window");

/// How targets are told from noise and side-lobes (docs/detection.md measures each).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
#[derive(strum::VariantArray, strum::IntoStaticStr, strum::EnumMessage)]
#[strum(serialize_all = "kebab-case")]
pub enum DetectorName {
    /// CLEAN with the waveform's point spread: subtract each target, search again (default).
    #[default]
    Clean,
    /// CLEAN with a local ordered-statistic noise estimate (noise that varies along the profile).
    #[strum(message = "CLEAN with a local ordered-statistic noise estimate")]
    CleanOs,
    /// Ordered-statistic CFAR (75 % rank), side-lobes masked by the point spread's envelope.
    #[strum(message = "Ordered-statistic CFAR, side-lobes masked by the point spread's envelope")]
    OsCfar,
    /// Cell-averaging CFAR.
    CaCfar,
    /// Greatest-of CFAR (robust at clutter edges, masks close targets).
    #[strum(message = "Greatest-of CFAR")]
    GoCfar,
    /// Smallest-of CFAR.
    SoCfar,
}

impl DetectorName {
    /// The `dsp` method.
    pub(crate) fn to_dsp(self) -> crate::dsp::Method {
        use crate::dsp::{CfarKind, Method, NoiseEstimate};
        let os = CfarKind::Os { rank: 0.75 };
        match self {
            DetectorName::Clean => Method::Clean {
                noise: NoiseEstimate::Global,
            },
            DetectorName::CleanOs => Method::Clean {
                noise: NoiseEstimate::Local(os),
            },
            DetectorName::OsCfar => Method::Cfar { kind: os },
            DetectorName::CaCfar => Method::Cfar { kind: CfarKind::Ca },
            DetectorName::GoCfar => Method::Cfar { kind: CfarKind::Go },
            DetectorName::SoCfar => Method::Cfar { kind: CfarKind::So },
        }
    }
}

named_enum!(DetectorName, "detector");

/// How each target's range is measured (docs/metrology.md).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
#[derive(strum::VariantArray, strum::IntoStaticStr, strum::EnumMessage)]
#[strum(serialize_all = "lowercase")]
pub enum Ranging {
    /// The echo's envelope: the fitted position of its point spread (default).
    #[strum(message = "The echo's envelope (default)")]
    #[default]
    Envelope,
    /// The envelope refined by the echo's carrier phase against the calibrated reference's,
    /// with a reference in the same record (the Tx -> Rx leakage) taking out the trigger's jitter.
    #[strum(
        message = "The envelope refined by the carrier phase against the calibration's \
                       reference (needs a response calibration)"
    )]
    Phase,
}

impl Ranging {
    /// Serde's `skip_serializing_if`: the default is not written (summaries stay as they were).
    pub(crate) fn is_envelope(&self) -> bool {
        *self == Ranging::Envelope
    }
}

named_enum!(Ranging, "ranging");

/// Largest OFDM zero-padding factor accepted (1000 x 128 subcarriers = 128 000 range bins).
pub(crate) const MAX_ZERO_PAD: usize = 1000;

/// MUSIC pseudo-spectrum grid = this factor x subcarriers (12 800 points, 1.17 mm for the thesis'
/// OFDM): MUSIC peaks are far narrower than Fourier ones, and a 1280-point grid (1.17 cm) leaves
/// sub-sample interpolation errors of several millimetres.
pub(crate) const MUSIC_GRID_FACTOR: usize = 100;

/// How to process a capture.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct ProcessOptions {
    pub algorithm: Algorithm,
    /// MUSIC sub-vector length M.
    pub music_m: usize,
    /// Number of targets for MUSIC/root-MUSIC/ESPRIT; `None` = estimated (MDL).
    pub music_p: Option<usize>,
    /// Forward-backward averaging of the MUSIC covariance.
    pub forward_backward: bool,
    /// OFDM Fourier zero padding.
    pub zero_pad: usize,
    pub window: WindowName,
    /// Precision of the OFDM receiver's per-symbol FFT.
    pub fft_precision: FftPrecisionName,
    /// Sub-sample interpolation of peak positions.
    pub interpolate: bool,
    /// Fixed delay of the bench (calibration), seconds.
    pub system_delay_s: f64,
    /// Detections closer than this are ignored (the direct Tx -> Rx leakage sits near 0 m).
    pub min_range_m: f64,
    /// Detections farther than this are ignored.
    pub max_range_m: f64,
    /// The detector of the profile algorithms (the subspace ones give their own estimates).
    pub detector: DetectorName,
    /// Probability of false alarm of the detector, per profile cell.
    pub pfa: f64,
    /// Targets closer than this are not separated, metres (`None`: 0.75 resolution cells).
    pub min_separation_m: Option<f64>,
    /// CLEAN's chain floor, dB under a target whose main lobe does not fit the ideal spread
    /// (docs/detection.md): weaker echoes within 1.6 m of it are its chain's, not targets.
    pub chain_floor_db: f64,
    /// RF carrier of the front ends, Hz: the velocity scale of the OFDM range-Doppler processing.
    pub carrier_hz: f64,
    /// The AWG's I/Q amplitude (peak to peak, volts): echo levels are given relative to a path
    /// of unit voltage gain from the AWG output to the scope input. `None` (simulations): levels
    /// are relative to the transmitted waveform itself.
    pub awg_amplitude_vpp: Option<f64>,
    /// The receive correction applied, and the calibration it came from (`None`: uncorrected).
    pub correction: Option<crate::measure::calibration::correction::CorrectionUsed>,
    /// How each target's range is measured (`envelope` is not written).
    #[serde(skip_serializing_if = "Ranging::is_envelope")]
    pub ranging: Ranging,
    /// The scope's RMS trigger jitter as the bench file states it (`[scope] trigger_jitter_s`),
    /// seconds; `None`: not stated, a typical scope's is assumed
    /// (`ranging::TYPICAL_TRIGGER_JITTER_S`).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub trigger_jitter_s: Option<f64>,
}

impl Default for ProcessOptions {
    fn default() -> Self {
        Self {
            algorithm: Algorithm::Correlation,
            music_m: 64,
            music_p: None,
            forward_backward: true,
            zero_pad: 10,
            window: WindowName::Rect,
            fft_precision: FftPrecisionName::Single,
            interpolate: true,
            system_delay_s: 0.0,
            min_range_m: 0.15,
            max_range_m: 10.0,
            detector: DetectorName::Clean,
            pfa: 1e-6,
            min_separation_m: None,
            chain_floor_db: -17.0,
            carrier_hz: 80e9,
            awg_amplitude_vpp: None,
            correction: None,
            ranging: Ranging::Envelope,
            trigger_jitter_s: None,
        }
    }
}

impl ProcessOptions {
    /// The defaults with the default algorithm of `waveform`.
    pub fn for_waveform(waveform: WaveformKind) -> Self {
        Self {
            algorithm: Algorithm::default_for(waveform),
            ..Self::default()
        }
    }
}
