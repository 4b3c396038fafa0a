//! Registration as runs happen, never in their way: the commands hand the folders they made
//! durable to a [`Registrar`], whose own thread writes them into the catalog with a short busy
//! timeout. Nothing here can fail or slow a measurement: a catalog that is locked, damaged or on
//! a full disk costs a warning, and the next `radbench runs index` (which reads the folders, the
//! truth) puts it right.

use super::db::{self, CATALOG_FILE};
use super::record::{read_capture, read_run};
use super::RunsDbError;
use std::path::{Path, PathBuf};
use std::sync::mpsc;
use std::time::{Duration, Instant};

/// How long one registration waits for another writer of the catalog.
const BUSY: Duration = Duration::from_millis(200);

/// The shortest time between two registrations while a command runs (a long campaign's
/// manifest grows with its steps: registering it after every step would cost a core).
const MIN_INTERVAL: Duration = Duration::from_secs(2);

/// `RADBENCH_CATALOG`: the catalog the commands register into (`off`: none); without it, the
/// `catalog.sqlite` beside the folder written (in its parent: the runs folder).
pub(crate) const CATALOG_ENV: &str = "RADBENCH_CATALOG";

/// Where the folder `dir` is registered, if anywhere.
pub fn catalog_for(dir: &Path) -> Option<PathBuf> {
    match std::env::var_os(CATALOG_ENV) {
        Some(v) if v == "off" => None,
        Some(v) if !v.is_empty() => Some(PathBuf::from(v)),
        _ => {
            let dir = super::record::absolute(dir);
            Some(dir.parent().unwrap_or(Path::new("/")).join(CATALOG_FILE))
        }
    }
}

/// A folder made durable, to register.
enum Job {
    Folder(PathBuf),
}

/// The registration thread. Dropping it without [`Registrar::finish`] leaves the thread to end
/// with the process (an unfinished transaction is rolled back by SQLite).
pub struct Registrar {
    jobs: Option<mpsc::Sender<Job>>,
    done: mpsc::Receiver<Vec<String>>,
}

impl Registrar {
    /// A registrar writing into `catalog`.
    pub fn start(catalog: PathBuf) -> Registrar {
        let (jobs, queue) = mpsc::channel::<Job>();
        let (report, done) = mpsc::channel();
        let spawned = std::thread::Builder::new()
            .name("radbench-catalog".into())
            .spawn(move || {
                let mut warnings = Vec::new();
                let mut pending: Vec<PathBuf> = Vec::new();
                let mut open = true;
                while open || !pending.is_empty() {
                    if pending.is_empty() {
                        match queue.recv() {
                            Ok(Job::Folder(d)) => pending.push(d),
                            Err(_) => break,
                        }
                    }
                    // Folders queued meanwhile: each registered once, in its latest state.
                    for Job::Folder(d) in queue.try_iter() {
                        pending.push(d);
                    }
                    let t = Instant::now();
                    let mut folders = std::mem::take(&mut pending);
                    folders.sort();
                    folders.dedup();
                    for d in folders {
                        if let Err(e) = register_folder(&catalog, &d) {
                            warnings.push(format!(
                                "the run catalog {} was not updated with {} ({e}); the run \
                                 itself is intact: `radbench runs index {}` brings the catalog \
                                 up to date",
                                catalog.display(),
                                d.display(),
                                d.parent().unwrap_or(Path::new(".")).display()
                            ));
                        }
                    }
                    // At most a tenth of a core, and not more often than every MIN_INTERVAL,
                    // while the command measures: what arrives meanwhile waits, unless the
                    // command is ending (then at once).
                    let rest = (t.elapsed() * 9).max(MIN_INTERVAL);
                    let until = Instant::now() + rest;
                    while open {
                        match queue.recv_timeout(until.saturating_duration_since(Instant::now())) {
                            Ok(Job::Folder(d)) => pending.push(d),
                            Err(mpsc::RecvTimeoutError::Timeout) => break,
                            Err(mpsc::RecvTimeoutError::Disconnected) => open = false,
                        }
                    }
                }
                let _ = report.send(warnings);
            });
        let jobs = spawned.ok().map(|_| jobs);
        Registrar { jobs, done }
    }

    /// Queues `dir` (a run or capture folder whose files are durable) for registration.
    pub fn register(&self, dir: &Path) {
        if let Some(jobs) = &self.jobs {
            let _ = jobs.send(Job::Folder(dir.to_path_buf()));
        }
    }

    /// Waits at most `limit` for the queued registrations; the warnings to show (one when the
    /// wait ran out).
    pub fn finish(mut self, limit: Duration) -> Vec<String> {
        self.jobs.take();
        let deadline = Instant::now() + limit;
        match self
            .done
            .recv_timeout(deadline.saturating_duration_since(Instant::now()))
        {
            Ok(w) => w,
            Err(mpsc::RecvTimeoutError::Disconnected) => Vec::new(),
            Err(mpsc::RecvTimeoutError::Timeout) => vec![format!(
                "the run catalog was still being updated after {:.1} s and was left as it is; \
                 `radbench runs index` brings it up to date",
                limit.as_secs_f64()
            )],
        }
    }
}

/// Registers one folder (a run or a capture, or a folder of captures such as `process`'s
/// output) into `catalog`, with a short busy timeout.
pub(crate) fn register_folder(catalog: &Path, dir: &Path) -> Result<(), RunsDbError> {
    use super::index::Found;
    // Read first: a folder with nothing to register creates no catalog.
    let mut runs = Vec::new();
    let mut captures = Vec::new();
    for found in super::index::discover(dir) {
        match found {
            Found::Run(d) => runs.extend(read_run(&d)?),
            Found::Capture(d) => captures.extend(read_capture(&d)?),
        }
    }
    if runs.is_empty() && captures.is_empty() {
        return Ok(());
    }
    let mut conn = db::open(catalog, BUSY)?;
    for r in &runs {
        super::index::write_run(&mut conn, r)?;
    }
    for c in &captures {
        super::index::write_capture(&mut conn, c)?;
    }
    Ok(())
}
