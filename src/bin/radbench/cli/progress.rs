//! A progress bar on stderr for long instrument transfers (`scpi`, `idn`), fed by the transport's
//! progress reports. Hidden when stderr is not a terminal, so scripts and logs stay clean.

use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};
use radbench::transport::{Direction, Progress, ProgressFn};
use std::sync::{Arc, Mutex};

/// One bar per transfer: a report whose direction differs, or whose count went back, starts a
/// new one. [`TransferBar::finish`] clears it when the command is over.
#[derive(Clone, Default)]
pub(crate) struct TransferBar {
    state: Arc<Mutex<State>>,
}

#[derive(Default)]
struct State {
    bar: Option<ProgressBar>,
    direction: Option<Direction>,
    done: u64,
}

impl TransferBar {
    pub(crate) fn new() -> Self {
        Self::default()
    }

    /// The callback to put in the link options.
    pub(crate) fn callback(&self) -> ProgressFn {
        let this = self.clone();
        Arc::new(move |p: Progress| this.report(p, ProgressDrawTarget::stderr()))
    }

    fn report(&self, p: Progress, target: ProgressDrawTarget) {
        let mut state = self.lock();
        let new_transfer = state.direction != Some(p.direction) || p.done < state.done;
        if new_transfer {
            if let Some(old) = state.bar.take() {
                old.finish_and_clear();
            }
            state.bar = Some(new_bar(p, target));
            state.direction = Some(p.direction);
        }
        state.done = p.done;
        if let Some(bar) = &state.bar {
            match p.total {
                Some(total) => bar.set_length(total.max(p.done)),
                None => bar.unset_length(),
            }
            bar.set_position(p.done);
        }
    }

    /// Removes the bar of the last transfer, if any.
    pub(crate) fn finish(&self) {
        let mut state = self.lock();
        if let Some(bar) = state.bar.take() {
            bar.finish_and_clear();
        }
        state.direction = None;
        state.done = 0;
    }

    fn lock(&self) -> std::sync::MutexGuard<'_, State> {
        // A panic while drawing leaves nothing to protect; keep reporting.
        self.state.lock().unwrap_or_else(|p| p.into_inner())
    }
}

fn new_bar(p: Progress, target: ProgressDrawTarget) -> ProgressBar {
    let verb = match p.direction {
        Direction::Read => "reading",
        Direction::Write => "writing",
    };
    let template = if p.total.is_some() {
        "{prefix} [{bar:30}] {bytes}/{total_bytes} {binary_bytes_per_sec} eta {eta}"
    } else {
        "{prefix} {bytes} {binary_bytes_per_sec}"
    };
    let bar = ProgressBar::with_draw_target(p.total, target);
    if let Ok(style) = ProgressStyle::with_template(template) {
        bar.set_style(style.progress_chars("=> "));
    }
    bar.set_prefix(verb);
    bar
}

#[cfg(test)]
mod tests {
    use super::*;

    fn report(bar: &TransferBar, direction: Direction, done: u64, total: Option<u64>) {
        let p = Progress {
            direction,
            done,
            total,
        };
        bar.report(p, ProgressDrawTarget::hidden());
    }

    #[test]
    fn follows_one_transfer_then_starts_the_next() {
        let bar = TransferBar::new();
        report(&bar, Direction::Write, 4 << 20, Some(64 << 20));
        report(&bar, Direction::Write, 8 << 20, Some(64 << 20));
        {
            let state = bar.lock();
            let b = state.bar.as_ref().expect("a bar");
            assert_eq!((b.position(), b.length()), (8 << 20, Some(64 << 20)));
        }
        // The reply starts: a new bar, whose length may grow as frames announce more.
        report(&bar, Direction::Read, 4 << 20, Some(5 << 20));
        report(&bar, Direction::Read, 9 << 20, Some(10 << 20));
        {
            let state = bar.lock();
            let b = state.bar.as_ref().expect("a bar");
            assert_eq!((b.position(), b.length()), (9 << 20, Some(10 << 20)));
        }
        bar.finish();
        assert!(bar.lock().bar.is_none());
        // Unknown length (an indefinite block): a counter without a bar.
        report(&bar, Direction::Read, 4 << 20, None);
        assert_eq!(bar.lock().bar.as_ref().unwrap().length(), None);
    }
}
