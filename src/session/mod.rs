//! Layer 2: IEEE 488.2 / SCPI sessions on a transport.
