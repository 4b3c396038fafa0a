//! Polyphase FIR decimation with a designed anti-alias low-pass, usable in chunks.
