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
    manual_front_ends_confirmed: bool,
}

impl RfPermit {
    /// Records the user's explicit decision. Call this only from the place that asked the user
    /// (a command-line flag, a confirmed prompt, a campaign file's explicit permission).
    pub fn granted_by_user() -> RfPermit {
        tracing::info!("RF and output permit granted by the user");
        RfPermit {
            manual_front_ends_confirmed: false,
        }
    }

    /// Records that the operator set the bench's manual front ends (`driver = "manual"`) by
    /// hand and confirmed it. Call this only where the operator confirmed (the command line's
    /// typed `yes`, Python's `manual_front_ends_confirmed=True`): a measurement on a bench with
    /// manual front ends is refused without it.
    pub fn with_manual_front_ends_confirmed(self) -> RfPermit {
        tracing::info!("manual front ends confirmed by the operator");
        RfPermit {
            manual_front_ends_confirmed: true,
        }
    }

    /// Whether the operator confirmed the manual front ends' settings.
    pub fn manual_front_ends_confirmed(&self) -> bool {
        self.manual_front_ends_confirmed
    }
}
