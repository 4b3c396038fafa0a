//! The user-facing names of the processing choices (`--algorithm`, `--window`, `--fft-precision`),
//! shared by `simulate`, `measure` and the CLI, and the `dsp` settings they stand for.

use crate::dsp::ofdm_radar::FftPrecision;
use crate::dsp::window::Window;
use serde::Serialize;

/// Range-processing algorithm.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum, Serialize)]
#[serde(rename_all = "kebab-case")]
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
    pub fn name(self) -> &'static str {
        match self {
            Algorithm::Correlation => "correlation",
            Algorithm::Fourier => "fourier",
            Algorithm::Music => "music",
            Algorithm::RootMusic => "root-music",
            Algorithm::Esprit => "esprit",
        }
    }

    /// The algorithms that return ranges without a profile.
    pub fn is_grid_free(self) -> bool {
        matches!(self, Algorithm::RootMusic | Algorithm::Esprit)
    }
}

/// Precision of the OFDM receiver's per-symbol FFT (`--fft-precision`); the rest is double.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, clap::ValueEnum, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum FftPrecisionName {
    /// Single precision (default): rounding ~130 dB under the signal, about twice as fast.
    #[default]
    Single,
    /// Double precision, for noise-free studies that look below -130 dB.
    Double,
}

impl FftPrecisionName {
    pub fn to_dsp(self) -> FftPrecision {
        match self {
            Self::Single => FftPrecision::Single,
            Self::Double => FftPrecision::Double,
        }
    }
}

/// Window on the subcarriers before the range IFFT (OFDM Fourier), trading side-lobes for width.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum WindowName {
    /// No window (rectangular): narrowest main lobe, -13.3 dB side-lobes.
    Rect,
    Hann,
    /// Taylor, 4 nearly equal side-lobes at -35 dB.
    Taylor,
    /// Dolph-Chebyshev, equal side-lobes at -50 dB.
    Chebyshev,
}

/// Maps a CLI window name to its `dsp` window: Taylor nbar 4 at -35 dB, Chebyshev at -50 dB.
impl WindowName {
    pub fn to_dsp(self) -> Window {
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
