//! One bench measurement: configure, arm, capture, decimate, align, process.
