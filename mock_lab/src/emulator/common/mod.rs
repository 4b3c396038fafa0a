//! Pieces shared by the emulators: the bounded log of received messages, IEEE 488.2 message
//! splitting (block- and quote-aware), SCPI header matching, numeric parameters and the error queue.

pub mod error_queue;
pub mod log;
pub mod message;
pub mod numeric;
pub mod scpi_header;
