//! The disk budget: what a run will write (estimated from each step's capture size and the
//! `[output]` choices), the free space where it writes, and the checks at the start and before
//! each step (docs/campaign.md, "Disk budget").

use super::error::CampaignError;
use super::plan::{Plan, WaveformCost};
use std::path::Path;

/// The environment variable that replaces the free-space probe, in bytes: a test hook (a full
/// filesystem without needing root to mount a small one). Not for use on a bench.
pub(crate) const FREE_BYTES_HOOK: &str = "RADBENCH_TEST_FREE_BYTES";

/// One `.trc` file's header and trailer, bytes (a LeCroy WAVEDESC and its text).
const TRC_OVERHEAD: f64 = 360.0;
/// Per algorithm: `profile.csv`, `profile.npy`, `profile.svg`, `summary.json`, `result.json`
/// (measured: MSK-LFM at 1 GHz, 0.15 .. 10 m).
const PROFILE_BYTES: f64 = 225e3;
/// Per algorithm: `profile.png`.
const PROFILE_PNG_BYTES: f64 = 171e3;
/// `link.svg` and `link.png`.
const LINK_SVG_BYTES: f64 = 90e3;
const LINK_PNG_BYTES: f64 = 154e3;
/// The run's own files per step: the report's share, the I/O journal, the manifest and results.
const RUN_BYTES_PER_STEP: f64 = 130e3;
/// Past the estimate, free space below this margin gets a warning at the start.
pub(crate) const MARGIN_BYTES: u64 = 1 << 30;

impl Plan {
    /// The estimated bytes step `k` (0-based) writes, its share of the run's files included.
    pub fn estimate_step_bytes(&self, k: usize, costs: &[WaveformCost]) -> u64 {
        self.estimate_step_files_bytes(k, costs) + RUN_BYTES_PER_STEP as u64
    }

    /// The estimated bytes of step `k`'s own files (its folder).
    pub(crate) fn estimate_step_files_bytes(&self, k: usize, costs: &[WaveformCost]) -> u64 {
        let step = &self.steps[k];
        let points = costs[step.waveform].points as f64;
        let reps = self.repetitions_at(k) as f64;
        let algorithms = self.processing_of(step.processing).len() as f64;
        let o = &self.output;
        // SigMF: I and Q, 16 bits each, every repetition.
        let mut b = 4.0 * points * reps + 5e3;
        if o.keep_trc {
            b += 2.0 * (2.0 * points + TRC_OVERHEAD);
        }
        b += algorithms * PROFILE_BYTES;
        if o.keep_bitmaps {
            b += algorithms * PROFILE_PNG_BYTES;
        }
        if o.keep_link_plots {
            b += LINK_SVG_BYTES;
            if o.keep_bitmaps {
                b += LINK_PNG_BYTES;
            }
        }
        b as u64
    }

    /// The estimated bytes of steps `from..` (0-based).
    pub fn estimate_bytes_from(&self, from: usize, costs: &[WaveformCost]) -> u64 {
        (from..self.steps.len())
            .map(|k| self.estimate_step_bytes(k, costs))
            .sum()
    }
}

/// Free bytes for an unprivileged writer on the filesystem holding `path` (or its nearest
/// existing ancestor); [`FREE_BYTES_HOOK`] replaces the probe.
pub(crate) fn free_bytes(path: &Path) -> std::io::Result<u64> {
    if let Ok(v) = std::env::var(FREE_BYTES_HOOK) {
        return v.trim().parse().map_err(|_| {
            std::io::Error::other(format!("{FREE_BYTES_HOOK}={v:?} is not a number of bytes"))
        });
    }
    let absolute = std::path::absolute(path)?;
    let existing = absolute
        .ancestors()
        .find(|p| p.exists())
        .unwrap_or(Path::new("/"));
    statvfs_free(existing)
}

#[cfg(unix)]
fn statvfs_free(path: &Path) -> std::io::Result<u64> {
    use std::os::unix::ffi::OsStrExt;
    let c = std::ffi::CString::new(path.as_os_str().as_bytes())
        .map_err(|_| std::io::Error::other("a path with a NUL byte"))?;
    // SAFETY: statvfs is plain old data; all zeroes is a valid value of it.
    let mut st: libc::statvfs = unsafe { std::mem::zeroed() };
    // SAFETY: `c` is a valid NUL-terminated path and `st` a writable statvfs.
    let rc = unsafe { libc::statvfs(c.as_ptr(), &mut st) };
    if rc != 0 {
        return Err(std::io::Error::last_os_error());
    }
    #[allow(clippy::unnecessary_cast)]
    Ok(st.f_bavail as u64 * st.f_frsize as u64)
}

#[cfg(not(unix))]
fn statvfs_free(_: &Path) -> std::io::Result<u64> {
    Ok(u64::MAX)
}

/// Megabytes, one decimal.
pub(crate) fn mb(bytes: u64) -> String {
    format!("{:.1} MB", bytes as f64 / 1e6)
}

/// What the start check found: `Ok(Some(warning))` when the space is enough but tight.
pub(crate) fn check(
    dir: &Path,
    needed: u64,
    when: &str,
    margin: u64,
) -> Result<Option<String>, CampaignError> {
    let free = free_bytes(dir).map_err(super::error::io(dir))?;
    if free < needed {
        return Err(CampaignError::DiskFull {
            dir: dir.to_path_buf(),
            free: mb(free),
            needed: mb(needed),
            when: when.to_string(),
        });
    }
    Ok((free - needed < margin).then(|| {
        format!(
            "warning: {} free at {}, the run needs about {} ({when}): less than {} to spare",
            mb(free),
            dir.display(),
            mb(needed),
            mb(margin)
        )
    }))
}
