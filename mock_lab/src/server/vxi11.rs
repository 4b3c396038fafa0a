//! vxi11 server (in progress).
