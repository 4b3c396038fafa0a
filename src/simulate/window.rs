//! The `--window` names and the `dsp` windows they stand for.

use super::spec::WindowName;
use crate::dsp::window::Window;

/// Maps a CLI window name to its `dsp` window: Taylor nbar 4 at -35 dB, Chebyshev at -50 dB.
pub fn to_dsp(name: WindowName) -> Window {
    match name {
        WindowName::Rect => Window::Rectangular,
        WindowName::Hann => Window::Hann,
        WindowName::Taylor => Window::Taylor {
            nbar: 4,
            sll_db: -35.0,
        },
        WindowName::Chebyshev => Window::Chebyshev { sll_db: -50.0 },
    }
}
