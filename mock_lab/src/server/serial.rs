//! serial server (in progress).
