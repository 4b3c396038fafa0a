//! The run folder's identity (device and inode), checked before anything is put in it: a folder
//! renamed, deleted or replaced while the campaign runs (an operator tidying up, a sync tool, a
//! disk cleaner) stops the run instead of being re-created at the old path and declared complete
//! with files that are not there.
//!
//! Also its lock: one process works in a run folder at a time.

use super::error::{io, CampaignError};
use std::os::unix::fs::MetadataExt;
use std::path::Path;

/// Held (flock) while a process works in the run folder.
const LOCK_FILE: &str = ".radbench.lock";

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

/// An exclusive lock on the run folder for this process (released when dropped).
pub(super) struct Lock {
    _file: std::fs::File,
}

pub(super) fn lock(dir: &Path) -> Result<Lock, CampaignError> {
    use std::os::fd::AsRawFd;
    let path = dir.join(LOCK_FILE);
    let file = std::fs::OpenOptions::new()
        .create(true)
        .truncate(false)
        .write(true)
        .open(&path)
        .map_err(io(&path))?;
    // SAFETY: flock on a file descriptor this function owns; no memory is shared.
    let rc = unsafe { libc::flock(file.as_raw_fd(), libc::LOCK_EX | libc::LOCK_NB) };
    if rc != 0 {
        return Err(CampaignError::Locked {
            dir: dir.to_path_buf(),
        });
    }
    Ok(Lock { _file: file })
}

/// Whether a process holds `dir`'s lock (works in the run folder now). A shared lock taken
/// for a moment tells: it is refused while a run or resume holds the exclusive one. A folder
/// without a lock file has no process in it.
pub(crate) fn lock_is_held(dir: &Path) -> bool {
    use std::os::fd::AsRawFd;
    let Ok(file) = std::fs::File::open(dir.join(LOCK_FILE)) else {
        return false;
    };
    // SAFETY: flock on a file descriptor this function owns; closing it releases the lock.
    let rc = unsafe { libc::flock(file.as_raw_fd(), libc::LOCK_SH | libc::LOCK_NB) };
    rc != 0
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
