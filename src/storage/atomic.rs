//! Atomic writes: write a temporary file next to the destination, flush it, then rename.
//!
//! The temporary file is `.<name>.radbench-tmp-<pid>-<16 random hex digits>` in the
//! destination's folder (a rename is only atomic within one file system). It is created with
//! `O_CREAT | O_EXCL | O_NOFOLLOW`, so nothing planted under that name, a symbolic link least of
//! all, is ever opened or followed, and its random part cannot be guessed in advance.
//!
//! Symbolic links: a destination that is a symbolic link is refused (an error naming it), so a
//! link planted in a run folder cannot make radbench write to the file it points at. Should a
//! link appear between that check and the rename, the rename replaces the link itself, never its
//! target: nothing outside the folder is written either way.
//!
//! A write that fails or panics removes its temporary file. One that is killed leaves it behind;
//! [`remove_stale_temporaries`] removes such leftovers (run it on a run folder at the start of a
//! run, and on a signal once no write of this process is in flight).

use super::StorageError;
use sha2::{Digest, Sha256};
use std::io::{Read, Write};
use std::os::unix::fs::OpenOptionsExt;
use std::path::{Path, PathBuf};
use std::sync::Mutex;

/// What every radbench temporary file name contains (after `.<name>`).
pub(crate) const TEMP_MARKER: &str = ".radbench-tmp-";

/// Largest single `write` call. A kernel without preemption (PREEMPT_NONE, common on servers
/// and VMs) runs a write of megabytes to the page cache to its end before any other thread may
/// have that CPU; a campaign's step worker writing a capture would then hold an instrument
/// reply of the next step for milliseconds. 256 KiB is a few tens of microseconds.
const WRITE_CHUNK: usize = 256 * 1024;

/// Writes `bytes` to `path` atomically: readers see either the old file or the complete new one.
pub fn write_atomic(path: &Path, bytes: &[u8]) -> Result<(), StorageError> {
    write_atomic_parts(path, &[bytes])
}

/// [`write_atomic`] of `parts` one after the other (a header and a body kept apart, unjoined).
/// Inside a [`write_group`] the file is complete on disk only when the group ends.
pub(crate) fn write_atomic_parts(path: &Path, parts: &[&[u8]]) -> Result<(), StorageError> {
    let io = |source| StorageError::Io {
        path: path.to_path_buf(),
        source,
    };
    refuse_symlink(path).map_err(io)?;
    let (mut file, tmp) = create_temporary(path).map_err(io)?;
    // Removes the temporary file on every way out but success (errors and panics alike).
    let mut guard = TempGuard(Some(tmp.clone()));
    // In a group: whether it hashes its files (`Some(true)`) or not.
    let group_hashes = GROUP.with(|g| g.borrow().as_ref().map(|g| g.hashed));
    let grouped = group_hashes.is_some();
    let mut hasher = group_hashes.unwrap_or(false).then(Sha256::new);
    let mut bytes = 0u64;
    let mut hashing = std::time::Duration::ZERO;
    let written = (|| {
        for part in parts {
            for chunk in part.chunks(WRITE_CHUNK) {
                file.write_all(chunk)?;
                if let Some(h) = hasher.as_mut() {
                    let t = std::time::Instant::now();
                    h.update(chunk);
                    hashing += t.elapsed();
                }
            }
            bytes += part.len() as u64;
        }
        if grouped {
            start_writeback(&file);
            return Ok(());
        }
        file.sync_all()?;
        std::fs::rename(&tmp, path)
    })();
    written.map_err(io)?;
    guard.0 = None;
    if grouped {
        in_flight().insert(tmp.clone());
        let sha256 = hasher
            .map(|h| super::hash::hex(&h.finalize()))
            .unwrap_or_default();
        GROUP.with(|g| {
            if let Some(group) = g.borrow_mut().as_mut() {
                group.hashing += hashing;
                group.pending.push(Pending {
                    file,
                    tmp,
                    path: path.to_path_buf(),
                    bytes,
                    sha256,
                });
            }
        });
    } else {
        sync_folder(path);
    }
    Ok(())
}

/// A file written piece by piece (an export too large to hold in memory at once) and put in
/// place atomically by [`commit`](Self::commit), like [`write_atomic`]. Dropped without a commit
/// (an error, a panic), its temporary file is removed.
pub(crate) struct AtomicFile {
    file: std::io::BufWriter<std::fs::File>,
    path: PathBuf,
    guard: TempGuard,
}

impl AtomicFile {
    /// Starts the temporary file beside `path` (a symbolic link at `path` is refused).
    pub(crate) fn create(path: &Path) -> Result<AtomicFile, StorageError> {
        let io = |source| StorageError::Io {
            path: path.to_path_buf(),
            source,
        };
        refuse_symlink(path).map_err(io)?;
        let (file, tmp) = create_temporary(path).map_err(io)?;
        Ok(AtomicFile {
            file: std::io::BufWriter::with_capacity(WRITE_CHUNK, file),
            path: path.to_path_buf(),
            guard: TempGuard(Some(tmp)),
        })
    }

    fn io(&self, source: std::io::Error) -> StorageError {
        StorageError::Io {
            path: self.path.clone(),
            source,
        }
    }

    /// Appends `bytes`.
    pub(crate) fn write(&mut self, bytes: &[u8]) -> Result<(), StorageError> {
        for chunk in bytes.chunks(WRITE_CHUNK) {
            if let Err(e) = self.file.write_all(chunk) {
                return Err(self.io(e));
            }
        }
        Ok(())
    }

    /// Flushes and syncs the file, renames it into place and syncs its folder.
    pub(crate) fn commit(mut self) -> Result<(), StorageError> {
        let Some(tmp) = self.guard.0.clone() else {
            return Ok(());
        };
        let done = self
            .file
            .flush()
            .and_then(|()| self.file.get_ref().sync_all())
            .and_then(|()| std::fs::rename(&tmp, &self.path));
        if let Err(e) = done {
            return Err(self.io(e));
        }
        self.guard.0 = None;
        sync_folder(&self.path);
        Ok(())
    }
}

/// A file written in a group: what it is to become and what it holds.
struct Pending {
    /// Kept open: the data is synced through it, and the rename checks the name still is it.
    file: std::fs::File,
    tmp: PathBuf,
    path: PathBuf,
    bytes: u64,
    sha256: String,
}

/// A file a `write_group` made durable: where, how long, its SHA-256 (hashed as written;
/// empty for a [`write_group_open`], which does not hash).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct WrittenFile {
    pub path: PathBuf,
    pub bytes: u64,
    pub sha256: String,
}

struct Group {
    pending: Vec<Pending>,
    hashing: std::time::Duration,
    /// Whether each file is hashed as it is written (for a manifest that lists the files).
    hashed: bool,
}

impl Group {
    fn new(hashed: bool) -> Group {
        Group {
            pending: Vec::new(),
            hashing: std::time::Duration::ZERO,
            hashed,
        }
    }
}

/// What a `write_group` wrote: every file in writing order, and the time spent hashing them.
#[derive(Debug, Clone, Default)]
pub struct GroupWritten {
    pub files: Vec<WrittenFile>,
    pub hashing_s: f64,
}

thread_local! {
    /// The files written so far in the [`write_group`] running on this thread.
    static GROUP: std::cell::RefCell<Option<Group>> = const { std::cell::RefCell::new(None) };
}

/// Temporary files of groups not yet ended, in any thread: never stale.
fn in_flight() -> std::sync::MutexGuard<'static, std::collections::HashSet<PathBuf>> {
    static IN_FLIGHT: std::sync::OnceLock<Mutex<std::collections::HashSet<PathBuf>>> =
        std::sync::OnceLock::new();
    IN_FLIGHT
        .get_or_init(Default::default)
        .lock()
        .unwrap_or_else(|p| p.into_inner())
}

/// Runs `write`, a group of [`write_atomic`] calls on this thread (one capture's ten files), and
/// makes them durable together at its end: each file is hashed while it is written and its
/// writeback starts at once, so the data goes to the disk while the next files are computed;
/// at the end every file is synced and renamed into place, then each folder synced once. Every
/// file is whole or absent at any moment; when this returns, all are durable. Files written
/// before an error or a panic inside `write` are still put in place (nothing written is lost).
/// Returns `write`'s value and every file, in writing order. A nested group belongs to the
/// outer one (it returns no files; the outer one ends them).
pub(crate) fn write_group<R, E: From<StorageError>>(
    write: impl FnOnce() -> Result<R, E>,
) -> Result<(R, GroupWritten), E> {
    struct End(bool);
    impl Drop for End {
        fn drop(&mut self) {
            if self.0 {
                // Unwinding: put in place what can be, quietly.
                let _ = end_group();
            }
        }
    }
    let outermost = GROUP.with(|g| {
        let mut g = g.borrow_mut();
        let fresh = g.is_none();
        if fresh {
            *g = Some(Group::new(true));
        }
        fresh
    });
    if !outermost {
        return write().map(|r| (r, GroupWritten::default()));
    }
    let mut end = End(true);
    let result = write();
    end.0 = false;
    let ended = end_group();
    let value = result?;
    Ok((value, ended?))
}

/// A `write_group` whose end is left to the caller: its files are written and on their way
/// to the disk, not yet synced nor in place. [`OpenGroup::finish`] ends it, on any thread (a
/// thread that only waits for the disk), so the thread that wrote it can go on computing; dropped
/// unfinished, it is finished quietly.
pub struct OpenGroup(Option<Group>);

impl OpenGroup {
    /// What `write_group` does at its end: every file synced and renamed into place in writing
    /// order, then each folder synced once; the first failure, after trying them all.
    pub fn finish(mut self) -> Result<GroupWritten, StorageError> {
        match self.0.take() {
            Some(group) => finish_group(group),
            None => Ok(GroupWritten::default()),
        }
    }
}

impl Drop for OpenGroup {
    fn drop(&mut self) {
        if let Some(group) = self.0.take() {
            let _ = finish_group(group);
        }
    }
}

/// `write_group` without its end: returns the group open (see [`OpenGroup`]). When `write`
/// fails or panics, the group is ended at once, as `write_group` ends it. Inside another group
/// it belongs to that one (the returned group is empty). Its files are not hashed (their
/// [`WrittenFile::sha256`] is empty): `radbench process`, its one user, lists no written files.
pub fn write_group_open<R, E: From<StorageError>>(
    write: impl FnOnce() -> Result<R, E>,
) -> Result<(R, OpenGroup), E> {
    let outermost = GROUP.with(|g| g.borrow().is_none());
    if !outermost {
        return write().map(|r| (r, OpenGroup(None)));
    }
    let (value, _) = write_group(|| -> Result<_, E> {
        GROUP.with(|g| {
            if let Some(group) = g.borrow_mut().as_mut() {
                group.hashed = false;
            }
        });
        let value = write()?;
        // Taken before write_group's end, which then has nothing left to do.
        let group = GROUP.with(|g| g.borrow_mut().replace(Group::new(false)));
        Ok((value, group))
    })?;
    let (value, group) = value;
    Ok((value, OpenGroup(group)))
}

/// Syncs and renames every pending file of this thread's group, then syncs their folders.
/// Keeps going past a failure and returns the first.
fn end_group() -> Result<GroupWritten, StorageError> {
    match GROUP.with(|g| g.borrow_mut().take()) {
        Some(group) => finish_group(group),
        None => Ok(GroupWritten::default()),
    }
}

/// [`end_group`] of `group`.
fn finish_group(group: Group) -> Result<GroupWritten, StorageError> {
    let hashing_s = group.hashing.as_secs_f64();
    let mut first_error = None;
    let mut written = Vec::new();
    let mut folders: Vec<PathBuf> = Vec::new();
    for p in group.pending {
        let done = p
            .file
            .sync_all()
            .and_then(|()| still_ours(&p.file, &p.tmp))
            .and_then(|()| std::fs::rename(&p.tmp, &p.path));
        in_flight().remove(&p.tmp);
        match done {
            Ok(()) => {
                let folder = folder_of(&p.path).to_path_buf();
                if !folders.contains(&folder) {
                    folders.push(folder);
                }
                written.push(WrittenFile {
                    path: p.path,
                    bytes: p.bytes,
                    sha256: p.sha256,
                });
            }
            Err(source) => {
                let _ = std::fs::remove_file(&p.tmp);
                first_error.get_or_insert(StorageError::Io {
                    path: p.path,
                    source,
                });
            }
        }
    }
    for folder in folders {
        if let Ok(dir) = std::fs::File::open(&folder) {
            let _ = dir.sync_all();
        }
    }
    match first_error {
        Some(e) => Err(e),
        None => Ok(GroupWritten {
            files: written,
            hashing_s,
        }),
    }
}

/// Whether `tmp` still names the file written through `file` (nothing was put in its place, a
/// symbolic link least of all, while the group went on): only then is it renamed into place.
fn still_ours(file: &std::fs::File, tmp: &Path) -> std::io::Result<()> {
    use std::os::unix::fs::MetadataExt;
    let (ours, named) = (file.metadata()?, std::fs::symlink_metadata(tmp)?);
    if named.file_type().is_file() && named.dev() == ours.dev() && named.ino() == ours.ino() {
        Ok(())
    } else {
        Err(std::io::Error::other(
            "its temporary file was replaced while the step was written; nothing was renamed",
        ))
    }
}

/// Asks the kernel to start writing the file's data back now, without waiting (Linux); the
/// sync at the end of the group then has little left to wait for.
fn start_writeback(file: &std::fs::File) {
    #[cfg(target_os = "linux")]
    {
        use std::os::fd::AsRawFd;
        // SAFETY: a plain syscall on an open descriptor; no memory is passed.
        let _ =
            unsafe { libc::sync_file_range(file.as_raw_fd(), 0, 0, libc::SYNC_FILE_RANGE_WRITE) };
    }
    #[cfg(not(target_os = "linux"))]
    let _ = file;
}

/// Removes the radbench temporary files in `dir` (not its subfolders) left by writes that never
/// finished: those of processes no longer running, and this process's own. Returns what it
/// removed. Other files, and temporaries of another radbench still running, are left alone.
pub(crate) fn remove_stale_temporaries(dir: &Path) -> Result<Vec<PathBuf>, StorageError> {
    let io = |source| StorageError::Io {
        path: dir.to_path_buf(),
        source,
    };
    let mut removed = Vec::new();
    for entry in std::fs::read_dir(dir).map_err(io)? {
        let entry = entry.map_err(io)?;
        let name = entry.file_name();
        let Some(pid) = name.to_str().and_then(temporary_pid) else {
            continue;
        };
        if pid != std::process::id() && process_alive(pid) {
            continue;
        }
        if in_flight().contains(&entry.path()) {
            continue;
        }
        // A link or a file: either way the entry itself goes, never what a link points at.
        match std::fs::remove_file(entry.path()) {
            Ok(()) => removed.push(entry.path()),
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => {}
            Err(e) => {
                return Err(StorageError::Io {
                    path: entry.path(),
                    source: e,
                })
            }
        }
    }
    Ok(removed)
}

/// The writer's process id when `name` is a radbench temporary file name.
fn temporary_pid(name: &str) -> Option<u32> {
    let (_, tail) = name.rsplit_once(TEMP_MARKER)?;
    if !name.starts_with('.') {
        return None;
    }
    let (pid, random) = tail.split_once('-')?;
    let hex = random.len() == 16 && random.bytes().all(|b| b.is_ascii_hexdigit());
    hex.then(|| pid.parse().ok()).flatten()
}

/// Whether a process with this id exists (signal 0 probes without sending anything).
fn process_alive(pid: u32) -> bool {
    let Ok(pid) = libc::pid_t::try_from(pid) else {
        return false;
    };
    // SAFETY: kill with signal 0 only checks for existence and permission; no memory involved.
    let rc = unsafe { libc::kill(pid, 0) };
    rc == 0 || std::io::Error::last_os_error().raw_os_error() == Some(libc::EPERM)
}

fn refuse_symlink(path: &Path) -> std::io::Result<()> {
    match std::fs::symlink_metadata(path) {
        Ok(meta) if meta.file_type().is_symlink() => Err(std::io::Error::other(
            "it is a symbolic link, and radbench never writes through one: remove the link or \
             choose another name",
        )),
        _ => Ok(()),
    }
}

/// Creates a new temporary file beside `path`; a name that exists (anything planted there) is
/// never opened, another random name is tried.
fn create_temporary(path: &Path) -> std::io::Result<(std::fs::File, PathBuf)> {
    let name = path
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_else(|| "output".to_string());
    let mut last = None;
    for _ in 0..8 {
        let tmp = path.with_file_name(format!(
            ".{name}{TEMP_MARKER}{}-{:016x}",
            std::process::id(),
            random_u64()
        ));
        let opened = std::fs::OpenOptions::new()
            .write(true)
            .create_new(true)
            .custom_flags(libc::O_NOFOLLOW | libc::O_CLOEXEC)
            .open(&tmp);
        match opened {
            Ok(file) => return Ok((file, tmp)),
            Err(e) if e.kind() == std::io::ErrorKind::AlreadyExists => last = Some(e),
            Err(e) => return Err(e),
        }
    }
    Err(last.unwrap_or_else(|| std::io::Error::other("no free temporary name")))
}

/// 64 unpredictable bits: the kernel's random source, or std's randomly keyed hasher where
/// that cannot be read.
fn random_u64() -> u64 {
    let mut bytes = [0u8; 8];
    let urandom = std::fs::File::open("/dev/urandom").and_then(|mut f| f.read_exact(&mut bytes));
    if urandom.is_ok() {
        return u64::from_le_bytes(bytes);
    }
    use std::hash::{BuildHasher, Hasher};
    let mut h = std::collections::hash_map::RandomState::new().build_hasher();
    h.write_u128(
        std::time::SystemTime::now()
            .duration_since(std::time::UNIX_EPOCH)
            .map_or(0, |d| d.as_nanos()),
    );
    h.finish()
}

/// Makes the rename durable (a power cut after a run must not lose the file). Best effort: a
/// folder that cannot be opened or synced does not make the write fail.
fn sync_folder(path: &Path) {
    if let Ok(dir) = std::fs::File::open(folder_of(path)) {
        let _ = dir.sync_all();
    }
}

fn folder_of(path: &Path) -> &Path {
    match path.parent() {
        Some(p) if !p.as_os_str().is_empty() => p,
        _ => Path::new("."),
    }
}

/// Deletes the temporary file unless disarmed (set to `None`) after the rename.
struct TempGuard(Option<PathBuf>);

impl Drop for TempGuard {
    fn drop(&mut self) {
        if let Some(tmp) = self.0.take() {
            let _ = std::fs::remove_file(tmp);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::os::unix::fs::symlink;

    /// A file outside the folder written to, holding "precious": what a planted link aims at.
    fn victim_outside() -> (tempfile::TempDir, std::path::PathBuf) {
        let outside = tempfile::tempdir().unwrap();
        let victim = outside.path().join("victim.txt");
        std::fs::write(&victim, b"precious").unwrap();
        (outside, victim)
    }

    #[test]
    fn a_group_puts_its_files_in_place_at_its_end_with_their_hashes() {
        let dir = tempfile::tempdir().unwrap();
        let sub = dir.path().join("sub");
        std::fs::create_dir(&sub).unwrap();
        let (n, files) = write_group(|| {
            write_atomic(&dir.path().join("a"), b"1")?;
            write_atomic_parts(&dir.path().join("b"), &[b"2", b"22"])?;
            // Not in place yet; the folder's stale-temporary sweep leaves them alone.
            assert!(!dir.path().join("a").exists());
            assert!(remove_stale_temporaries(dir.path())?.is_empty());
            // A nested group belongs to the outer one.
            let (_, inner) = write_group(|| write_atomic(&sub.join("c"), b"3"))?;
            assert!(inner.files.is_empty());
            Ok::<_, StorageError>(3)
        })
        .unwrap();
        assert_eq!(n, 3);
        let got: Vec<(PathBuf, u64, String)> = files
            .files
            .into_iter()
            .map(|f| (f.path, f.bytes, f.sha256))
            .collect();
        assert_eq!(
            got,
            [
                (dir.path().join("a"), 1, super::super::hash::sha256(b"1")),
                (dir.path().join("b"), 3, super::super::hash::sha256(b"222")),
                (sub.join("c"), 1, super::super::hash::sha256(b"3")),
            ]
        );
        assert_eq!(std::fs::read(dir.path().join("b")).unwrap(), b"222");
        assert_eq!(names(dir.path()), ["a", "b", "sub"]);
        // (Other tests' groups may be in flight at the same time.)
        assert!(in_flight().iter().all(|p| !p.starts_with(dir.path())));
    }

    #[test]
    fn an_open_group_is_put_in_place_when_finished_on_another_thread_or_dropped() {
        let dir = tempfile::tempdir().unwrap();
        let (n, open) = write_group_open(|| {
            write_atomic(&dir.path().join("a"), b"1")?;
            write_atomic(&dir.path().join("b"), b"22")?;
            Ok::<_, StorageError>(2)
        })
        .unwrap();
        assert_eq!(n, 2);
        // Written, not in place, and no stale temporaries while open.
        assert!(!dir.path().join("a").exists());
        assert!(remove_stale_temporaries(dir.path()).unwrap().is_empty());
        let written = std::thread::spawn(move || open.finish())
            .join()
            .unwrap()
            .unwrap();
        let got: Vec<(PathBuf, u64, String)> = written
            .files
            .into_iter()
            .map(|f| (f.path, f.bytes, f.sha256))
            .collect();
        // Not hashed (nobody lists them).
        let none = String::new();
        assert_eq!(
            got,
            [
                (dir.path().join("a"), 1, none.clone()),
                (dir.path().join("b"), 2, none)
            ]
        );
        assert_eq!(names(dir.path()), ["a", "b"]);
        // Dropped unfinished: finished all the same.
        let ((), open) = write_group_open(|| write_atomic(&dir.path().join("c"), b"3")).unwrap();
        drop(open);
        assert_eq!(std::fs::read(dir.path().join("c")).unwrap(), b"3");
        // A failing write ends its group at once: what it wrote is in place, the error returned.
        let failed = write_group_open(|| {
            write_atomic(&dir.path().join("d"), b"4")?;
            write_atomic(&dir.path().join("missing").join("e"), b"5")
        });
        assert!(failed.is_err());
        assert_eq!(names(dir.path()), ["a", "b", "c", "d"]);
        assert!(in_flight().iter().all(|p| !p.starts_with(dir.path())));
    }

    #[test]
    fn a_temporary_replaced_during_the_group_is_not_renamed_into_place() {
        let (_outside, victim) = victim_outside();
        let dir = tempfile::tempdir().unwrap();
        let dest = dir.path().join("a.bin");
        let ended = write_group(|| {
            write_atomic(&dest, b"radbench output")?;
            let tmp = GROUP.with(|g| g.borrow().as_ref().unwrap().pending[0].tmp.clone());
            std::fs::remove_file(&tmp).unwrap();
            symlink(&victim, &tmp).unwrap();
            Ok::<_, StorageError>(())
        });
        assert!(ended.unwrap_err().to_string().contains("replaced"));
        assert!(
            !dest.exists(),
            "the planted link was not renamed into place"
        );
        assert_eq!(std::fs::read(&victim).unwrap(), b"precious");
    }

    #[test]
    fn files_written_before_an_error_or_a_panic_are_kept() {
        let dir = tempfile::tempdir().unwrap();
        let failed = write_group(|| {
            write_atomic(&dir.path().join("a"), b"1")?;
            write_atomic(&dir.path().join("no/such/folder/b"), b"2")?;
            Ok::<_, StorageError>(())
        });
        assert!(failed.unwrap_err().to_string().contains("no/such/folder"));
        let caught = std::panic::catch_unwind(|| {
            write_group(|| {
                write_atomic(&dir.path().join("d"), b"4")?;
                panic!("in the middle");
                #[allow(unreachable_code)]
                Ok::<_, StorageError>(())
            })
        });
        assert!(caught.is_err());
        assert!(GROUP.with(|g| g.borrow().is_none()), "the group ended");
        assert_eq!(names(dir.path()), ["a", "d"]);
        assert_eq!(std::fs::read(dir.path().join("d")).unwrap(), b"4");
    }

    fn names(dir: &Path) -> Vec<String> {
        let mut v: Vec<String> = std::fs::read_dir(dir)
            .unwrap()
            .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
            .collect();
        v.sort();
        v
    }

    #[test]
    fn replaces_the_file_and_leaves_no_temporary() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("a.txt");
        write_atomic(&path, b"first").unwrap();
        write_atomic(&path, b"second").unwrap();
        assert_eq!(std::fs::read(&path).unwrap(), b"second");
        assert_eq!(names(dir.path()), ["a.txt"], "only the destination remains");
    }

    #[test]
    fn missing_folder_is_an_io_error_naming_the_path() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("no/such/dir/a.txt");
        let err = write_atomic(&path, b"x").unwrap_err();
        assert!(err.to_string().contains("no/such/dir"), "{err}");
    }

    #[test]
    fn a_planted_symlink_is_refused_and_its_target_untouched() {
        let (outside, victim) = victim_outside();
        let run = tempfile::tempdir().unwrap();
        let planted = run.path().join("summary.json");
        symlink(&victim, &planted).unwrap();
        let err = write_atomic(&planted, b"radbench output").unwrap_err();
        assert!(err.to_string().contains("symbolic link"), "{err}");
        assert_eq!(std::fs::read(&victim).unwrap(), b"precious");
        assert!(std::fs::symlink_metadata(&planted)
            .unwrap()
            .file_type()
            .is_symlink());
        assert_eq!(names(run.path()), ["summary.json"], "no temporary left");
        // A dangling link is refused too (it would create the file it names).
        let dangling = run.path().join("profile.csv");
        let target = outside.path().join("created.txt");
        symlink(&target, &dangling).unwrap();
        assert!(write_atomic(&dangling, b"x").is_err());
        assert!(!target.exists());
    }

    #[test]
    fn a_symlink_planted_at_a_guessable_temporary_name_is_not_followed() {
        let (_outside, victim) = victim_outside();
        let run = tempfile::tempdir().unwrap();
        let dest = run.path().join("a.bin");
        // The names earlier versions used (`.a.bin.tmp-<pid>`), and this version's prefix.
        let pid = std::process::id();
        for guess in [
            format!(".a.bin.tmp-{pid}"),
            format!(".a.bin{TEMP_MARKER}{pid}"),
        ] {
            symlink(&victim, run.path().join(guess)).unwrap();
        }
        write_atomic(&dest, b"radbench output").unwrap();
        assert_eq!(std::fs::read(&dest).unwrap(), b"radbench output");
        assert_eq!(std::fs::read(&victim).unwrap(), b"precious");
    }

    #[test]
    fn temporaries_are_created_exclusively_and_never_followed() {
        let (_outside, victim) = victim_outside();
        let run = tempfile::tempdir().unwrap();
        let dest = run.path().join("a.bin");
        // Whatever name is planted, create_new + O_NOFOLLOW never opens it.
        for _ in 0..3 {
            let (file, tmp) = create_temporary(&dest).unwrap();
            drop(file);
            std::fs::remove_file(&tmp).unwrap();
            symlink(&victim, &tmp).unwrap();
            let opened = std::fs::OpenOptions::new()
                .write(true)
                .create_new(true)
                .custom_flags(libc::O_NOFOLLOW)
                .open(&tmp);
            assert!(opened.is_err(), "a planted link is never opened");
            std::fs::remove_file(&tmp).unwrap();
        }
        // Two names for the same destination differ in their random part.
        let (_, a) = create_temporary(&dest).unwrap();
        let (_, b) = create_temporary(&dest).unwrap();
        assert_ne!(a, b);
        let a = a.file_name().unwrap().to_str().unwrap().to_string();
        assert!(a.starts_with(".a.bin.radbench-tmp-"), "{a}");
        assert_eq!(temporary_pid(&a), Some(std::process::id()));
        assert_eq!(std::fs::read(&victim).unwrap(), b"precious");
    }

    #[test]
    fn stale_temporaries_are_removed_and_nothing_else() {
        let dir = tempfile::tempdir().unwrap();
        let d = dir.path();
        let own = format!(
            ".C1.trc{TEMP_MARKER}{}-0123456789abcdef",
            std::process::id()
        );
        // pid 2^22 + 1 is above Linux's pid_max limit: never a running process.
        let dead = format!(".capture.sigmf-data{TEMP_MARKER}4194305-fedcba9876543210");
        // This test's own parent process is alive: its temporaries stay.
        let alive = format!(
            ".profile.csv{TEMP_MARKER}{}-00000000000000ff",
            std::os::unix::process::parent_id()
        );
        for name in [&own, &dead, &alive] {
            std::fs::write(d.join(name), b"half").unwrap();
        }
        let (_outside, victim) = victim_outside();
        let linked = format!(".x{TEMP_MARKER}4194305-1111111111111111");
        symlink(&victim, d.join(&linked)).unwrap();
        for keep in [
            "summary.json",
            ".hidden",
            "notes.radbench-tmp-1-0123456789abcdef",
            ".a.radbench-tmp-1-short",
        ] {
            std::fs::write(d.join(keep), b"keep").unwrap();
        }
        let mut removed: Vec<String> = remove_stale_temporaries(d)
            .unwrap()
            .iter()
            .map(|p| p.file_name().unwrap().to_string_lossy().into_owned())
            .collect();
        removed.sort();
        let mut expected = vec![own, dead, linked];
        expected.sort();
        assert_eq!(removed, expected);
        assert_eq!(std::fs::read(&victim).unwrap(), b"precious");
        let left = names(d);
        assert!(left.contains(&alive), "{left:?}");
        assert_eq!(left.len(), 5, "{left:?}");
    }

    #[test]
    fn a_panicking_write_leaves_no_temporary() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("a.bin");
        let result = std::panic::catch_unwind(|| {
            let (_file, tmp) = create_temporary(&path).unwrap();
            let _guard = TempGuard(Some(tmp));
            panic!("a bug while writing");
        });
        assert!(result.is_err());
        assert!(names(dir.path()).is_empty());
    }
}
