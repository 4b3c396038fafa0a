//! What processing in memory gives back (a capture of `ProcessRequest`, or of the warm bench
//! session).

use crate::measure::{ProcessOptions, Processed};
use serde_json::Value;

/// One capture (or record of samples) processed: `summary.json` as `radbench process` writes it
/// (but `files`), the arrays behind it and every option used.
#[derive(Debug, Clone)]
pub struct InMemory {
    pub summary: Value,
    pub processed: Processed,
    pub options: ProcessOptions,
}
