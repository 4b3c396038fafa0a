//! A panic runs the safe state from the panic hook (its own test binary: the hook is global).

use std::time::Duration;

use radbench::catalog::Catalog;
use radbench::driver::safe_state::{share, Bench};
use radbench::driver::scripted::ERROR_CHECK;
use radbench::driver::{install_panic_hook, Awg, M8195a, SafeState, Scripted};

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_panic_runs_the_safe_state_from_the_hook() {
    let catalog = Catalog::embedded().unwrap();
    let fake = Scripted::new("awg").reply("*IDN?", "Keysight Technologies,M8195A,MY1,4.0");
    let log = fake.log();
    let awg = M8195a::connect(
        Box::new(fake),
        catalog.get("keysight-m8195a").unwrap(),
        "awg",
    )
    .await
    .unwrap();
    let safe = SafeState::new(
        Bench {
            awg: Some(share::<dyn Awg>(Box::new(awg))),
            ..Bench::default()
        },
        Duration::from_secs(5),
    );
    install_panic_hook(safe);
    log.clear();
    let crashed = tokio::time::timeout(
        Duration::from_secs(30),
        tokio::spawn(async { panic!("a bug in the middle of a measurement") }),
    )
    .await
    .expect("the panicking task ended within 30 s");
    assert!(crashed.is_err(), "the task panicked");
    assert_eq!(
        log.ops(),
        [
            ":OUTP1 OFF",
            ":OUTP2 OFF",
            ":OUTP3 OFF",
            ":OUTP4 OFF",
            ":ABOR",
            ERROR_CHECK
        ]
    );
}
