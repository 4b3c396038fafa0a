//! The run folder's identity (device and inode), checked before anything is put in it: a folder
//! renamed, deleted or replaced while the campaign runs (an operator tidying up, a sync tool, a
//! disk cleaner) stops the run instead of being re-created at the old path and declared complete
//! with files that are not there.

use super::{io, CampaignError};
use std::os::unix::fs::MetadataExt;
use std::path::Path;

/// Which folder the run was started in.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) struct FolderIdentity {
    dev: u64,
    ino: u64,
}

impl FolderIdentity {
    /// The identity of `dir` as it is now.
    pub(crate) fn of(dir: &Path) -> Result<FolderIdentity, CampaignError> {
        let m = std::fs::metadata(dir).map_err(io(dir))?;
        Ok(FolderIdentity {
            dev: m.dev(),
            ino: m.ino(),
        })
    }

    /// That `dir` is still the folder the run was started in.
    pub(crate) fn check(&self, dir: &Path) -> Result<(), CampaignError> {
        let lost = |what: &'static str| CampaignError::FolderLost {
            dir: dir.to_path_buf(),
            what,
        };
        match std::fs::metadata(dir) {
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => Err(lost("moved or deleted")),
            Err(e) => Err(io(dir)(e)),
            Ok(m) if (m.dev(), m.ino()) != (self.dev, self.ino) => {
                Err(lost("replaced by another folder of that name"))
            }
            Ok(_) => Ok(()),
        }
    }
}

impl FolderIdentity {
    /// After a write failed: the folder's loss when that was the cause (a write racing the
    /// folder's removal fails with "not found", which would not say what happened).
    pub(crate) fn lost(&self, dir: &Path) -> Option<CampaignError> {
        self.check(dir)
            .err()
            .filter(|e| matches!(e, CampaignError::FolderLost { .. }))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_moved_deleted_or_replaced_folder_is_told() {
        let tmp = tempfile::tempdir().unwrap();
        let run = tmp.path().join("run");
        std::fs::create_dir(&run).unwrap();
        let id = FolderIdentity::of(&run).unwrap();
        assert!(id.check(&run).is_ok());
        std::fs::rename(&run, tmp.path().join("elsewhere")).unwrap();
        let err = id.check(&run).unwrap_err().to_string();
        assert!(err.contains("moved or deleted"), "{err}");
        std::fs::create_dir(&run).unwrap();
        let err = id.check(&run).unwrap_err().to_string();
        assert!(err.contains("replaced"), "{err}");
        assert!(id.check(&tmp.path().join("elsewhere")).is_ok());
    }
}
