//! A client-side fault injector around any [`InstrumentIo`], for reliability tests.
//!
//! mock_lab injects faults on the server side (`mock_lab::faults`) and the I/O tests put a seeded
//! proxy on the wire; both need a network between driver and instrument. [`FaultyIo`] sits where
//! the driver meets its session instead, so it works on every transport (serial too) and against
//! the [`Scripted`](super::scripted::Scripted) fake, and it can fail an operation at the two
//! moments that matter to a driver: before the instrument saw the command, and after the
//! instrument acted on it but before the driver learnt so. Like smoltcp's `FaultInjector` it is
//! seeded (the same seed and the same sequence of operations give the same faults) and has a
//! switch that turns it into a pass-through at run time.
//!
//! Every fault shows as a [`SessionError::Link`] (timeout or closed connection, kind
//! [`ErrorKind::Retry`](crate::transport::ErrorKind::Retry)), exactly what a real link gives, with
//! the resource marked `(injected fault)` so a test failure says where it came from. An injected
//! fault never corrupts or replays data: a "lost" reply is read from the instrument and thrown
//! away, so the next operation never sees it.

use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::{Arc, Mutex};
use std::time::Duration;

use super::io::{BoxFuture, InstrumentIo};
use crate::rng::SplitMix64;
use crate::session::{Block, DeviceError, SessionError};
use crate::transport::LinkError;

/// The time an injected timeout says it waited. Nothing waits that long (a test wants the error,
/// not the wait); a [`query_with_timeout`](InstrumentIo::query_with_timeout) reports its own.
pub(crate) const INJECTED_TIMEOUT: Duration = Duration::from_secs(2);

/// How often each fault strikes, per operation, in 1/1000. Plain data, so a test states its fault
/// mix in one literal. The three failures are exclusive (one draw decides; their sum is capped at
/// 1000); a delay is drawn independently and comes first.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct FaultPlan {
    /// The operation times out before anything is sent: the instrument never sees it.
    pub timeout_per_mille: u16,
    /// The operation reaches the instrument (which acts on it, and whose reply is read and
    /// discarded) but the caller gets a timeout: the case where retrying blindly would repeat it.
    pub reply_lost_per_mille: u16,
    /// The connection drops before the operation is sent; it and every later operation on this
    /// link fail with a closed-link error until `FaultSwitch::heal` (the reconnect).
    pub drop_per_mille: u16,
    /// The operation is held back by up to [`max_delay`](Self::max_delay) first (a slow network
    /// or instrument): it must still give the right answer.
    pub delay_per_mille: u16,
    pub max_delay: Duration,
}

/// How many faults a [`FaultSwitch`]'s injectors produced, so a test can show faults happened.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct FaultCounts {
    /// Timeouts before sending.
    pub timeouts: u64,
    /// Replies lost after the instrument acted.
    pub replies_lost: u64,
    /// Connection drops.
    pub drops: u64,
    /// Operations refused because the connection was down (after a drop, before the heal).
    pub refused_while_down: u64,
    /// Operations delayed.
    pub delays: u64,
}

impl FaultCounts {
    /// The faults that failed an operation by themselves: timeouts, lost replies and drops.
    pub fn injected(&self) -> u64 {
        self.timeouts
            .saturating_add(self.replies_lost)
            .saturating_add(self.drops)
    }
}

#[derive(Debug)]
struct SwitchState {
    enabled: AtomicBool,
    /// One flag per link under this switch: a drop takes down its own link only.
    links: Mutex<Vec<Arc<AtomicBool>>>,
    timeouts: AtomicU64,
    replies_lost: AtomicU64,
    drops: AtomicU64,
    refused_while_down: AtomicU64,
    delays: AtomicU64,
}

/// Turns the faults of one or more [`FaultyIo`] on and off at run time, heals a dropped link and
/// counts what was injected. Cheap to clone: the test keeps one after boxing the injector into a
/// driver (the way `Faults::hostile` in the proxy test, or smoltcp's injector, are switched).
#[derive(Debug, Clone)]
pub struct FaultSwitch(Arc<SwitchState>);

impl Default for FaultSwitch {
    /// Faults on, link up, nothing counted yet.
    fn default() -> Self {
        FaultSwitch(Arc::new(SwitchState {
            enabled: AtomicBool::new(true),
            links: Mutex::new(Vec::new()),
            timeouts: AtomicU64::new(0),
            replies_lost: AtomicU64::new(0),
            drops: AtomicU64::new(0),
            refused_while_down: AtomicU64::new(0),
            delays: AtomicU64::new(0),
        }))
    }
}

impl FaultSwitch {
    /// A new switch, faults on.
    pub fn new() -> Self {
        Self::default()
    }

    /// On: the plan applies. Off: every operation goes straight to the inner link, and a dropped
    /// link counts as reconnected (switching off must give a healthy link, e.g. for the safe
    /// state).
    pub fn set_enabled(&self, on: bool) {
        if !on {
            self.heal();
        }
        self.0.enabled.store(on, Ordering::SeqCst);
    }

    pub(crate) fn is_enabled(&self) -> bool {
        self.0.enabled.load(Ordering::SeqCst)
    }

    /// Every dropped link under this switch is back (what a reconnect does); faults stay as
    /// switched.
    pub(crate) fn heal(&self) {
        for down in self.links().iter() {
            down.store(false, Ordering::SeqCst);
        }
    }

    /// Whether a drop left a link under this switch down.
    #[cfg(test)]
    pub(crate) fn is_down(&self) -> bool {
        self.links().iter().any(|down| down.load(Ordering::SeqCst))
    }

    fn links(&self) -> std::sync::MutexGuard<'_, Vec<Arc<AtomicBool>>> {
        // A poisoned list is still a list of flags: no panic here.
        self.0.links.lock().unwrap_or_else(|p| p.into_inner())
    }

    /// A new link's "down" flag, healed with the others.
    fn register(&self) -> Arc<AtomicBool> {
        let down = Arc::new(AtomicBool::new(false));
        self.links().push(down.clone());
        down
    }

    /// What was injected so far through this switch.
    pub fn counts(&self) -> FaultCounts {
        let s = &self.0;
        FaultCounts {
            timeouts: s.timeouts.load(Ordering::SeqCst),
            replies_lost: s.replies_lost.load(Ordering::SeqCst),
            drops: s.drops.load(Ordering::SeqCst),
            refused_while_down: s.refused_while_down.load(Ordering::SeqCst),
            delays: s.delays.load(Ordering::SeqCst),
        }
    }

    fn count(counter: &AtomicU64) {
        counter.fetch_add(1, Ordering::SeqCst);
    }
}

/// What happens to one operation.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Fate {
    Pass,
    TimeoutBeforeSend,
    ReplyLost,
    Drop,
    /// The link was already down.
    Down,
}

/// The link operation names the errors carry: the send, and the reply (or acknowledgement).
#[derive(Debug, Clone, Copy)]
struct Ops {
    send: &'static str,
    reply: &'static str,
}

const WRITE: Ops = Ops {
    send: "write",
    reply: "write",
};
const QUERY: Ops = Ops {
    send: "write",
    reply: "read",
};
const CLEAR: Ops = Ops {
    send: "device clear",
    reply: "device clear",
};

/// An [`InstrumentIo`] that passes operations to an inner one, failing or delaying some of them
/// as its seeded [`FaultPlan`] says while its [`FaultSwitch`] is on.
pub struct FaultyIo {
    inner: Box<dyn InstrumentIo>,
    plan: FaultPlan,
    rng: SplitMix64,
    switch: FaultSwitch,
    /// This link's flag in the switch: set by a drop, cleared by a heal.
    down: Arc<AtomicBool>,
}

impl FaultyIo {
    /// Wraps `inner` with its own switch (faults on).
    pub fn new(inner: Box<dyn InstrumentIo>, seed: u64, plan: FaultPlan) -> Self {
        Self::with_switch(inner, seed, plan, FaultSwitch::new())
    }

    /// Wraps `inner` under a shared switch (one switch for a whole bench; its counts add up).
    pub fn with_switch(
        inner: Box<dyn InstrumentIo>,
        seed: u64,
        plan: FaultPlan,
        switch: FaultSwitch,
    ) -> Self {
        Self {
            inner,
            plan,
            rng: SplitMix64::new(seed),
            down: switch.register(),
            switch,
        }
    }

    /// The switch (clone it before boxing the injector into a driver).
    pub fn switch(&self) -> FaultSwitch {
        self.switch.clone()
    }

    /// Draws the next operation's fate and delay. Two draws per operation while faults are on and
    /// the link is up, none otherwise: the faults depend on the seed and the operations only.
    fn decide(&mut self) -> (Fate, Duration) {
        let s = &self.switch.0;
        if !self.switch.is_enabled() {
            return (Fate::Pass, Duration::ZERO);
        }
        if self.down.load(Ordering::SeqCst) {
            FaultSwitch::count(&s.refused_while_down);
            return (Fate::Down, Duration::ZERO);
        }
        let p = self.plan;
        let roll = self.rng.next_u64() % 1000;
        let timeout = u64::from(p.timeout_per_mille);
        let lost = timeout.saturating_add(u64::from(p.reply_lost_per_mille));
        let dropped = lost.saturating_add(u64::from(p.drop_per_mille));
        let fate = if roll < timeout {
            Fate::TimeoutBeforeSend
        } else if roll < lost {
            Fate::ReplyLost
        } else if roll < dropped {
            Fate::Drop
        } else {
            Fate::Pass
        };
        let draw = self.rng.next_u64();
        let delayed = draw % 1000 < u64::from(p.delay_per_mille);
        let delay = if delayed {
            let max_us = u64::try_from(p.max_delay.as_micros()).unwrap_or(u64::MAX);
            Duration::from_micros((draw / 1000) % max_us.saturating_add(1))
        } else {
            Duration::ZERO
        };
        match fate {
            Fate::TimeoutBeforeSend => FaultSwitch::count(&s.timeouts),
            Fate::ReplyLost => FaultSwitch::count(&s.replies_lost),
            Fate::Drop => {
                FaultSwitch::count(&s.drops);
                self.down.store(true, Ordering::SeqCst);
            }
            Fate::Pass | Fate::Down => {}
        }
        if delayed {
            FaultSwitch::count(&s.delays);
        }
        (fate, delay)
    }

    fn link_error(&self, source: LinkError) -> SessionError {
        SessionError::Link {
            resource: format!("{} (injected fault)", self.inner.resource_text()),
            source,
        }
    }

    /// Runs one operation under the plan. `call` gets the inner link only when the operation is
    /// to reach the instrument; `after` is the timeout a failure reports.
    fn run<'a, T: Send + 'a>(
        &'a mut self,
        ops: Ops,
        after: Duration,
        call: impl FnOnce(&'a mut (dyn InstrumentIo + 'static)) -> BoxFuture<'a, Result<T, SessionError>>
            + Send
            + 'a,
    ) -> BoxFuture<'a, Result<T, SessionError>> {
        Box::pin(async move {
            let (fate, delay) = self.decide();
            if !delay.is_zero() {
                tokio::time::sleep(delay).await;
            }
            match fate {
                Fate::Pass => call(&mut *self.inner).await,
                Fate::TimeoutBeforeSend => Err(self.link_error(LinkError::Timeout {
                    op: ops.send,
                    after,
                })),
                Fate::Drop | Fate::Down => Err(self.link_error(LinkError::Closed { op: ops.send })),
                Fate::ReplyLost => {
                    // Made before the call, which holds the inner link for the rest of 'a.
                    let lost = self.link_error(LinkError::Timeout {
                        op: ops.reply,
                        after,
                    });
                    // The instrument acts and its reply is consumed, whatever it was: nothing
                    // stale is left for the next operation to read.
                    let _ = call(&mut *self.inner).await;
                    Err(lost)
                }
            }
        })
    }
}

impl InstrumentIo for FaultyIo {
    fn resource_text(&self) -> String {
        self.inner.resource_text()
    }

    fn protocol(&self) -> &'static str {
        self.inner.protocol()
    }

    fn write<'a>(&'a mut self, command: &'a str) -> BoxFuture<'a, Result<(), SessionError>> {
        self.run(WRITE, INJECTED_TIMEOUT, move |io| io.write(command))
    }

    fn query<'a>(&'a mut self, query: &'a str) -> BoxFuture<'a, Result<String, SessionError>> {
        self.run(QUERY, INJECTED_TIMEOUT, move |io| io.query(query))
    }

    fn query_with_timeout<'a>(
        &'a mut self,
        query: &'a str,
        timeout: Duration,
    ) -> BoxFuture<'a, Result<String, SessionError>> {
        self.run(QUERY, timeout, move |io| {
            io.query_with_timeout(query, timeout)
        })
    }

    fn write_block<'a>(
        &'a mut self,
        header: &'a str,
        payload: &'a [u8],
    ) -> BoxFuture<'a, Result<(), SessionError>> {
        self.run(WRITE, INJECTED_TIMEOUT, move |io| {
            io.write_block(header, payload)
        })
    }

    fn query_block<'a>(&'a mut self, query: &'a str) -> BoxFuture<'a, Result<Block, SessionError>> {
        self.run(QUERY, INJECTED_TIMEOUT, move |io| io.query_block(query))
    }

    fn errors(&mut self) -> BoxFuture<'_, Result<Vec<DeviceError>, SessionError>> {
        self.run(QUERY, INJECTED_TIMEOUT, |io| io.errors())
    }

    fn device_clear(&mut self) -> BoxFuture<'_, Result<(), SessionError>> {
        self.run(CLEAR, INJECTED_TIMEOUT, |io| io.device_clear())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::driver::scripted::{block_on, Scripted};
    use crate::transport::ErrorKind;

    const OPS: usize = 400;

    fn plan() -> FaultPlan {
        FaultPlan {
            timeout_per_mille: 100,
            reply_lost_per_mille: 100,
            drop_per_mille: 20,
            delay_per_mille: 0,
            max_delay: Duration::ZERO,
        }
    }

    /// A fake answering `A?` with `1` as often as asked.
    fn fake() -> Scripted {
        Scripted::new("fake").reply_times("A?", "1", OPS)
    }

    /// Runs `OPS` queries, healing after each drop; what each gave (`1`, `timeout`, `closed`).
    fn outcomes(seed: u64) -> (Vec<String>, FaultCounts, Vec<String>) {
        let fake = fake();
        let log = fake.log();
        let mut io = FaultyIo::new(Box::new(fake), seed, plan());
        let switch = io.switch();
        let seen = block_on(async {
            let mut seen = Vec::new();
            for _ in 0..OPS {
                seen.push(match io.query("A?").await {
                    Ok(reply) => reply,
                    Err(e) => {
                        assert_eq!(e.kind(), ErrorKind::Retry, "{e}");
                        match e.link_error() {
                            Some(LinkError::Timeout { .. }) => "timeout".into(),
                            Some(LinkError::Closed { .. }) => {
                                switch.heal();
                                "closed".into()
                            }
                            _ => panic!("not a link failure: {e}"),
                        }
                    }
                });
            }
            seen
        });
        (seen, switch.counts(), log.ops())
    }

    #[test]
    fn the_same_seed_gives_the_same_faults() {
        let (a, counts, sent) = outcomes(7);
        assert_eq!(outcomes(7).0, a);
        assert_ne!(outcomes(8).0, a, "another seed, other faults");
        assert!(counts.timeouts > 0 && counts.replies_lost > 0 && counts.drops > 0);
        assert_eq!(
            a.iter().filter(|s| *s == "timeout").count() as u64,
            counts.timeouts + counts.replies_lost
        );
        // Timeouts before sending and drops never reach the instrument; lost replies do.
        assert_eq!(
            sent.len() as u64,
            OPS as u64 - counts.timeouts - counts.drops
        );
    }

    #[test]
    fn a_drop_holds_until_healed_and_off_is_a_pass_through() {
        let always_drop = FaultPlan {
            drop_per_mille: 1000,
            ..FaultPlan::default()
        };
        let fake = fake();
        let log = fake.log();
        let mut io = FaultyIo::new(Box::new(fake), 1, always_drop);
        let switch = io.switch();
        block_on(async {
            for _ in 0..3 {
                let e = io.query("A?").await.unwrap_err();
                assert!(
                    matches!(e.link_error(), Some(LinkError::Closed { .. })),
                    "{e}"
                );
                assert!(e.to_string().contains("(injected fault)"), "{e}");
            }
            assert!(switch.is_down());
            switch.set_enabled(false);
            assert!(!switch.is_down(), "off means a healthy link");
            for _ in 0..5 {
                assert_eq!(io.query("A?").await.unwrap(), "1");
            }
        });
        let counts = switch.counts();
        assert_eq!((counts.drops, counts.refused_while_down), (1, 2));
        assert_eq!(
            log.ops(),
            ["A?"; 5],
            "only the pass-through reached the fake"
        );
    }

    #[test]
    fn a_drop_takes_down_its_own_link_only() {
        let switch = FaultSwitch::new();
        let always_drop = FaultPlan {
            drop_per_mille: 1000,
            ..FaultPlan::default()
        };
        let mut dropping = FaultyIo::with_switch(Box::new(fake()), 1, always_drop, switch.clone());
        let mut healthy =
            FaultyIo::with_switch(Box::new(fake()), 2, FaultPlan::default(), switch.clone());
        block_on(async {
            assert!(dropping.query("A?").await.is_err());
            assert!(switch.is_down());
            assert_eq!(healthy.query("A?").await.unwrap(), "1");
            switch.heal();
            assert!(!switch.is_down());
        });
        assert_eq!(switch.counts().drops, 1);
    }

    #[test]
    fn delays_stay_within_their_bound() {
        let slow = FaultPlan {
            delay_per_mille: 1000,
            max_delay: Duration::from_millis(2),
            ..FaultPlan::default()
        };
        let mut io = FaultyIo::new(Box::new(fake()), 3, slow);
        let switch = io.switch();
        block_on(async {
            let start = std::time::Instant::now();
            for _ in 0..10 {
                assert_eq!(io.query("A?").await.unwrap(), "1");
            }
            // Ten delays of at most 2 ms each, with generous slack for a busy machine.
            assert!(start.elapsed() < Duration::from_secs(2));
        });
        assert_eq!(switch.counts().delays, 10);
        assert_eq!(switch.counts().injected(), 0);
    }
}
