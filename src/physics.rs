//! Physical constants shared by every layer (a leaf: imports nothing).

/// Speed of light in vacuum, m/s (the thesis rounds it to 3e8).
pub const C0: f64 = 299_792_458.0;
