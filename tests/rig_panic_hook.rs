//! The panic path of every command that measures through `Rig` (`capture`, `capture --repeat`,
//! `align`, a campaign's steps, with or without `--live`): `Rig::connect` arms the process's
//! panic hook with the bench's safe state, so a panic anywhere in the process while the bench
//! radiates switches it off, before the panicking measurement is unwound (its own test binary:
//! the hook is global). Loopback only (the built-in mock lab), every wait bounded.

use radbench::catalog::Catalog;
use radbench::driver::RfPermit;
use radbench::measure::Interrupt;
use radbench::measure::ProcessOptions;
use radbench::measure::{prepare, CaptureRequest, Rig};
use radbench::measure::{Bench, BenchSource, BuiltIn};
use radbench::waveform::WaveformKind;
use std::sync::atomic::Ordering;
use std::time::Duration;

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_panic_while_a_rig_radiates_switches_the_bench_off() {
    let bench = Bench::open(BenchSource::BuiltIn(Box::<BuiltIn>::default()))
        .await
        .unwrap();
    let lab = &bench.lab.as_ref().unwrap().bench;
    // No trigger reaches the scope: the measurement waits with RF on.
    lab.marker_cable.store(false, Ordering::SeqCst);
    let catalog = Catalog::embedded().unwrap();
    let kind = WaveformKind::MskLfm;
    let request = CaptureRequest {
        waveform: kind.thesis_default(),
        payload: None,
        seed: 1,
        options: ProcessOptions::for_waveform(kind),
        tx_off: false,
        wait_s: 60.0,
        background: None,
    };
    let mut prepared = prepare(&bench, &catalog, &request).await.unwrap();
    let mut rig = Rig::connect(&bench, &catalog, None).await.unwrap();
    let permit = RfPermit::granted_by_user();
    let interrupt = Interrupt::never();
    let measuring = rig.measure(&bench, &mut prepared, 1, &permit, &interrupt);
    let panicked = async {
        let poll = async {
            while !(lab.tx.front_end().rf_enabled && lab.awg.playback().running) {
                tokio::time::sleep(Duration::from_millis(5)).await;
            }
        };
        tokio::time::timeout(Duration::from_secs(60), poll)
            .await
            .expect("RF on within 60 s");
        // A bug elsewhere in the process, while the measurement still waits with RF on.
        let crashed = tokio::time::timeout(
            Duration::from_secs(30),
            tokio::spawn(async { panic!("a bug in the middle of a measurement") }),
        )
        .await
        .expect("the panicking task ended within 30 s");
        assert!(crashed.is_err(), "the task panicked");
        // Checked here, while the measurement is still pending (its own guard has not run).
        assert!(lab.is_safe(), "the hook put the bench in its safe state");
        assert!(!lab.tx.front_end().rf_enabled && !lab.rx.front_end().rf_enabled);
    };
    tokio::select! {
        m = measuring => panic!("the measurement ended first: {:?}", m.err()),
        () = panicked => {}
    }
}
