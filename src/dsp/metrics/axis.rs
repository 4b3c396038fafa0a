//! The uniform axis every metric is measured on.

/// A uniform axis: `x(i) = start + i * step`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Axis {
    pub start: f64,
    pub step: f64,
}

impl Axis {
    /// The axis position of a (fractional) sample index.
    pub fn at(&self, index: f64) -> f64 {
        self.start + index * self.step
    }

    /// Infers the axis from a sampled, uniform axis vector (at least two points, else step 1).
    pub fn from_samples(x: &[f64]) -> Self {
        match x {
            [] => Axis {
                start: 0.0,
                step: 1.0,
            },
            [a] => Axis {
                start: *a,
                step: 1.0,
            },
            [a, .., b] => Axis {
                start: *a,
                step: (b - a) / (x.len() - 1) as f64,
            },
        }
    }
}
