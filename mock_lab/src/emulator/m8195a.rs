//! Keysight M8195A emulator.
