//! Prepared pieces kept on disk between runs: what a pipeline computes before its first capture
//! and that depends only on its inputs (the decimation filter's taps, the detector's point-spread
//! table). A one-shot `radbench capture` or `radbench process` then reads them instead of
//! designing the filter and tabulating the spread again (tens of milliseconds each).
//!
//! Each piece is a file named by its key: the SHA-256 of what it depends on (the inputs' own
//! bytes, the piece's kind and format, and this build: the executable's size and modification
//! time, the version and commit), so another input or another build looks for another file. A
//! file is used only when its header holds the same key and its payload's SHA-256 checks;
//! anything else (truncated, corrupt, another key) is rebuilt and written again. Writing is best
//! effort: a folder that cannot be written only costs the time saved. Pieces over [`MAX_PIECE`]
//! are not stored.
//!
//! Where: `$RADBENCH_CACHE_DIR` when set, else `$XDG_CACHE_HOME/radbench`, else
//! `~/.cache/radbench`; `RADBENCH_CACHE=off` turns it off. Deleting the folder clears it. At most
//! [`KEEP`] files of each kind are kept (the oldest go first).

use sha2::{Digest, Sha256};
use std::io::Write;
use std::path::{Path, PathBuf};
use std::sync::OnceLock;

const MAGIC: &[u8; 8] = b"RBCACHE1";
/// Files kept per kind.
pub(crate) const KEEP: usize = 16;
/// Larger pieces are not stored (a long waveform's point spread over a wide range window can be
/// over 100 MB; the bench's is about 1.3 MB): the folder stays within `KEEP` times this per kind.
pub(crate) const MAX_PIECE: usize = 8 << 20;

/// A key under construction: the SHA-256 of everything a piece depends on.
pub(crate) struct Key(Sha256);

impl Key {
    /// A key for pieces of `kind` (e.g. `"decimator-taps-v1"`: name and format), made by this
    /// build.
    pub(crate) fn new(kind: &str) -> Key {
        let mut h = Sha256::new();
        h.update(build_identity());
        h.update((kind.len() as u64).to_le_bytes());
        h.update(kind.as_bytes());
        Key(h)
    }

    pub(crate) fn bytes(mut self, b: &[u8]) -> Key {
        self.0.update((b.len() as u64).to_le_bytes());
        self.0.update(b);
        self
    }

    pub(crate) fn u64(mut self, v: u64) -> Key {
        self.0.update(v.to_le_bytes());
        self
    }

    pub(crate) fn f64s(mut self, values: &[f64]) -> Key {
        self.0.update((values.len() as u64).to_le_bytes());
        for v in values {
            self.0.update(v.to_bits().to_le_bytes());
        }
        self
    }

    fn finish(self) -> [u8; 32] {
        self.0.finalize().into()
    }

    /// The key's bytes, for tests elsewhere that compare keys.
    #[cfg(test)]
    pub(crate) fn digest(self) -> [u8; 32] {
        self.finish()
    }
}

/// This build: a rebuilt executable (another size or modification time) keys every piece anew.
fn build_identity() -> &'static [u8] {
    static ID: OnceLock<Vec<u8>> = OnceLock::new();
    ID.get_or_init(|| {
        let mut id = format!(
            "{} {}",
            env!("CARGO_PKG_VERSION"),
            option_env!("RADBENCH_GIT_COMMIT").unwrap_or("")
        )
        .into_bytes();
        if let Some(meta) = std::env::current_exe()
            .ok()
            .and_then(|p| std::fs::metadata(p).ok())
        {
            id.extend(meta.len().to_le_bytes());
            if let Ok(t) = meta.modified() {
                if let Ok(d) = t.duration_since(std::time::UNIX_EPOCH) {
                    id.extend(d.as_nanos().to_le_bytes());
                }
            }
        }
        id
    })
}

/// The cache folder, or `None` when turned off or no home is known.
pub(crate) fn folder() -> Option<PathBuf> {
    if std::env::var_os("RADBENCH_CACHE").is_some_and(|v| v == "off") {
        return None;
    }
    if let Some(dir) = std::env::var_os("RADBENCH_CACHE_DIR").filter(|d| !d.is_empty()) {
        return Some(PathBuf::from(dir));
    }
    if let Some(dir) = std::env::var_os("XDG_CACHE_HOME").filter(|d| !d.is_empty()) {
        return Some(PathBuf::from(dir).join("radbench"));
    }
    std::env::var_os("HOME")
        .filter(|d| !d.is_empty())
        .map(|h| PathBuf::from(h).join(".cache").join("radbench"))
}

fn path_of(dir: &Path, kind: &str, key: &[u8; 32]) -> PathBuf {
    dir.join(kind)
        .join(super::hash::hex(key))
        .with_extension("bin")
}

/// The piece under `key`, made by `build` when the cache has no good copy (and then stored).
/// `decode` may refuse a payload (`None`): it is then rebuilt too.
pub(crate) fn get_or_build<T, E>(
    kind: &str,
    key: Key,
    encode: impl FnOnce(&T) -> Vec<u8>,
    decode: impl FnOnce(&[u8]) -> Option<T>,
    build: impl FnOnce() -> Result<T, E>,
) -> Result<T, E> {
    let Some(dir) = folder() else {
        return build();
    };
    get_or_build_in(&dir, kind, key, encode, decode, build)
}

/// [`get_or_build`] in the folder `dir`.
pub(crate) fn get_or_build_in<T, E>(
    dir: &Path,
    kind: &str,
    key: Key,
    encode: impl FnOnce(&T) -> Vec<u8>,
    decode: impl FnOnce(&[u8]) -> Option<T>,
    build: impl FnOnce() -> Result<T, E>,
) -> Result<T, E> {
    let key = key.finish();
    let path = path_of(dir, kind, &key);
    if let Some(found) = read(&path, &key).and_then(|payload| decode(&payload)) {
        return Ok(found);
    }
    let built = build()?;
    let payload = encode(&built);
    if payload.len() > MAX_PIECE {
        return Ok(built);
    }
    if let Err(e) = write(&path, &key, &payload) {
        tracing::debug!("cache: cannot store {}: {e}", path.display());
    } else {
        prune(path.parent().unwrap_or(dir));
    }
    Ok(built)
}

/// The payload of a good file under `key`; `None` when missing, of another key, or corrupt.
fn read(path: &Path, key: &[u8; 32]) -> Option<Vec<u8>> {
    let bytes = std::fs::read(path).ok()?;
    let header = MAGIC.len() + 32 + 8 + 32;
    if bytes.len() < header || &bytes[..MAGIC.len()] != MAGIC {
        return None;
    }
    let (stored_key, rest) = bytes[MAGIC.len()..].split_at(32);
    let (len, rest) = rest.split_at(8);
    let (sha, payload) = rest.split_at(32);
    let len = u64::from_le_bytes(len.try_into().ok()?);
    if stored_key != key || payload.len() as u64 != len || Sha256::digest(payload)[..] != *sha {
        tracing::debug!("cache: {} is stale or corrupt: rebuilt", path.display());
        return None;
    }
    Some(payload.to_vec())
}

/// Written to a temporary file and renamed into place: a reader sees the old file, none, or
/// the whole new one. Not synced: a file a crash truncated fails its check and is rebuilt.
fn write(path: &Path, key: &[u8; 32], payload: &[u8]) -> std::io::Result<()> {
    let dir = path.parent().unwrap_or(Path::new("."));
    std::fs::create_dir_all(dir)?;
    static COUNTER: std::sync::atomic::AtomicU64 = std::sync::atomic::AtomicU64::new(0);
    let n = COUNTER.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
    let tmp = dir.join(format!(".tmp-{}-{n}", std::process::id()));
    let result = (|| {
        let mut f = std::fs::File::create(&tmp)?;
        f.write_all(MAGIC)?;
        f.write_all(key)?;
        f.write_all(&(payload.len() as u64).to_le_bytes())?;
        f.write_all(&Sha256::digest(payload))?;
        f.write_all(payload)?;
        drop(f);
        std::fs::rename(&tmp, path)
    })();
    if result.is_err() {
        let _ = std::fs::remove_file(&tmp);
    }
    result
}

/// Keeps the newest [`KEEP`] pieces of a kind.
fn prune(dir: &Path) {
    let Ok(entries) = std::fs::read_dir(dir) else {
        return;
    };
    let mut files: Vec<(std::time::SystemTime, PathBuf)> = entries
        .filter_map(Result::ok)
        .filter(|e| e.path().extension().is_some_and(|x| x == "bin"))
        .filter_map(|e| Some((e.metadata().ok()?.modified().ok()?, e.path())))
        .collect();
    if files.len() <= KEEP {
        return;
    }
    files.sort();
    for (_, p) in &files[..files.len() - KEEP] {
        let _ = std::fs::remove_file(p);
    }
}

/// Little-endian `f64`s.
pub(crate) fn f64s_to_bytes(values: &[f64]) -> Vec<u8> {
    values.iter().flat_map(|v| v.to_le_bytes()).collect()
}

/// The inverse of [`f64s_to_bytes`]; `None` on a length that is not whole values.
pub(crate) fn f64s_from_bytes(bytes: &[u8]) -> Option<Vec<f64>> {
    if bytes.len() % 8 != 0 {
        return None;
    }
    Some(
        bytes
            .chunks_exact(8)
            .map(|c| f64::from_le_bytes(c.try_into().expect("8 bytes")))
            .collect(),
    )
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::cell::Cell;

    fn get(dir: &Path, built: &Cell<usize>, value: f64) -> Vec<f64> {
        get_or_build_in(
            dir,
            "test-v1",
            Key::new("test-v1").f64s(&[1.0, 2.0]),
            |v: &Vec<f64>| f64s_to_bytes(v),
            f64s_from_bytes,
            || {
                built.set(built.get() + 1);
                Ok::<_, ()>(vec![value; 3])
            },
        )
        .unwrap()
    }

    fn only_file(dir: &Path) -> PathBuf {
        let mut files: Vec<PathBuf> = std::fs::read_dir(dir.join("test-v1"))
            .unwrap()
            .map(|e| e.unwrap().path())
            .collect();
        assert_eq!(files.len(), 1, "{files:?}");
        files.pop().unwrap()
    }

    #[test]
    fn a_stored_piece_is_read_back_instead_of_built() {
        let dir = tempfile::tempdir().unwrap();
        let built = Cell::new(0);
        assert_eq!(get(dir.path(), &built, 0.5), vec![0.5; 3]);
        assert_eq!(get(dir.path(), &built, 9.0), vec![0.5; 3]);
        assert_eq!(built.get(), 1);
    }

    #[test]
    fn a_corrupt_or_truncated_piece_is_rebuilt_never_used() {
        let dir = tempfile::tempdir().unwrap();
        let built = Cell::new(0);
        get(dir.path(), &built, 0.5);
        let file = only_file(dir.path());
        let good = std::fs::read(&file).unwrap();
        // One bit of the payload flipped, then the file cut short.
        let mut bad = good.clone();
        let last = bad.len() - 1;
        bad[last] ^= 0x01;
        std::fs::write(&file, &bad).unwrap();
        assert_eq!(get(dir.path(), &built, 0.25), vec![0.25; 3]);
        assert_eq!(built.get(), 2);
        std::fs::write(&file, &good[..good.len() - 8]).unwrap();
        assert_eq!(get(dir.path(), &built, 0.125), vec![0.125; 3]);
        assert_eq!(built.get(), 3);
        // The rebuilt piece was stored again, whole.
        assert_eq!(get(dir.path(), &built, 7.0), vec![0.125; 3]);
        assert_eq!(built.get(), 3);
    }

    #[test]
    fn a_stale_piece_under_this_name_is_rebuilt_never_used() {
        let dir = tempfile::tempdir().unwrap();
        let built = Cell::new(0);
        get(dir.path(), &built, 0.5);
        let file = only_file(dir.path());
        // Another input's piece (its own key and a valid checksum) put under this one's name.
        let other = [7u8; 32];
        write(&file, &other, &f64s_to_bytes(&[3.0; 3])).unwrap();
        assert_eq!(get(dir.path(), &built, 0.25), vec![0.25; 3]);
        assert_eq!(built.get(), 2);
    }

    #[test]
    fn a_piece_over_the_size_limit_is_not_stored() {
        let dir = tempfile::tempdir().unwrap();
        let build = || Ok::<_, ()>(vec![1.0; MAX_PIECE / 8 + 1]);
        let key = || Key::new("big-v1").u64(1);
        let enc = |v: &Vec<f64>| f64s_to_bytes(v);
        get_or_build_in(dir.path(), "big-v1", key(), enc, f64s_from_bytes, build).unwrap();
        assert!(!dir.path().join("big-v1").exists());
    }

    #[test]
    fn other_inputs_have_other_keys() {
        let a = Key::new("k").f64s(&[1.0]).finish();
        let b = Key::new("k").f64s(&[1.0 + f64::EPSILON]).finish();
        let c = Key::new("j").f64s(&[1.0]).finish();
        assert_ne!(a, b);
        assert_ne!(a, c);
        assert_eq!(a, Key::new("k").f64s(&[1.0]).finish());
    }
}
