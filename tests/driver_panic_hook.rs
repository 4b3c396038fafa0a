//! A panic runs the safe state from the panic hook (its own test binary: the hook is global).

#[path = "support/driver/mod.rs"]
mod driver_support;

use std::time::Duration;

use driver_support::{guarded, model, AWG_SAFE_STATE};
use radbench::driver::{install_panic_hook, M8195a, Scripted};

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_panic_runs_the_safe_state_from_the_hook() {
    let fake = Scripted::new("awg").reply("*IDN?", "Keysight Technologies,M8195A,MY1,4.0");
    let log = fake.log();
    let awg = M8195a::connect(Box::new(fake), &model("keysight-m8195a"), "awg")
        .await
        .unwrap();
    let (safe, _awg, _tx) = guarded(Box::new(awg), None);
    install_panic_hook(safe);
    log.clear();
    let crashed = tokio::time::timeout(
        Duration::from_secs(30),
        tokio::spawn(async { panic!("a bug in the middle of a measurement") }),
    )
    .await
    .expect("the panicking task ended within 30 s");
    assert!(crashed.is_err(), "the task panicked");
    assert_eq!(log.ops(), AWG_SAFE_STATE);
}
