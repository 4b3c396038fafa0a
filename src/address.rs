//! VISA-style resource strings (see the transport layer).
