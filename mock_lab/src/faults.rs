//! Faults the tests can switch on.
