//! instruments/README.md, "Adding a scope model with data only", done as it says: the WaveMaster
//! 820Zi-B file in `instruments/examples/` is loaded next to the built-in models, the unchanged
//! LeCroy driver runs it (against a scripted session and against mock_lab's scope emulator
//! reading the same file), and its own limits hold: what the LabMaster allows and the WaveMaster
//! does not is refused before anything is sent.

use crate::driver_support;

use std::path::{Path, PathBuf};
use std::sync::Arc;

use mock_lab::catalog::digitizer_from_str;
use mock_lab::emulator::lecroy::{Lecroy as ScopeEmu, RemoteInterface, TestSignal};
use mock_lab::server::{self, ServerHandle, ServerOptions};
use radbench::address::Resource;
use radbench::catalog::{Catalog, InstrumentModel, Origin};
use radbench::driver::{Digitizer, DigitizerSettings, DriverError, Lecroy, Scripted};
use radbench::exit::{Classify, ExitClass};

use driver_support::bounded;

const WAVEMASTER: &str = "lecroy-wavemaster820zi-b";
const LABMASTER: &str = "lecroy-labmaster10zi-a";

fn examples() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("instruments/examples")
}

fn model(key: &str) -> InstrumentModel {
    Catalog::load(Some(&examples()))
        .unwrap()
        .get(key)
        .unwrap()
        .clone()
}

/// The first thing the driver sends when asked to configure `settings` on `key`, once it is
/// connected to a script that answers nothing else: `None` when the settings were refused before
/// anything was sent.
async fn first_sent(key: &str, settings: &DigitizerSettings) -> (Option<String>, DriverError) {
    let m = model(key);
    let idn = format!(
        "{},{},EMU,1",
        m.identity.emulator.manufacturer, m.identity.emulator.model
    );
    let fake = Scripted::new("scope").reply("*IDN?", &idn);
    let log = fake.log();
    let mut scope = bounded(Lecroy::connect(Box::new(fake), &m, "scope"))
        .await
        .unwrap();
    log.clear();
    let e = bounded(scope.configure(settings)).await.unwrap_err();
    (log.ops().first().cloned(), e)
}

#[test]
fn the_example_folder_adds_the_wavemaster_next_to_the_built_in_models() {
    let catalog = Catalog::load(Some(&examples())).unwrap();
    let (wavemaster, origin) = catalog
        .models()
        .find(|(m, _)| m.instrument.key == WAVEMASTER)
        .expect("the example file is loaded");
    assert!(matches!(origin, Origin::File(_)), "{origin}");
    let labmaster = catalog.get(LABMASTER).unwrap();
    let (w, l) = (
        wavemaster.digitizer.as_ref().unwrap(),
        labmaster.digitizer.as_ref().unwrap(),
    );
    assert_eq!(
        (w.sample_rates.as_slice(), l.sample_rates.as_slice()),
        (&[40e9][..], &[80e9][..])
    );
    assert_eq!(
        (w.max_points_per_channel, l.max_points_per_channel),
        (10_000_000, 32_000_000)
    );
    let vendor = catalog.identify("LECROY,WM820ZI-B,LCRY0001,9.2.0").unwrap();
    assert_eq!(vendor.model.instrument.key, WAVEMASTER);
    let vendor = catalog.identify("LECROY,MCM-ZI-A,LCRY0002,8.5.0").unwrap();
    assert_eq!(vendor.model.instrument.key, LABMASTER);
}

#[tokio::test]
async fn a_rate_the_labmaster_runs_is_refused_by_the_wavemaster_before_anything_is_sent() {
    let settings = DigitizerSettings::default();
    assert_eq!(settings.sample_rate_hz, 80e9);
    let (sent, _) = first_sent(LABMASTER, &settings).await;
    assert_eq!(sent.as_deref(), Some("CMR?"), "the LabMaster goes ahead");
    let (sent, e) = first_sent(WAVEMASTER, &settings).await;
    assert_eq!(sent, None, "nothing sent to the WaveMaster");
    assert!(
        matches!(&e, DriverError::OutOfLimits { field: "sample_rate_hz", allowed, .. } if allowed.contains("40000000000")),
        "{e}"
    );
    assert_eq!(e.exit_class(), ExitClass::BadInput);
}

#[tokio::test]
async fn a_record_the_labmaster_holds_is_refused_by_the_wavemaster_before_anything_is_sent() {
    // 300 us: 24 Mpoints at the LabMaster's 80 GSa/s (32 M allowed), 12 Mpoints at the
    // WaveMaster's 40 GSa/s (10 M allowed).
    let long = |rate| DigitizerSettings {
        sample_rate_hz: rate,
        repetition_s: 300e-6,
        longest_echo_s: 0.0,
        ..DigitizerSettings::default()
    };
    let (sent, _) = first_sent(LABMASTER, &long(80e9)).await;
    assert_eq!(sent.as_deref(), Some("CMR?"), "the LabMaster goes ahead");
    let (sent, e) = first_sent(WAVEMASTER, &long(40e9)).await;
    assert_eq!(sent, None, "nothing sent to the WaveMaster");
    assert!(
        e.to_string()
            .contains("at most 10000000 points per channel"),
        "{e}"
    );
}

/// mock_lab's scope emulator with the limits and identity of the example file, over VICP.
async fn emulated_wavemaster() -> (Arc<ScopeEmu>, ServerHandle, Resource) {
    let text = std::fs::read_to_string(examples().join("lecroy_wavemaster820zi_b.toml")).unwrap();
    let emu_model = digitizer_from_str(&text).unwrap();
    let emu =
        Arc::new(ScopeEmu::new(emu_model, Arc::new(TestSignal::new(true, 1e9, 0.1))).unwrap());
    let handler = Arc::new(emu.port(RemoteInterface::Vicp));
    let handle = server::vicp::serve(server::loopback_any(), handler, ServerOptions::default())
        .await
        .expect("server starts");
    let resource = format!("VICP::127.0.0.1,{}", handle.local_addr().port())
        .parse()
        .unwrap();
    (emu, handle, resource)
}

#[tokio::test]
async fn the_unchanged_driver_captures_at_the_wavemasters_rate_on_its_emulator() {
    let (emu, _server, resource) = emulated_wavemaster().await;
    let m = model(WAVEMASTER);
    let mut scope = bounded(Lecroy::open(resource, &m, None, "scope"))
        .await
        .unwrap();
    let settings = DigitizerSettings {
        sample_rate_hz: 40e9,
        repetition_s: 1.024e-6,
        longest_echo_s: 0.1e-6,
        ..DigitizerSettings::default()
    };
    let applied = bounded(scope.configure(&settings)).await.unwrap();
    assert_eq!(applied.sample_rate_hz, 40e9);
    let capture = bounded(scope.capture_iq(5.0)).await.unwrap();
    assert_eq!(capture.i.segment_volts(0).len() as u64, applied.points);
    assert_eq!(capture.i.sample_interval_s as f32, 25e-12_f32);
    assert_eq!(
        capture.i.native.as_ref().unwrap().to_vec(),
        emu.trc_bytes(1).unwrap()
    );
}

#[tokio::test]
async fn the_labmaster_model_does_not_take_the_wavemaster_for_itself() {
    let (_emu, _server, resource) = emulated_wavemaster().await;
    let e = bounded(Lecroy::open(resource, &model(LABMASTER), None, "scope"))
        .await
        .err()
        .unwrap();
    assert!(matches!(e, DriverError::WrongInstrument { .. }), "{e}");
    assert!(e.to_string().contains("WM820ZI-B-EMU"), "{e}");
}
