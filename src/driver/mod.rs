//! Layer 3: capability traits and the concrete instrument drivers.
