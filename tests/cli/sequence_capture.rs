//! `--repetitions N` on a scope with sequence mode: one acquisition records the N triggers and one
//! `WF? ALL` per channel brings them back; without sequence mode in the catalog (or past its
//! segment count) the repetitions are separate acquisitions. Either way every repetition is one
//! repetition of the waveform and the targets are where the scene put them.

use radbench::catalog::Catalog;
use radbench::driver::RfPermit;
use radbench::measure::Interrupt;
use radbench::measure::ProcessOptions;
use radbench::measure::{prepare, Measurement, Rig};
use radbench::measure::{Bench, BenchSource, BuiltIn};
use radbench::waveform::WaveformKind;
use std::time::Duration;

const LABMASTER: &str = include_str!("../../instruments/lecroy_labmaster10zi_a.toml");

/// The built-in catalog with the LabMaster's `max_sequence_segments` set to `segments` (a
/// catalog folder overriding the built-in file, as a user's would).
fn catalog(dir: &std::path::Path, segments: u32) -> Catalog {
    let text = LABMASTER.replace(
        "max_sequence_segments = 15000",
        &format!("max_sequence_segments = {segments}"),
    );
    assert_ne!(text, LABMASTER, "the catalog line to change is there");
    std::fs::write(dir.join("lecroy_labmaster10zi_a.toml"), text).unwrap();
    Catalog::load(Some(dir)).unwrap()
}

/// One measurement of `repetitions` on the built-in mock lab (a pillar at 1 m) with `catalog`,
/// and what the scope emulator received.
async fn measure(catalog: &Catalog, repetitions: usize) -> (Measurement, Vec<String>) {
    let bench = Bench::open(BenchSource::BuiltIn(Box::<BuiltIn>::default()))
        .await
        .unwrap();
    let kind = WaveformKind::MskLfm;
    let mut options = ProcessOptions::for_waveform(kind);
    options.system_delay_s = bench.file.system_delay_s();
    let request = crate::support::thesis_request(kind, options, false);
    let mut prepared = prepare(&bench, catalog, &request).await.unwrap();
    let mut rig = Rig::connect(&bench, catalog, None).await.unwrap();
    let scope = bench.lab.as_ref().unwrap().bench.scope.clone();
    scope.log().clear();
    let m = tokio::time::timeout(
        Duration::from_secs(120),
        rig.measure(
            &bench,
            &mut prepared,
            repetitions,
            &RfPermit::granted_by_user(),
            &Interrupt::never(),
        ),
    )
    .await
    .expect("a measurement within 120 s")
    .unwrap();
    assert!(bench.lab.as_ref().unwrap().bench.is_safe());
    (m, scope.log().texts())
}

fn count(log: &[String], what: &str) -> usize {
    log.iter().filter(|t| t.contains(what)).count()
}

/// Every repetition found the pillar at 1 m, and the result too.
fn pillar_at_1_m(m: &Measurement) {
    let found: Vec<f64> = m
        .processing
        .processed
        .targets
        .iter()
        .map(|t| t.range_m)
        .collect();
    assert!(
        found.iter().any(|r| (r - 1.0).abs() < 1e-3),
        "result: {found:?}"
    );
    for (k, r) in m.processing.repetitions.iter().enumerate() {
        let found: Vec<f64> = r.targets.iter().map(|t| t.range_m).collect();
        assert!(
            found.iter().any(|r| (r - 1.0).abs() < 1e-3),
            "repetition {k}: {found:?}"
        );
    }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn repetitions_come_from_one_sequence_acquisition() {
    let (m, log) = measure(&Catalog::embedded().unwrap(), 4).await;
    assert_eq!(count(&log, "SampleMode = \"Sequence\""), 1, "{log:?}");
    assert_eq!(count(&log, "NumSegments = 4"), 1, "{log:?}");
    assert_eq!(count(&log, "ARM"), 1, "one acquisition: {log:?}");
    assert_eq!(count(&log, "WF? ALL"), 2, "one read per channel: {log:?}");
    assert_eq!(m.taken.captured.acquisitions.len(), 1);
    assert_eq!(m.taken.captured.repetitions(), 4);
    assert_eq!(m.processing.repetitions.len(), 4);
    // The segments were triggered by successive marker edges, in order, a whole number of
    // waveform repetitions apart.
    let period = m.taken.plan.period as f64 / 16e9;
    let times: Vec<f64> = (0..4)
        .map(|k| m.taken.captured.source(k).timing.trigger_time_s.unwrap())
        .collect();
    for pair in times.windows(2) {
        let gap = (pair[1] - pair[0]) / period;
        assert!(gap >= 1.0 && (gap - gap.round()).abs() < 1e-6, "{times:?}");
    }
    pillar_at_1_m(&m);
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn without_sequence_mode_each_repetition_is_an_acquisition() {
    let dir = tempfile::tempdir().unwrap();
    let (m, log) = measure(&catalog(dir.path(), 0), 3).await;
    assert_eq!(count(&log, "Sequence"), 0, "{log:?}");
    assert_eq!(count(&log, "SampleMode = \"RealTime\""), 1, "{log:?}");
    assert_eq!(count(&log, "ARM"), 3, "{log:?}");
    assert_eq!(count(&log, "WF? ALL"), 6, "{log:?}");
    assert_eq!(m.taken.captured.acquisitions.len(), 3);
    pillar_at_1_m(&m);
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn more_repetitions_than_segments_split_into_even_sequences() {
    let dir = tempfile::tempdir().unwrap();
    // 5 repetitions, at most 2 segments: three acquisitions of 2, the last segment unused.
    let (m, log) = measure(&catalog(dir.path(), 2), 5).await;
    assert_eq!(count(&log, "NumSegments = 2"), 1, "{log:?}");
    assert_eq!(count(&log, "ARM"), 3, "{log:?}");
    assert_eq!(m.taken.captured.acquisitions.len(), 3);
    assert_eq!(m.taken.captured.repetitions(), 5);
    let last = m.taken.captured.source(4);
    assert_eq!((last.acquisition, last.segment), (2, 0));
    assert_eq!(m.processing.repetitions.len(), 5);
    pillar_at_1_m(&m);
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_bench_files_own_catalog_folder_is_what_the_capture_uses() {
    use mock_lab::server::launch::Transport;
    let lab = tokio::time::timeout(
        Duration::from_secs(10),
        mock_lab::lab::start(mock_lab::lab::LabOptions::default()),
    )
    .await
    .expect("lab starts")
    .expect("lab starts");
    let dir = tempfile::tempdir().unwrap();
    let folder = dir.path().join("my-instruments");
    std::fs::create_dir(&folder).unwrap();
    // The folder overrides the built-in LabMaster: no sequence mode.
    catalog(&folder, 0);
    let bench = dir.path().join("bench.toml");
    let text = format!(
        "catalog = \"my-instruments\"\n{}",
        lab.bench_toml(Transport::Hislip, Transport::Vicp)
    );
    std::fs::write(&bench, text).unwrap();
    let journal = dir.path().join("io.jsonl");
    let scope = lab.bench.scope.clone();
    scope.log().clear();
    let (code, _, err) = crate::support::radbench_in(
        None,
        &[
            "--trace-io",
            journal.to_str().unwrap(),
            "capture",
            "--allow-rf",
            "--json",
            "--repetitions",
            "2",
            "--bench",
            bench.to_str().unwrap(),
            "--out",
            dir.path().join("out").to_str().unwrap(),
        ],
    )
    .await;
    assert_eq!(code, 0, "{err}");
    let log = scope.log().texts();
    assert_eq!(count(&log, "Sequence"), 0, "{log:?}");
    assert_eq!(count(&log, "ARM"), 2, "two acquisitions: {log:?}");

    // A folder that does not exist is named, with the bench file.
    std::fs::write(
        &bench,
        format!(
            "catalog = \"nowhere\"\n{}",
            lab.bench_toml(Transport::Hislip, Transport::Vicp)
        ),
    )
    .unwrap();
    let (code, _, err) = crate::support::radbench_in(
        None,
        &["capture", "--allow-rf", "--bench", bench.to_str().unwrap()],
    )
    .await;
    assert_eq!(code, 2, "{err}");
    assert!(err.contains("nowhere"), "{err}");
}

/// Both front ends are checked before either is switched on: a transmitter whose interlock is
/// open refuses the measurement before the receiver's enable is written, and nothing radiates.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_transmitter_not_ready_stops_the_measurement_before_the_receiver_is_enabled() {
    let bench = Bench::open(BenchSource::BuiltIn(Box::<BuiltIn>::default()))
        .await
        .unwrap();
    let catalog = Catalog::embedded().unwrap();
    let kind = WaveformKind::MskLfm;
    let request = crate::support::thesis_request(kind, ProcessOptions::for_waveform(kind), false);
    let mut prepared = prepare(&bench, &catalog, &request).await.unwrap();
    let mut rig = Rig::connect(&bench, &catalog, None).await.unwrap();
    let lab = &bench.lab.as_ref().unwrap().bench;
    lab.tx.set_interlock_open(true);
    lab.rx.log().clear();
    lab.scope.log().clear();
    let outcome = tokio::time::timeout(
        Duration::from_secs(120),
        rig.measure(
            &bench,
            &mut prepared,
            1,
            &RfPermit::granted_by_user(),
            &Interrupt::never(),
        ),
    )
    .await
    .expect("an answer within 120 s");
    let e = outcome
        .err()
        .expect("the open interlock refuses the measurement");
    assert!(e.to_string().contains("interlock"), "{e}");
    let rx_log = lab.rx.log().texts();
    assert!(
        rx_log.iter().any(|t| t.starts_with("R 01")),
        "the receiver was checked: {rx_log:?}"
    );
    let rx_enables: Vec<&String> = rx_log
        .iter()
        .filter(|t| t.starts_with("W 02 ") && !t.starts_with("W 02 0000"))
        .collect();
    assert!(
        rx_enables.is_empty(),
        "the receiver was switched on: {rx_enables:?}"
    );
    assert!(!lab.rx.front_end().rf_enabled);
    assert_eq!(
        count(&lab.scope.log().texts(), "ARM"),
        0,
        "nothing was acquired"
    );
    assert!(lab.is_safe());
}
