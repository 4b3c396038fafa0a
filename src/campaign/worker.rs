//! The thread that processes and writes a campaign's steps while the next step is captured.
//!
//! It runs in Linux's idle scheduling class (`SCHED_IDLE`): on a busy machine (a lab PC, CI's 2
//! cores, a simulated bench on the same CPUs) the next step's instrument exchanges are answered
//! first, and the worker takes the CPU time left over. It is never starved outright (the idle
//! class keeps a small share), and a step waits for the one before it, so a loaded machine slows
//! a campaign without piling up steps. One thread, jobs in submission order, so steps are
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
    pub(crate) fn start() -> std::io::Result<StepWorker> {
        let (jobs, queue) = mpsc::channel::<Job>();
        let thread = std::thread::Builder::new()
            .name("radbench-steps".into())
            .spawn(move || {
                lower_priority();
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

#[cfg(target_os = "linux")]
fn lower_priority() {
    // SCHED_IDLE: any ordinary thread that wakes up (an instrument reply for the capture path, a
    // simulated lab's server) takes the CPU from the worker at once. A nice value alone is not
    // enough: measured on 2 CPUs, a woken thread then waited for the next scheduler tick (4 ms)
    // behind the worker while the other CPU sat idle.
    let param = libc::sched_param { sched_priority: 0 };
    // SAFETY: plain system calls on the calling thread (id 0); `param` outlives the call.
    let rc = unsafe { libc::sched_setscheduler(0, libc::SCHED_IDLE, &param) };
    if rc != 0 {
        tracing::debug!(
            "the step worker keeps its scheduling class: {}",
            std::io::Error::last_os_error()
        );
    }
}

#[cfg(not(target_os = "linux"))]
fn lower_priority() {
    // Elsewhere a process-wide nice would slow the capture path too: keep the priority.
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

    #[cfg(target_os = "linux")]
    #[tokio::test]
    async fn the_worker_runs_in_the_idle_class_and_the_caller_does_not() {
        let worker = StepWorker::start().unwrap();
        // SAFETY: reads the calling thread's scheduling policy.
        let policy = || unsafe { libc::sched_getscheduler(0) };
        assert_eq!(worker.submit(policy).await.unwrap(), libc::SCHED_IDLE);
        assert_eq!(policy(), libc::SCHED_OTHER);
    }
}
