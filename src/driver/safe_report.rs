//! What the safe-state sequence did, step by step: the report every exit path returns and an
//! error can carry (a file of its own so that `error` does not depend on the sequence itself).

/// One step of the sequence and how it went.
#[derive(Debug, Clone, PartialEq, Eq, serde::Serialize)]
pub struct SafeStep {
    pub step: &'static str,
    /// `None` when the step succeeded, else what went wrong.
    pub error: Option<String>,
}

/// What the safe-state sequence did.
#[derive(Debug, Clone, Default, PartialEq, Eq, serde::Serialize)]
pub struct SafeStateReport {
    pub steps: Vec<SafeStep>,
}

impl SafeStateReport {
    /// Whether every step succeeded.
    pub fn is_safe(&self) -> bool {
        self.steps.iter().all(|s| s.error.is_none())
    }
}

impl std::fmt::Display for SafeStateReport {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        for (n, s) in self.steps.iter().enumerate() {
            if n > 0 {
                f.write_str("; ")?;
            }
            match &s.error {
                None => write!(f, "{}: done", s.step)?,
                Some(e) => write!(f, "{}: FAILED ({e})", s.step)?,
            }
        }
        Ok(())
    }
}
