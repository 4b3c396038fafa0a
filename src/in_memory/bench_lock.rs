//! One session at a time on a bench: an exclusive `flock` on a file keyed on the bench's
//! instrument addresses, so that a second session on the same instruments is refused with the
//! reason instead of interleaving its commands with the first one's. The lock belongs to the
//! open file: it goes when the session ends, however the process ends. A session that ends
//! normally removes its file too (a mock lab's random ports would otherwise leave one per
//! session); a taker checks that the file it locked is still the one at the path, so a file
//! removed under it is never shared.

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

/// Held while a session works on the bench (released, and its file removed, when dropped).
pub(crate) struct BenchLock {
    file: std::fs::File,
    path: PathBuf,
}

impl Drop for BenchLock {
    fn drop(&mut self) {
        // Removed while still locked: a taker that opened it meanwhile finds it gone (below).
        let _ = std::fs::remove_file(&self.path);
        let _ = self.file.set_len(0);
    }
}

/// Whether `file` is still the file at `path` (not removed by the holder that let it go).
fn still_at(file: &std::fs::File, path: &std::path::Path) -> bool {
    use std::os::unix::fs::MetadataExt;
    match (file.metadata(), std::fs::metadata(path)) {
        (Ok(a), Ok(b)) => a.dev() == b.dev() && a.ino() == b.ino(),
        _ => false,
    }
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
        // A few tries: each fails only when the holder let go and removed the file between our
        // open and our lock.
        let mut tries = 0;
        let mut lock = loop {
            tries += 1;
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
                        "the instruments are in use: another radbench session holds this bench \
                         ({}; {}). Close it first (`close()` or leaving its `with` block); its \
                         lock is {}",
                        addresses.join(", "),
                        holder.trim(),
                        path.display()
                    ),
                }));
            }
            if still_at(&lock, &path) || tries >= 5 {
                break lock;
            }
        };
        // Who holds it, for the message of a refused session (the lock is the flock, not this).
        let _ = lock.set_len(0);
        let _ = lock.rewind();
        let _ = write!(
            lock,
            "held by process {} since {}",
            std::process::id(),
            crate::storage::utc_now_rfc3339()
        );
        Ok(BenchLock { file: lock, path })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn bench(port: u16) -> BenchFile {
        let text = format!(
            "[awg]\nmodel = \"keysight-m8195a\"\nresource = \"TCPIP::127.0.0.1::hislip0,{port}::INSTR\"\n\
             [scope]\nmodel = \"lecroy-labmaster10zi-a\"\nresource = \"VICP::127.0.0.1\"\n"
        );
        BenchFile::parse(&text, std::path::Path::new("b.toml")).unwrap()
    }

    fn lock_path(file: &BenchFile) -> PathBuf {
        let key = crate::storage::sha256(addresses(file).join("\n").as_bytes());
        lock_dir().join(format!("{}.lock", &key[..16]))
    }

    #[test]
    fn a_lock_is_exclusive_and_its_file_goes_with_it() {
        // A port no other test names: this test's own lock file.
        let file = bench(60_001);
        let path = lock_path(&file);
        let held = BenchLock::take(&file).unwrap();
        assert!(path.exists());
        let refused = BenchLock::take(&file).err().expect("refused while held");
        assert!(crate::exit::render(&refused).contains("in use"));
        drop(held);
        assert!(
            !path.exists(),
            "removed with the lock: no file left per session"
        );
        let again = BenchLock::take(&file).unwrap();
        drop(again);
        assert!(!path.exists());
    }

    #[test]
    fn a_file_removed_under_a_taker_is_not_the_lock() {
        let file = bench(60_002);
        let path = lock_path(&file);
        std::fs::create_dir_all(lock_dir()).unwrap();
        let stale = std::fs::File::create(&path).unwrap();
        std::fs::remove_file(&path).unwrap();
        assert!(!still_at(&stale, &path));
        let held = BenchLock::take(&file).unwrap();
        assert!(still_at(&held.file, &path));
    }
}
