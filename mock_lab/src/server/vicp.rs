//! vicp server (in progress).
