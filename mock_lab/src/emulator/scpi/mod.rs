//! IEEE 488.2 and SCPI pieces the emulators parse and answer with: program messages split into
//! units (block- and quote-aware), header matching (long and short forms, optional nodes, numeric
//! suffixes), numeric and keyword parameters, and the error/event queue.

pub mod error_queue;
pub mod header;
pub mod message;
pub mod numeric;
