//! Protocol servers. Each binds 127.0.0.1 (port 0 in tests), reports its address, serves several
//! clients at once, and hands whole messages to a pluggable [`Handler`].

/// What an emulated instrument does with whole messages. Servers frame bytes into messages
/// (terminator outside `#N` blocks, VXI-11 END, HiSLIP DataEnd, VICP EOI) and call these methods
/// from a blocking thread, so a handler may block (for example a scope's `WAIT`).
pub trait Handler: Send + Sync + 'static {
    /// One whole program message from a client. Returns the whole response messages it produced,
    /// in order (empty for commands that answer nothing). A response carries no transport framing;
    /// the raw-socket server appends the newline terminator itself when the response lacks one.
    fn message(&self, data: &[u8]) -> Vec<Vec<u8>>;
    /// IEEE 488.2 device clear: abandon pending input and output.
    fn device_clear(&self) {}
    /// The status byte, for serial polls (HiSLIP AsyncStatusQuery, VXI-11 device_readstb, VICP).
    fn status_byte(&self) -> u8 {
        0
    }
    /// A group-execute trigger (VXI-11 device_trigger, HiSLIP Trigger).
    fn trigger(&self) {}
}
