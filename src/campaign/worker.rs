//! The thread that processes and writes a campaign's steps while the next step is captured.
//!
//! Its priority ([`WorkerPriority`]): on Linux an ordinary thread, five nice levels below the
//! thread that starts it (`setpriority` on its own thread id: Linux nice values are per thread),
//! so the capture path's threads weigh three times as much as it does in the scheduler (1024
//! against 335) and any other program's busy thread as well: the worker keeps a share of a
//! busy machine instead of starving. It used to run in the idle scheduling class (`SCHED_IDLE`,
//! weight 3): a woken capture thread took the CPU from it at once, but two busy processes started
//! from the same shell left it almost nothing, and a 6-step campaign took 105 times its quiet
//! time. Measurements and the choice of five: docs/speed.md ("A campaign on a busy PC").
//! `RADBENCH_STEP_WORKER=idle` (or `nice=N`) sets it otherwise, e.g. to compare.
//!
//! A step waits for the one before it (at most two wait for the worker), so a loaded machine
//! slows a campaign without piling up steps. One thread, jobs in submission order, so steps are
//! recorded in step order.

use std::panic::{catch_unwind, AssertUnwindSafe};
use std::sync::mpsc;
use std::thread::JoinHandle;
use tokio::sync::oneshot;

type Job = Box<dyn FnOnce() + Send>;

pub(crate) struct StepWorker {
    jobs: Option<mpsc::Sender<Job>>,
    thread: Option<JoinHandle<()>>,
}

impl StepWorker {
    /// A worker at the priority `RADBENCH_STEP_WORKER` asks for, by default
    /// [`WorkerPriority::default`].
    pub(crate) fn start() -> std::io::Result<StepWorker> {
        Self::start_with(WorkerPriority::from_env())
    }

    pub(crate) fn start_with(priority: WorkerPriority) -> std::io::Result<StepWorker> {
        let (jobs, queue) = mpsc::channel::<Job>();
        let thread = std::thread::Builder::new()
            .name("radbench-steps".into())
            .spawn(move || {
                lower_priority(priority);
                while let Ok(job) = queue.recv() {
                    // A job that panics loses its own result (its receiver reports it); the
                    // worker goes on with the next one.
                    let _ = catch_unwind(AssertUnwindSafe(job));
                }
            })?;
        Ok(StepWorker {
            jobs: Some(jobs),
            thread: Some(thread),
        })
    }

    /// Runs `f` on the worker after the jobs before it; the receiver yields its value, or an
    /// error when it panicked.
    pub(crate) fn submit<T: Send + 'static>(
        &self,
        f: impl FnOnce() -> T + Send + 'static,
    ) -> oneshot::Receiver<T> {
        let (tx, rx) = oneshot::channel();
        let job: Job = Box::new(move || {
            let _ = tx.send(f());
        });
        if let Some(jobs) = &self.jobs {
            // A worker that is gone drops the job, and with it the sender: the receiver says so.
            let _ = jobs.send(job);
        }
        rx
    }
}

impl Drop for StepWorker {
    fn drop(&mut self) {
        // Finish what was submitted (a capture taken is written), then stop.
        self.jobs.take();
        if let Some(t) = self.thread.take() {
            let _ = t.join();
        }
    }
}

/// How much the step worker yields to the capture path.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum WorkerPriority {
    /// An ordinary thread this many nice levels below the thread that starts it (at most 19).
    Nicer(i32),
    /// Linux's idle scheduling class: only the CPU time no ordinary thread wants.
    Idle,
}

impl Default for WorkerPriority {
    fn default() -> Self {
        WorkerPriority::Nicer(DEFAULT_NICER)
    }
}

/// Nice levels between the capture path and the step worker (docs/speed.md).
pub(crate) const DEFAULT_NICER: i32 = 5;

impl WorkerPriority {
    /// `RADBENCH_STEP_WORKER`: `idle` or `nice=N` (N levels below the capture path, 0..19);
    /// unset or anything else, the default.
    pub(crate) fn from_env() -> Self {
        match std::env::var("RADBENCH_STEP_WORKER") {
            Ok(v) => Self::parse(&v).unwrap_or_else(|| {
                tracing::warn!(
                    "RADBENCH_STEP_WORKER={v:?} is not `idle` or `nice=N` (0..19): ignored"
                );
                Self::default()
            }),
            Err(_) => Self::default(),
        }
    }

    fn parse(v: &str) -> Option<Self> {
        match v.trim() {
            "idle" => Some(WorkerPriority::Idle),
            v => v
                .strip_prefix("nice=")
                .and_then(|n| n.parse::<i32>().ok())
                .filter(|n| (0..=19).contains(n))
                .map(WorkerPriority::Nicer),
        }
    }
}

#[cfg(target_os = "linux")]
fn lower_priority(priority: WorkerPriority) {
    match priority {
        WorkerPriority::Nicer(by) => {
            // SAFETY: plain system calls on the calling thread's own id.
            let tid = unsafe { libc::syscall(libc::SYS_gettid) } as libc::id_t;
            // The nice value this thread inherited from the one that started it (the capture
            // path's); -1 is a valid value, so errno tells an error.
            // SAFETY: as above; errno is this thread's.
            let inherited = unsafe {
                *libc::__errno_location() = 0;
                let n = libc::getpriority(libc::PRIO_PROCESS, tid);
                (*libc::__errno_location() == 0).then_some(n)
            };
            let Some(inherited) = inherited else {
                tracing::debug!(
                    "the step worker keeps its priority: {}",
                    std::io::Error::last_os_error()
                );
                return;
            };
            // Only ever lower: unprivileged, a thread cannot take a priority back.
            let nice = inherited.saturating_add(by.max(0)).min(19);
            // SAFETY: sets the nice value of this thread alone (`tid`), nothing else.
            let rc = unsafe { libc::setpriority(libc::PRIO_PROCESS, tid, nice) };
            if rc != 0 {
                tracing::debug!(
                    "the step worker keeps its priority: {}",
                    std::io::Error::last_os_error()
                );
            }
        }
        WorkerPriority::Idle => {
            let param = libc::sched_param { sched_priority: 0 };
            // SAFETY: plain system call on the calling thread (id 0); `param` outlives the call.
            let rc = unsafe { libc::sched_setscheduler(0, libc::SCHED_IDLE, &param) };
            if rc != 0 {
                tracing::debug!(
                    "the step worker keeps its scheduling class: {}",
                    std::io::Error::last_os_error()
                );
            }
        }
    }
}

#[cfg(not(target_os = "linux"))]
fn lower_priority(_: WorkerPriority) {
    // Elsewhere nice is per process and would slow the capture path too: keep the priority.
}

#[cfg(test)]
mod tests {
    use super::*;

    #[tokio::test]
    async fn jobs_run_in_order_and_a_panic_does_not_stop_the_worker() {
        let worker = StepWorker::start().unwrap();
        let first = worker.submit(|| 1);
        let panicked = worker.submit(|| -> i32 { panic!("a step job failed") });
        let third = worker.submit(|| 3);
        assert_eq!(first.await.unwrap(), 1);
        assert!(panicked.await.is_err());
        assert_eq!(third.await.unwrap(), 3);
    }

    /// The calling thread's (policy, nice).
    #[cfg(target_os = "linux")]
    fn own_priority() -> (i32, i32) {
        // SAFETY: reads the calling thread's scheduling policy and nice value.
        unsafe {
            let tid = libc::syscall(libc::SYS_gettid) as libc::id_t;
            (
                libc::sched_getscheduler(0),
                libc::getpriority(libc::PRIO_PROCESS, tid),
            )
        }
    }

    #[cfg(target_os = "linux")]
    #[tokio::test]
    async fn the_worker_is_an_ordinary_thread_five_nice_levels_below_the_caller_alone() {
        let (policy, nice) = own_priority();
        let worker = StepWorker::start_with(WorkerPriority::default()).unwrap();
        let (w_policy, w_nice) = worker.submit(own_priority).await.unwrap();
        // An ordinary thread (not idle-class: it keeps a share of a busy machine), lower than
        // the capture path by DEFAULT_NICER (up to the lowest, 19)...
        assert_eq!(w_policy, libc::SCHED_OTHER);
        assert_eq!(w_nice, (nice + DEFAULT_NICER).min(19));
        assert!(nice >= 19 || w_nice > nice);
        // ...and the caller, whose threads are the capture path, keeps its own.
        assert_eq!(own_priority(), (policy, nice));
        // A second worker started from here is lowered from here again, not further.
        let again = StepWorker::start_with(WorkerPriority::default()).unwrap();
        assert_eq!(again.submit(own_priority).await.unwrap().1, w_nice);
    }

    #[cfg(target_os = "linux")]
    #[tokio::test]
    async fn the_idle_class_is_still_there_on_request_and_the_caller_does_not_change() {
        let before = own_priority();
        let worker = StepWorker::start_with(WorkerPriority::Idle).unwrap();
        assert_eq!(
            worker.submit(own_priority).await.unwrap().0,
            libc::SCHED_IDLE
        );
        assert_eq!(own_priority(), before);
    }

    #[test]
    fn the_priority_from_the_environment_is_idle_or_nice_n_else_the_default() {
        assert_eq!(WorkerPriority::parse("idle"), Some(WorkerPriority::Idle));
        assert_eq!(
            WorkerPriority::parse("nice=0"),
            Some(WorkerPriority::Nicer(0))
        );
        assert_eq!(
            WorkerPriority::parse(" nice=19 "),
            Some(WorkerPriority::Nicer(19))
        );
        for bad in ["", "nice=20", "nice=-1", "nice", "batch", "IDLE"] {
            assert_eq!(WorkerPriority::parse(bad), None, "{bad:?}");
        }
        assert_eq!(
            WorkerPriority::default(),
            WorkerPriority::Nicer(DEFAULT_NICER)
        );
    }
}
