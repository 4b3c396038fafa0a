//! A generic test instrument for transport tests: identity, block store and echo, slow replies.
