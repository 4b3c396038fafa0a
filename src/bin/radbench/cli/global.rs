//! What every subcommand shares: the global options and the runtime for instrument I/O. Its own
//! room, so that the subcommands need not import their parent (`cli`), which imports them.

use std::path::PathBuf;

/// Options every subcommand can see.
#[derive(Debug, Clone, Default)]
pub struct Global {
    pub trace_io: Option<PathBuf>,
}

/// A tokio runtime for the subcommands that talk to instruments.
pub fn runtime() -> anyhow::Result<tokio::runtime::Runtime> {
    Ok(tokio::runtime::Builder::new_multi_thread()
        .enable_all()
        .build()?)
}
