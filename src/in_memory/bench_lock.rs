//! One session at a time on a bench: an exclusive `flock` on a file keyed on the bench's
//! instrument addresses, so that a second session on the same instruments is refused with the
//! reason instead of interleaving its commands with the first one's. The lock belongs to the
//! open file: it goes when the session ends, however the process ends.

use crate::exit::{Classified, ExitClass};
use crate::measure::BenchFile;
use std::io::{Read, Seek, Write};
use std::os::fd::AsRawFd;
use std::path::PathBuf;

/// The folder of the lock files (shared by every user's sessions on this machine).
fn lock_dir() -> PathBuf {
    std::env::temp_dir().join("radbench-bench-locks")
}

/// The instruments a bench file names, one `section=resource` each, in a fixed order.
fn addresses(file: &BenchFile) -> Vec<String> {
    let mut out = vec![
        format!("awg={}", file.awg.resource),
        format!("scope={}", file.scope.resource),
    ];
    for (name, entry) in [("tx", &file.tx), ("rx", &file.rx)] {
        if let Some(e) = entry.as_ref().filter(|e| !e.resource.is_empty()) {
            out.push(format!("{name}={}", e.resource));
        }
    }
    out
}

/// Held while a session works on the bench (released when dropped).
pub(crate) struct BenchLock {
    _file: std::fs::File,
}

impl BenchLock {
    /// Takes the bench's lock, or says who holds it (instrument class: the instruments are in
    /// use).
    pub(crate) fn take(file: &BenchFile) -> anyhow::Result<BenchLock> {
        let addresses = addresses(file);
        let key = crate::storage::sha256(addresses.join("\n").as_bytes());
        let dir = lock_dir();
        let cannot = |e: std::io::Error| {
            anyhow::Error::new(Classified {
                class: ExitClass::Processing,
                message: format!("cannot use the bench lock folder {}: {e}", dir.display()),
            })
        };
        std::fs::create_dir_all(&dir).map_err(cannot)?;
        let path = dir.join(format!("{}.lock", &key[..16]));
        let mut lock = std::fs::OpenOptions::new()
            .create(true)
            .truncate(false)
            .read(true)
            .write(true)
            .open(&path)
            .map_err(cannot)?;
        // SAFETY: flock on a file descriptor this function owns; no memory is shared.
        let rc = unsafe { libc::flock(lock.as_raw_fd(), libc::LOCK_EX | libc::LOCK_NB) };
        if rc != 0 {
            let mut holder = String::new();
            let _ = lock.read_to_string(&mut holder);
            return Err(anyhow::Error::new(Classified {
                class: ExitClass::Instrument,
                message: format!(
                    "the instruments are in use: another radbench session holds this bench ({}; \
                     {}). Close it first (`close()` or leaving its `with` block); its lock is \
                     {}",
                    addresses.join(", "),
                    holder.trim(),
                    path.display()
                ),
            }));
        }
        // Who holds it, for the message of a refused session (the lock is the flock, not this).
        let _ = lock.set_len(0);
        let _ = lock.rewind();
        let _ = write!(
            lock,
            "held by process {} since {}",
            std::process::id(),
            crate::storage::utc_now_rfc3339()
        );
        Ok(BenchLock { _file: lock })
    }
}
