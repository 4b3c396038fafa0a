//! Layer 1: transports that move whole messages.
