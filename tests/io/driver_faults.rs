//! Real drivers and sessions against the emulated bench on 127.0.0.1, with client-side faults
//! ([`FaultyIo`]) between each driver and its session: links time out before a command is sent,
//! lose the reply after the instrument acted, drop until reconnected, or lag. Over several seeds a
//! whole capture (configure, load, enable under an `RfPermit`, capture) either succeeds with this
//! run's data or fails with a link error, never a wrong or stale answer and never a panic; and
//! the bench always ends in its safe state (Tx RF off, AWG outputs off, AWG stopped).

use crate::driver_support;

use std::time::Duration;

use driver_support::{bounded, model};
use mock_lab::lab::{self, Lab, LabOptions};
use mock_lab::server::launch::Transport;
use radbench::address::Resource;
use radbench::driver::Framing;
use radbench::driver::COMMAND_ERRORS;
use radbench::driver::{open_session, session_options};
use radbench::driver::{
    run_guarded, Awg, AwgSettings, Digitizer, DigitizerSettings, DriverError, ErrorKind, FaultPlan,
    FaultSwitch, FaultyIo, Gotmic, IqCapture, IqWaveform, Lecroy, LoadedSegment, M8195a, Outcome,
    RfFrontEnd, RfPermit, RfSettings, SafeState,
};
use radbench::driver::{share, Bench as Drivers, Shared};
use radbench::rng::SplitMix64;
use radbench::session::{Session, SCPI_ERROR_QUERY};
use radbench::transport::LinkError;

/// Seeds per test: enough for both outcomes to show, few enough to stay within a few seconds.
const SEEDS: u64 = 8;

/// About one failed operation in a hundred, and some lag: a capture is some eighty operations
/// over the three links, so roughly half the runs meet a fault and half get through.
const CAPTURE_FAULTS: FaultPlan = FaultPlan {
    timeout_per_mille: 4,
    reply_lost_per_mille: 4,
    drop_per_mille: 2,
    delay_per_mille: 50,
    max_delay: Duration::from_millis(2),
};

/// Hostile enough that the safe-state sequence itself (some ten operations) fails in most runs.
const SAFE_STATE_FAULTS: FaultPlan = FaultPlan {
    timeout_per_mille: 30,
    reply_lost_per_mille: 30,
    drop_per_mille: 20,
    delay_per_mille: 100,
    max_delay: Duration::from_millis(1),
};

async fn start_lab() -> Lab {
    bounded(lab::start(LabOptions::default()))
        .await
        .expect("the emulated lab starts")
}

fn resource(lab: &Lab, instrument: &str, transport: Transport) -> Resource {
    lab.endpoint(instrument, transport)
        .expect("the lab serves this endpoint")
        .resource
        .parse()
        .expect("a resource string")
}

/// The bench's drivers, each on a real session wrapped in a [`FaultyIo`] under one switch.
struct FaultyBench {
    switch: FaultSwitch,
    awg: Shared<dyn Awg>,
    tx: Shared<dyn RfFrontEnd>,
    scope: Lecroy,
    safe: SafeState,
}

/// Opens the AWG (HiSLIP), the scope (VICP) and the transmitter (serial) with faults switched
/// off, so every run starts connected and identified; the caller switches them on. Each link gets
/// its own seed, derived from `seed`.
async fn open_bench(lab: &Lab, seed: u64, plan: FaultPlan) -> FaultyBench {
    let switch = FaultSwitch::new();
    switch.set_enabled(false);
    let faulty = |session: Session, salt: u64| {
        let seed = seed ^ salt.wrapping_mul(0x9E37_79B9_7F4A_7C15);
        Box::new(FaultyIo::with_switch(
            Box::new(session),
            seed,
            plan,
            switch.clone(),
        ))
    };

    let awg_model = model("keysight-m8195a");
    let session = open_session(
        resource(lab, "awg", Transport::Hislip),
        &awg_model,
        SCPI_ERROR_QUERY,
        None,
        "awg",
    );
    let session = bounded(session).await.expect("AWG session");
    let awg = bounded(M8195a::connect(faulty(session, 1), &awg_model, "awg"))
        .await
        .expect("AWG identified");

    let scope_model = model("lecroy-labmaster10zi-a");
    let session = open_session(
        resource(lab, "scope", Transport::Vicp),
        &scope_model,
        COMMAND_ERRORS,
        None,
        "scope",
    );
    let session = bounded(session).await.expect("scope session");
    let scope = bounded(Lecroy::connect(faulty(session, 2), &scope_model, "scope"))
        .await
        .expect("scope identified");

    // What Gotmic::open does (the catalog's serial settings are the link defaults), with the
    // session wrapped.
    let tx_model = model("gotmic-eband-tx");
    let session = Session::open(
        resource(lab, "tx", Transport::Serial),
        session_options(&tx_model, ""),
        None,
        "tx",
    );
    let session = bounded(session).await.expect("Tx session");
    let tx = Gotmic::connect_with(
        faulty(session, 3),
        &tx_model,
        "tx",
        Framing::from_catalog(&tx_model),
    );
    let tx = bounded(tx).await.expect("Tx identified");

    let awg = share(Box::new(awg) as Box<dyn Awg>);
    let tx = share(Box::new(tx) as Box<dyn RfFrontEnd>);
    let safe = SafeState::new(
        Drivers {
            tx: Some(tx.clone()),
            rx: None,
            awg: Some(awg.clone()),
        },
        Duration::from_secs(5),
    );
    FaultyBench {
        switch,
        awg,
        tx,
        scope,
        safe,
    }
}

/// A waveform of this seed's own random codes, so data left over from another run is noticed.
fn waveform(seed: u64) -> IqWaveform {
    let mut rng = SplitMix64::new(seed);
    let mut codes = |n: usize| (0..n).map(|_| rng.next_u64() as i8).collect::<Vec<i8>>();
    IqWaveform {
        i: codes(4096),
        q: codes(4096),
        marker_high_samples: 64,
    }
}

/// The driver operations of one capture, as the station runs them.
async fn capture(
    bench: &mut FaultyBench,
    wf: &IqWaveform,
) -> Result<(LoadedSegment, u64, IqCapture), DriverError> {
    let permit = RfPermit::granted_by_user();
    let awg_settings = AwgSettings::default();
    let mut awg = bench.awg.lock().await;
    awg.configure(&awg_settings).await?;
    let loaded = awg.load(wf).await?;
    let scope_settings = DigitizerSettings {
        repetition_s: loaded.padded_samples as f64 / awg_settings.sample_rate_hz,
        ..DigitizerSettings::default()
    };
    let applied = bench.scope.configure(&scope_settings).await?;
    awg.enable_outputs(&permit).await?;
    awg.run().await?;
    drop(awg);
    bench
        .tx
        .lock()
        .await
        .enable(&permit, &RfSettings::default())
        .await?;
    let iq = bench.scope.capture_iq(2.0).await?;
    Ok((loaded, applied.points, iq))
}

/// A fault may only show as the link failure it is: a timeout or a closed connection of an
/// injected fault, kind Retry.
fn assert_injected_link_failure(seed: u64, e: &DriverError) {
    let link = match e {
        DriverError::Session { source, .. } => source.link_error(),
        _ => None,
    };
    assert!(
        matches!(
            link,
            Some(LinkError::Timeout { .. } | LinkError::Closed { .. })
        ) && e.kind() == ErrorKind::Retry
            && e.to_string().contains("(injected fault)"),
        "seed {seed}: a fault showed as something else than a link failure: {e}"
    );
}

fn assert_bench_safe(seed: u64, lab: &Lab) {
    let play = lab.bench.awg.playback();
    assert!(
        lab.bench.is_safe(),
        "seed {seed}: bench not safe: Tx RF on {}, AWG running {}, outputs on {:?}",
        lab.bench.tx.front_end().rf_enabled,
        play.running,
        play.channels
            .iter()
            .map(|c| c.output_on)
            .collect::<Vec<_>>()
    );
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_capture_under_link_faults_gives_the_right_data_or_a_link_error_and_ends_safe() {
    // One lab for all seeds: a run also starts from whatever the previous, faulted one left.
    let lab = start_lab().await;
    let (mut succeeded, mut failed, mut injected) = (0, 0, 0);
    for seed in 0..SEEDS {
        let mut bench = open_bench(&lab, seed, CAPTURE_FAULTS).await;
        let switch = bench.switch.clone();
        let wf = waveform(seed);
        let safe = bench.safe.clone();
        switch.set_enabled(true);
        // The safe state goes over the same links as the measurement, so the work switches the
        // faults off as its last step: the capture runs under faults, the safe state on a
        // healthy link. That shows a fault mid-capture leaves nothing behind (a held lock, a
        // half-read reply, a driver in a state it cannot leave) that keeps the bench from being
        // switched off. The safe state under faults is the next test.
        let work = async {
            let result = capture(&mut bench, &wf).await;
            switch.set_enabled(false);
            result
        };
        let (outcome, report) =
            bounded(run_guarded(&safe, work, std::future::pending::<()>())).await;
        let Outcome::Finished(result) = outcome else {
            panic!("seed {seed}: nothing interrupts this run");
        };
        match result {
            Ok((loaded, points, iq)) => {
                succeeded += 1;
                // The AWG plays this run's waveform and the capture is the scope's last
                // acquisition, byte for byte: no stale data from an earlier run or reply.
                assert_eq!(loaded.samples, 4096, "seed {seed}");
                let play = lab.bench.awg.playback();
                assert_eq!(&play.channels[0].samples[..4096], &wf.i[..], "seed {seed}");
                assert_eq!(&play.channels[1].samples[..4096], &wf.q[..], "seed {seed}");
                assert_eq!(iq.i.codes.len() as u64, points, "seed {seed}");
                assert_eq!(
                    iq.i.native.as_ref().map(|f| f.to_vec()),
                    lab.bench.scope.trc_bytes(1),
                    "seed {seed}: I is the scope's last acquisition"
                );
                assert_eq!(
                    iq.q.native.as_ref().map(|f| f.to_vec()),
                    lab.bench.scope.trc_bytes(2),
                    "seed {seed}: Q is the scope's last acquisition"
                );
            }
            Err(e) => {
                failed += 1;
                assert_injected_link_failure(seed, &e);
            }
        }
        assert!(report.is_safe(), "seed {seed}: {report}");
        assert_bench_safe(seed, &lab);
        injected += switch.counts().injected();
    }
    assert!(injected > 0, "no fault was injected over {SEEDS} seeds");
    assert!(
        succeeded > 0 && failed > 0,
        "both outcomes over {SEEDS} seeds: {succeeded} succeeded, {failed} failed"
    );
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_safe_state_under_link_faults_never_reports_safe_wrongly_and_succeeds_once_healed() {
    let lab = start_lab().await;
    let (mut complete, mut incomplete, mut injected) = (0, 0, 0);
    for seed in 0..SEEDS {
        let mut bench = open_bench(&lab, seed, SAFE_STATE_FAULTS).await;
        let switch = bench.switch.clone();
        let wf = waveform(seed);
        let safe = bench.safe.clone();
        // Radiating first, on healthy links; then the faults go on for the safe state only.
        let work = async {
            let result = capture(&mut bench, &wf).await;
            switch.set_enabled(true);
            result
        };
        let (outcome, report) =
            bounded(run_guarded(&safe, work, std::future::pending::<()>())).await;
        assert!(
            matches!(outcome, Outcome::Finished(Ok(_))),
            "seed {seed}: the capture runs on healthy links"
        );
        // The report may be pessimistic (a lost reply hides a step that did happen) but never
        // claims a safe bench that is not.
        if report.is_safe() {
            complete += 1;
            assert_bench_safe(seed, &lab);
        } else {
            incomplete += 1;
            assert!(
                report.to_string().contains("(injected fault)"),
                "seed {seed}: a failed step names the link failure: {report}"
            );
        }
        injected += switch.counts().injected();
        // The link comes back: the next safe state (a retry, the drop guard) completes.
        switch.set_enabled(false);
        let report = bounded(safe.engage()).await;
        assert!(report.is_safe(), "seed {seed}: {report}");
        assert_bench_safe(seed, &lab);
    }
    assert!(injected > 0, "no fault was injected over {SEEDS} seeds");
    assert!(
        complete > 0 && incomplete > 0,
        "both outcomes over {SEEDS} seeds: {complete} complete, {incomplete} incomplete"
    );
}
