//! IEEE 488.2 and SCPI pieces the emulators parse and answer with: program messages split into
//! units (block- and quote-aware), header matching (long and short forms, optional nodes, numeric
//! suffixes), numeric and keyword parameters, and the error/event queue.

pub(crate) mod error_queue;
pub(crate) mod header;
pub(crate) mod message;
pub(crate) mod numeric;
