//! The spectral-division matrix `I_div` the receiver fills and the estimators read.

use num_complex::Complex64;

/// The spectral-division matrix `I_div`, symbol-major, subcarriers in ascending frequency.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct IDiv {
    pub(super) symbols: usize,
    pub(super) subcarriers: usize,
    pub(super) data: Vec<Complex64>,
}

impl IDiv {
    /// An empty matrix; [`OfdmRadar::divide`](super::OfdmRadar::divide) sizes it (and reuses its storage afterwards).
    pub fn new() -> Self {
        Self::default()
    }

    pub fn symbols(&self) -> usize {
        self.symbols
    }

    pub fn subcarriers(&self) -> usize {
        self.subcarriers
    }

    /// All values, symbol-major (what `Music::estimate` takes).
    pub fn as_slice(&self) -> &[Complex64] {
        &self.data
    }

    /// The N values of one symbol (the thesis' "column" of I_div), ascending frequency.
    pub fn symbol(&self, s: usize) -> &[Complex64] {
        &self.data[s * self.subcarriers..(s + 1) * self.subcarriers]
    }

    pub(super) fn resize(&mut self, symbols: usize, subcarriers: usize) {
        self.symbols = symbols;
        self.subcarriers = subcarriers;
        self.data
            .resize(symbols * subcarriers, Complex64::default());
    }
}
