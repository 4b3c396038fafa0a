//! Faults the tests can switch on at run time, one [`Faults`] per server.
//!
//! Every protocol server asks its `Faults` for a `ReplyPlan` each time the instrument produced a
//! response, and delivers the response accordingly. This is what lets a client's tests provoke the
//! failures real links show: a slow instrument, a reply trickling in one byte per TCP segment, a
//! connection that dies in the middle of a binary block, a query whose answer never comes.
//!
//! Delay and 1-byte segments stay on until switched off; the dropped connection and the missing
//! reply are one-shot (they hit the next response only), so the test can check that the client
//! recovers and the following exchange succeeds. A stall (every reply held until a moment) and a
//! silence (every reply swallowed until a moment: a module without power) end by themselves.

use std::sync::atomic::{AtomicBool, AtomicU32, AtomicU64, Ordering};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

/// Run-time switchable faults for one server. Cheap to share: wrap it in an [`Arc`] and keep a
/// clone in the test.
#[derive(Debug, Default)]
pub struct Faults {
    reply_delay_us: AtomicU64,
    byte_segments: AtomicBool,
    drop_next: AtomicU32,
    swallow_next: AtomicU32,
    /// Replies are held until then (a stalled instrument).
    stalled_until: Mutex<Option<Instant>>,
    /// Replies are swallowed until then (a module without power).
    silent_until: Mutex<Option<Instant>>,
    /// Faults of a wider scope (the whole lab) that apply here too.
    shared: Option<Arc<Faults>>,
}

/// How one response is to be delivered.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) struct ReplyPlan {
    /// Wait this long before sending anything.
    pub delay: Duration,
    /// Write the encoded response one byte at a time, flushing after each byte.
    pub byte_segments: bool,
    /// What happens to the response.
    pub fate: ReplyFate,
}

/// The fate of one response.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum ReplyFate {
    /// Send it whole.
    Deliver,
    /// Send the first half of the encoded bytes, then close the connection.
    DropMidway,
    /// Never send it (the client must time out).
    Swallow,
}

impl ReplyPlan {
    /// A plan without any fault.
    pub(crate) const CLEAN: ReplyPlan = ReplyPlan {
        delay: Duration::ZERO,
        byte_segments: false,
        fate: ReplyFate::Deliver,
    };
}

impl Faults {
    /// No faults switched on.
    pub fn new() -> Arc<Faults> {
        Arc::new(Faults::default())
    }

    /// Faults of one server that also obeys `shared` (the lab-wide switches): a test can stall one
    /// instrument while the others keep answering.
    pub(crate) fn layered(shared: Arc<Faults>) -> Arc<Faults> {
        Arc::new(Faults {
            shared: Some(shared),
            ..Faults::default()
        })
    }

    /// Delay every response by `delay` (zero switches it off).
    pub fn set_reply_delay(&self, delay: Duration) {
        let us = u64::try_from(delay.as_micros()).unwrap_or(u64::MAX);
        self.reply_delay_us.store(us, Ordering::SeqCst);
    }

    /// Write every response one byte per TCP segment (flush after each byte) while `on`.
    pub fn set_byte_segments(&self, on: bool) {
        self.byte_segments.store(on, Ordering::SeqCst);
    }

    /// Cut the connection halfway through the next response (one-shot).
    pub fn drop_next_reply_midway(&self) {
        self.drop_next.fetch_add(1, Ordering::SeqCst);
    }

    /// Never send the next response (one-shot): the client's read must time out.
    pub fn swallow_next_reply(&self) {
        self.swallow_next.fetch_add(1, Ordering::SeqCst);
    }

    /// Hold every reply until `for_` from now (a stalled instrument: what it answers in that
    /// time arrives when the stall ends).
    pub fn stall_for(&self, for_: Duration) {
        *lock(&self.stalled_until) = Some(Instant::now() + for_);
    }

    /// Swallow every reply until `for_` from now (a module whose power is off: it hears
    /// nothing, answers nothing).
    pub fn silence_for(&self, for_: Duration) {
        *lock(&self.silent_until) = Some(Instant::now() + for_);
    }

    /// Switch every fault off, including pending one-shots.
    pub fn clear(&self) {
        self.reply_delay_us.store(0, Ordering::SeqCst);
        self.byte_segments.store(false, Ordering::SeqCst);
        self.drop_next.store(0, Ordering::SeqCst);
        self.swallow_next.store(0, Ordering::SeqCst);
        *lock(&self.stalled_until) = None;
        *lock(&self.silent_until) = None;
    }

    /// Decide how the next response is delivered, consuming a pending one-shot fault.
    pub(crate) fn plan_reply(&self) -> ReplyPlan {
        let own = self.plan_own();
        match &self.shared {
            None => own,
            Some(shared) => {
                let wide = shared.plan_own();
                ReplyPlan {
                    delay: own.delay.max(wide.delay),
                    byte_segments: own.byte_segments || wide.byte_segments,
                    fate: if own.fate == ReplyFate::Deliver {
                        wide.fate
                    } else {
                        own.fate
                    },
                }
            }
        }
    }

    fn plan_own(&self) -> ReplyPlan {
        let now = Instant::now();
        let left = |until: &Mutex<Option<Instant>>| {
            lock(until)
                .map(|t| t.saturating_duration_since(now))
                .filter(|d| !d.is_zero())
        };
        let fate = if left(&self.silent_until).is_some() || take_one(&self.swallow_next) {
            ReplyFate::Swallow
        } else if take_one(&self.drop_next) {
            ReplyFate::DropMidway
        } else {
            ReplyFate::Deliver
        };
        let delay = Duration::from_micros(self.reply_delay_us.load(Ordering::SeqCst));
        ReplyPlan {
            delay: delay.max(left(&self.stalled_until).unwrap_or_default()),
            byte_segments: self.byte_segments.load(Ordering::SeqCst),
            fate,
        }
    }
}

fn lock<T>(m: &Mutex<T>) -> std::sync::MutexGuard<'_, T> {
    // Plain data: a panic elsewhere leaves it consistent.
    m.lock().unwrap_or_else(|p| p.into_inner())
}

/// Decrement `counter` if it is positive; true when a pending fault was taken.
fn take_one(counter: &AtomicU32) -> bool {
    counter
        .fetch_update(Ordering::SeqCst, Ordering::SeqCst, |n| n.checked_sub(1))
        .is_ok()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn one_shot_faults_hit_only_the_next_reply() {
        let faults = Faults::new();
        faults.swallow_next_reply();
        faults.drop_next_reply_midway();
        assert_eq!(faults.plan_reply().fate, ReplyFate::Swallow);
        assert_eq!(faults.plan_reply().fate, ReplyFate::DropMidway);
        assert_eq!(faults.plan_reply(), ReplyPlan::CLEAN);
    }

    #[test]
    fn persistent_faults_stay_until_cleared() {
        let faults = Faults::new();
        faults.set_reply_delay(Duration::from_millis(5));
        faults.set_byte_segments(true);
        for _ in 0..3 {
            let plan = faults.plan_reply();
            assert_eq!(plan.delay, Duration::from_millis(5));
            assert!(plan.byte_segments);
        }
        faults.clear();
        assert_eq!(faults.plan_reply(), ReplyPlan::CLEAN);
    }

    #[test]
    fn a_stall_holds_and_a_silence_swallows_until_they_end() {
        let faults = Faults::new();
        faults.stall_for(Duration::from_secs(60));
        let plan = faults.plan_reply();
        assert!(plan.delay > Duration::from_secs(59) && plan.fate == ReplyFate::Deliver);
        faults.silence_for(Duration::from_secs(60));
        assert_eq!(faults.plan_reply().fate, ReplyFate::Swallow);
        assert_eq!(faults.plan_reply().fate, ReplyFate::Swallow);
        faults.stall_for(Duration::ZERO);
        faults.silence_for(Duration::ZERO);
        assert_eq!(faults.plan_reply(), ReplyPlan::CLEAN);
    }

    #[test]
    fn layered_faults_add_the_lab_wide_ones_to_their_own() {
        let lab = Faults::new();
        let scope = Faults::layered(lab.clone());
        scope.set_reply_delay(Duration::from_secs(2));
        lab.set_reply_delay(Duration::from_secs(1));
        lab.swallow_next_reply();
        assert_eq!(lab.plan_reply().delay, Duration::from_secs(1));
        lab.swallow_next_reply();
        let plan = scope.plan_reply();
        assert_eq!(plan.delay, Duration::from_secs(2));
        assert_eq!(plan.fate, ReplyFate::Swallow);
        scope.clear();
        lab.clear();
        assert_eq!(scope.plan_reply(), ReplyPlan::CLEAN);
    }
}
