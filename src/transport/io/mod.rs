//! Shared machinery of the network transports: options, size-aware deadlines, progress reports,
//! and the cancel-safe frame reader.
//!
//! Cancel safety: every await here is either `read_buf` into a buffer the transport owns, or a
//! write. A dropped read therefore loses no bytes (the decoder state and the partial frame stay in
//! the transport); a dropped write may leave half a message on the wire, which is why transports
//! mark themselves dirty before writing and recover (clear or reconnect) before the next operation.
//!
//! One room per job: [`options`](LinkOptions) (timeouts, limits, progress), the decoders' trait and
//! header-plus-payload frames, reading one message, the receive buffers, writing, connecting.

mod buffers;
mod connect;
mod decode;
mod options;
mod read;
mod write;

pub(crate) use buffers::Reassembly;
#[cfg(test)]
pub(crate) use buffers::PRESIZE_LIMIT;
pub use buffers::{buffer_ceiling, reserve_announced, reserve_within};
pub(crate) use connect::connect_tcp;
#[cfg(test)]
pub(crate) use decode::decode_chunks;
pub use decode::{Decode, FrameHeader, Framed, FramedDecoder};
pub use options::{Direction, LinkOptions, Progress, ProgressFn, Timeouts};
pub(crate) use read::ReadContext;
pub(crate) use write::{io_error, write_parts};
