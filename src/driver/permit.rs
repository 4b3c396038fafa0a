//! The explicit permission to drive outputs or radiate.
//!
//! Architecture rule 9: anything that can radiate or drive an output needs an explicit permit.
//! [`RfPermit`] has a private field and no `Default`, so the only way to get one is to call
//! [`RfPermit::granted_by_user`] — in radbench that happens in exactly one place, where the CLI
//! reads `--allow-rf` (or the campaign file's explicit permission). Output-enabling driver calls
//! take `&RfPermit`, so a code path that forgot to ask the user does not compile.

/// Proof that the user explicitly allowed outputs and RF to be switched on.
#[derive(Debug)]
pub struct RfPermit {
    _private: (),
}

impl RfPermit {
    /// Records the user's explicit decision. Call this only from the place that asked the user
    /// (a command-line flag, a confirmed prompt, a campaign file's explicit permission).
    pub fn granted_by_user() -> RfPermit {
        tracing::info!("RF and output permit granted by the user");
        RfPermit { _private: () }
    }
}
