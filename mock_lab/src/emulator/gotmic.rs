//! Gotmic E-band Tx/Rx emulators (project-defined serial protocol, instruments.md section 5).
