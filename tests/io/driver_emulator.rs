//! Drivers against the mock_lab emulators over loopback, on every transport each instrument
//! supports: M8195A over raw socket, HiSLIP and VXI-11; LeCroy over VICP and VXI-11; Gotmic Tx/Rx
//! over a serial pseudo-terminal. Emulator rejections surface as device errors with code and text,
//! and the safe state leaves the emulated bench off.

use crate::driver_support;

use std::sync::Arc;

use driver_support::{bounded, guarded, model};
use mock_lab::emulator::gotmic::Gotmic as GotmicEmu;
use mock_lab::emulator::lecroy::{Lecroy as ScopeEmu, RemoteInterface, TestSignal};
use mock_lab::emulator::m8195a::M8195a as AwgEmu;
use mock_lab::server::vxi11::Vxi11Addresses;
use mock_lab::server::{self, Handler, ServerHandle, ServerOptions};
use radbench::address::Resource;
use radbench::catalog::InstrumentModel;
use radbench::driver::open_session;
use radbench::driver::{
    Awg, AwgSettings, Digitizer, DigitizerSettings, DriverError, Gotmic, IqWaveform, Lecroy,
    M8195a, ReferenceClock, RfFrontEnd, RfPermit, RfSettings,
};

#[derive(Debug, Clone, Copy)]
enum Net {
    Socket,
    Hislip,
    Vxi11,
    Vicp,
}

async fn serve(net: Net, handler: Arc<dyn Handler>) -> (ServerHandle, Resource) {
    let any = server::loopback_any();
    let options = ServerOptions::default();
    let handle = match net {
        Net::Socket => server::raw::serve(any, handler, options).await,
        Net::Hislip => server::hislip::serve(any, handler, options).await,
        Net::Vxi11 => server::vxi11::serve(Vxi11Addresses::loopback(), handler, options).await,
        Net::Vicp => server::vicp::serve(any, handler, options).await,
    }
    .expect("server starts");
    let port = handle.local_addr().port();
    let text = match net {
        Net::Socket => format!("TCPIP::127.0.0.1::{port}::SOCKET"),
        Net::Hislip => format!("TCPIP::127.0.0.1::hislip0,{port}::INSTR"),
        Net::Vxi11 => format!("TCPIP::127.0.0.1,{port}::inst0::INSTR"),
        Net::Vicp => format!("VICP::127.0.0.1,{port}"),
    };
    (handle, text.parse().unwrap())
}

// ---------------------------------------------------------------- M8195A

async fn awg_over(net: Net, driver_model: &InstrumentModel) -> (Arc<AwgEmu>, M8195a, ServerHandle) {
    let emu = Arc::new(AwgEmu::embedded().unwrap());
    let (server, resource) = serve(net, emu.clone()).await;
    let session = bounded(open_session(
        resource,
        driver_model,
        "SYST:ERR?",
        None,
        "awg",
    ))
    .await
    .unwrap();
    let awg = bounded(M8195a::connect(Box::new(session), driver_model, "awg"))
        .await
        .unwrap();
    (emu, awg, server)
}

fn waveform(n: usize) -> IqWaveform {
    IqWaveform {
        i: (0..n)
            .map(|k| ((k * 7) % 200) as i32 - 100)
            .map(|v| v as i8)
            .collect(),
        q: (0..n)
            .map(|k| ((k * 3) % 250) as i32 - 125)
            .map(|v| v as i8)
            .collect(),
        marker_high_samples: 64,
    }
}

async fn awg_plays_iq_with_a_marker(net: Net) {
    let m = model("keysight-m8195a");
    let (emu, mut awg, _server) = awg_over(net, &m).await;
    let settings = AwgSettings {
        reference_clock: ReferenceClock::External { frequency_hz: 10e6 },
        ..AwgSettings::default()
    };
    let applied = bounded(awg.configure(&settings)).await.unwrap();
    assert_eq!((applied.dac_mode.as_str(), applied.divider), ("DCM", 4));
    assert_eq!(applied.reference_source, "EXT");
    assert_eq!(applied.sample_rate_hz, 16e9);
    let wf = waveform(5000);
    let loaded = bounded(awg.load(&wf)).await.unwrap();
    assert_eq!(loaded.padded_samples, 5056);
    let permit = RfPermit::granted_by_user();
    bounded(awg.enable_outputs(&permit)).await.unwrap();
    bounded(awg.run()).await.unwrap();
    let applied = bounded(awg.applied()).await.unwrap();
    assert!(
        applied.outputs.iter().all(|o| o.on),
        "{:?}",
        applied.outputs
    );
    assert_eq!(applied.segments[0].samples, 5056);
    let play = emu.playback();
    assert!(play.running);
    assert_eq!(play.channels[0].sample_rate, 16e9);
    assert_eq!(&play.channels[0].samples[..5000], &wf.i[..]);
    assert_eq!(&play.channels[1].samples[..5000], &wf.q[..]);
    assert!(play.channels[0].samples[5000..].iter().all(|s| *s == 0));
    assert!(play.markers[..64].iter().all(|m| *m == 1));
    assert!(play.markers[64..].iter().all(|m| *m == 0));
    assert!(play.channels[2].output_on, "marker output on");
    bounded(awg.safe_state()).await.unwrap();
    let play = emu.playback();
    assert!(!play.running);
    assert!(play.channels.iter().all(|c| !c.output_on));
}

#[tokio::test]
async fn m8195a_over_raw_socket() {
    awg_plays_iq_with_a_marker(Net::Socket).await;
}

#[tokio::test]
async fn m8195a_over_hislip() {
    awg_plays_iq_with_a_marker(Net::Hislip).await;
}

#[tokio::test]
async fn m8195a_over_vxi11() {
    awg_plays_iq_with_a_marker(Net::Vxi11).await;
}

#[tokio::test]
async fn m8195a_output_on_before_a_waveform_is_refused_with_code_and_text() {
    let m = model("keysight-m8195a");
    let (_emu, mut awg, _server) = awg_over(Net::Socket, &m).await;
    bounded(awg.configure(&AwgSettings::default()))
        .await
        .unwrap();
    let permit = RfPermit::granted_by_user();
    let e = bounded(awg.enable_outputs(&permit)).await.unwrap_err();
    let errors = e.device_errors().expect("a device error");
    assert_eq!(errors[0].code, -221, "{e}");
    assert!(errors[0].message.contains("no waveform"), "{e}");
}

/// A catalog override that is wrong about the instrument: finer granularity, wider raster.
fn overconfident_awg_model() -> InstrumentModel {
    let mut m = model("keysight-m8195a");
    let awg_limits = m.awg.as_mut().unwrap();
    awg_limits.dac_rate_max = 70e9;
    for d in &mut awg_limits.dividers {
        if d.divider == 4 {
            d.granularity = 32;
            d.min_segment_samples = 160;
        }
    }
    m
}

#[tokio::test]
async fn m8195a_a_rate_the_catalog_wrongly_allows_is_refused_by_the_instrument() {
    let m = overconfident_awg_model();
    let (_emu, mut awg, _server) = awg_over(Net::Hislip, &m).await;
    let fast = AwgSettings {
        sample_rate_hz: 17e9,
        ..AwgSettings::default()
    };
    let e = bounded(awg.configure(&fast)).await.unwrap_err();
    assert!(matches!(e, DriverError::Refused { .. }), "{e}");
    assert_eq!(
        e.device_errors().unwrap()[0].code,
        -222,
        "rate outside the range: {e}"
    );
}

#[tokio::test]
async fn m8195a_a_granularity_the_catalog_wrongly_allows_is_refused_by_the_instrument() {
    let m = overconfident_awg_model();
    let (_emu, mut awg, _server) = awg_over(Net::Hislip, &m).await;
    bounded(awg.configure(&AwgSettings::default()))
        .await
        .unwrap();
    let e = bounded(awg.load(&waveform(1100))).await.unwrap_err();
    let errors = e.device_errors().expect("a device error");
    assert!(
        errors
            .iter()
            .any(|d| d.code == -222 && d.message.contains("granularity")),
        "{e}"
    );
}

// ---------------------------------------------------------------- LeCroy

fn capture_settings() -> DigitizerSettings {
    DigitizerSettings {
        repetition_s: 1.024e-6,
        longest_echo_s: 0.1e-6,
        pre_trigger_s: 10e-9,
        i_volts_per_div: 0.05,
        q_volts_per_div: 0.05,
        ..DigitizerSettings::default()
    }
}

async fn scope_over(
    net: Net,
    marker: bool,
) -> (Arc<ScopeEmu>, Arc<TestSignal>, Resource, ServerHandle) {
    let signal = Arc::new(TestSignal::new(marker, 1e9, 0.1));
    let emu = Arc::new(ScopeEmu::embedded_with(signal.clone()).unwrap());
    let via = match net {
        Net::Vicp => RemoteInterface::Vicp,
        _ => RemoteInterface::Vxi11,
    };
    emu.set_remote_interface(via);
    let (server, resource) = serve(net, Arc::new(emu.port(via))).await;
    (emu, signal, resource, server)
}

async fn scope_captures_iq(net: Net) {
    let (emu, _signal, resource, _server) = scope_over(net, true).await;
    let m = model("lecroy-labmaster10zi-a");
    let mut scope = bounded(Lecroy::open(resource, &m, None, "scope"))
        .await
        .unwrap();
    let settings = capture_settings();
    let applied = bounded(scope.configure(&settings)).await.unwrap();
    assert_eq!(applied.sample_rate_hz, 80e9);
    assert!(applied.record_s >= settings.record_s() * (1.0 - 1e-9));
    let capture = bounded(scope.capture_iq(5.0)).await.unwrap();
    let (i, q) = (capture.i.segment_volts(0), capture.q.segment_volts(0));
    assert_eq!(i.len() as u64, applied.points);
    assert_eq!(capture.i.sample_interval_s as f32, (1.0 / 80e9) as f32);
    let t = capture.i.segment_times(0);
    assert!(
        (t[0] + settings.pre_trigger_s).abs() < 1e-12,
        "record starts {} s",
        t[0]
    );
    // The test signal is a 0.1 V complex tone: |I + jQ| = 0.1 V within the 8-bit quantisation.
    for k in (0..i.len()).step_by(997) {
        let mag = (i[k] * i[k] + q[k] * q[k]).sqrt();
        assert!((mag - 0.1).abs() < 0.01, "|IQ| = {mag} at {k}");
    }
    // The saved .trc is exactly what the scope itself would save.
    assert_eq!(
        capture.i.native.as_ref().unwrap().to_vec(),
        emu.trc_bytes(1).unwrap()
    );
}

#[tokio::test]
async fn lecroy_over_vicp() {
    scope_captures_iq(Net::Vicp).await;
}

#[tokio::test]
async fn lecroy_over_vxi11() {
    scope_captures_iq(Net::Vxi11).await;
}

#[tokio::test]
async fn lecroy_without_marker_reports_no_marker_edge() {
    let (_emu, _signal, resource, _server) = scope_over(Net::Vicp, false).await;
    let m = model("lecroy-labmaster10zi-a");
    let mut scope = bounded(Lecroy::open(resource, &m, None, "scope"))
        .await
        .unwrap();
    bounded(scope.configure(&capture_settings())).await.unwrap();
    let e = bounded(scope.acquire(0.3)).await.unwrap_err();
    assert!(matches!(e, DriverError::NoTrigger { .. }), "{e}");
}

/// Opens the scope over `net` while its remote interface is set to `enabled`; the error.
async fn open_with_the_other_interface(
    net: Net,
    via: RemoteInterface,
    enabled: RemoteInterface,
) -> DriverError {
    let signal = Arc::new(TestSignal::default());
    let emu = Arc::new(ScopeEmu::embedded_with(signal).unwrap());
    emu.set_remote_interface(enabled);
    let (_server, resource) = serve(net, Arc::new(emu.port(via))).await;
    let mut m = model("lecroy-labmaster10zi-a");
    m.timeouts.read_ms = 300;
    bounded(Lecroy::open(resource, &m, None, "scope"))
        .await
        .err()
        .unwrap()
}

#[tokio::test]
async fn lecroy_over_vicp_while_set_to_vxi11_says_so() {
    let e = open_with_the_other_interface(Net::Vicp, RemoteInterface::Vicp, RemoteInterface::Vxi11)
        .await;
    assert!(matches!(e, DriverError::RemoteInterface { .. }), "{e}");
    assert!(e.to_string().contains("LXI (VXI-11)"), "{e}");
}

#[tokio::test]
async fn lecroy_over_vxi11_while_set_to_vicp_says_so() {
    let e =
        open_with_the_other_interface(Net::Vxi11, RemoteInterface::Vxi11, RemoteInterface::Vicp)
            .await;
    assert!(matches!(e, DriverError::RemoteInterface { .. }), "{e}");
    assert!(e.to_string().contains("TCPIP (VICP)"), "{e}");
}

// ---------------------------------------------------------------- Gotmic

fn serial_resource(path: &str) -> Resource {
    format!("ASRL{path}::INSTR").parse().unwrap()
}

/// A Gotmic emulator on a serial pseudo-terminal and the driver connected to it.
async fn gotmic_over_serial(
    key: &str,
    emu: GotmicEmu,
) -> (Arc<GotmicEmu>, Gotmic, server::serial::SerialHandle) {
    let emu = Arc::new(emu);
    let endpoint = server::serial::serve(emu.clone(), ServerOptions::default()).unwrap();
    let rf = bounded(Gotmic::open(
        serial_resource(endpoint.device_path()),
        &model(key),
        None,
        key,
    ))
    .await
    .unwrap();
    (emu, rf, endpoint)
}

/// A Gotmic module on one end of a pseudo-terminal pair, answered by the emulator on a thread:
/// `stale` is written before the driver opens its end; with `one_behind` every request is
/// answered with the reply owed to the previous one (the first with `late`), as a module still
/// answering an abandoned request of the port's previous user does. Returns the driver's
/// connect (its link flushes the line at open and does not wait for it to go quiet, as
/// `Gotmic::open` does).
async fn gotmic_with_a_stale_reply(
    stale: &'static [u8],
    one_behind: Option<&'static [u8]>,
) -> Result<Gotmic, DriverError> {
    use mock_lab::server::Handler;
    use radbench::transport::{OnOpen, SerialLink};
    use serialport::SerialPort;
    use std::io::{Read, Write};
    let (mut peer, client) = serialport::TTYPort::pair().expect("pty pair");
    peer.write_all(stale).unwrap();
    peer.flush().unwrap();
    let emu = GotmicEmu::tx_embedded().unwrap();
    std::thread::spawn(move || {
        let _ = peer.set_timeout(std::time::Duration::from_secs(20));
        let mut owed: Option<Vec<u8>> = one_behind.map(<[u8]>::to_vec);
        let mut line = Vec::new();
        let mut byte = [0u8; 1];
        while matches!(peer.read(&mut byte), Ok(1)) {
            line.push(byte[0]);
            if byte[0] != b'\n' {
                continue;
            }
            let mut reply = emu.message(&line).concat();
            reply.push(b'\n');
            line.clear();
            let out = match owed.as_mut() {
                Some(previous) => std::mem::replace(previous, reply),
                None => reply,
            };
            if peer.write_all(&out).and_then(|()| peer.flush()).is_err() {
                return;
            }
        }
    });
    let device = client.name().unwrap_or_default();
    let link = SerialLink::from_port_with(Box::new(client), device.clone(), 1 << 20, OnOpen::Flush)
        .unwrap();
    let resource = serial_resource(&device);
    let link = radbench::transport::Link::from_serial(
        resource,
        link,
        radbench::transport::LinkOptions::default(),
    );
    let session = radbench::session::Session::from_link(link, Default::default());
    let model = model("gotmic-eband-tx");
    bounded(Gotmic::connect_with(
        Box::new(session),
        &model,
        "tx",
        radbench::driver::Framing::from_catalog(&model),
    ))
    .await
}

/// A reply the port's previous user left unread on the line is flushed when the link opens (no
/// quiet-line wait): the module is identified by its own answers.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn gotmic_connect_flushes_a_reply_left_on_the_line() {
    let rf = gotmic_with_a_stale_reply(b"OK 0003\n", None)
        .await
        .expect("the stale reply is thrown away");
    assert_eq!(rf.identity().model, "GOTMIC-EBAND-TX-EMU");
}

/// A reply still in flight when the link opens (the module answers one request behind) is never
/// taken for the module's state: the connect's own exchanges find the replies out of step and
/// the connect fails.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn gotmic_connect_fails_when_a_stale_reply_puts_the_replies_out_of_step() {
    for late in [
        &b"OK 0003\n"[..],
        b"MOCK_LAB,GOTMIC-EBAND-TX-EMU,EMU0003,mock_lab-1\n",
    ] {
        let Err(e) = gotmic_with_a_stale_reply(b"", Some(late)).await else {
            panic!("a connect with its replies out of step succeeded");
        };
        assert!(
            matches!(
                e,
                DriverError::Reply { .. }
                    | DriverError::WrongInstrument { .. }
                    | DriverError::LineRefused { .. }
            ),
            "{e}"
        );
    }
}

async fn enable_read_back_and_disable(key: &str, emu: GotmicEmu) {
    let (emu, mut rf, _endpoint) = gotmic_over_serial(key, emu).await;
    let before = bounded(rf.status()).await.unwrap();
    assert!(!before.rf_enabled && before.powered);
    let permit = RfPermit::granted_by_user();
    let settings = RfSettings {
        attenuation_db: 12.5,
        lo_frequency_hz: Some(13.333e9),
    };
    let on = bounded(rf.enable(&permit, &settings)).await.unwrap();
    assert!(on.rf_enabled && on.lo_locked, "{key}: {on:?}");
    assert_eq!(on.attenuation_db, 12.5);
    assert!(emu.front_end().rf_enabled, "{key}");
    let framed = emu.log().texts();
    assert!(
        framed.iter().any(|t| t.starts_with("W 02 000F*")),
        "CRC-framed requests: {framed:?}"
    );
    bounded(rf.disable()).await.unwrap();
    let off = bounded(rf.status()).await.unwrap();
    assert!(!off.rf_enabled);
    assert_eq!(
        off.attenuation_db, 31.5,
        "maximum attenuation after disable"
    );
    assert!(!emu.front_end().rf_enabled);
}

#[tokio::test]
async fn gotmic_tx_over_serial_enables_reads_back_and_disables() {
    enable_read_back_and_disable("gotmic-eband-tx", GotmicEmu::tx_embedded().unwrap()).await;
}

#[tokio::test]
async fn gotmic_rx_over_serial_enables_reads_back_and_disables() {
    enable_read_back_and_disable("gotmic-eband-rx", GotmicEmu::rx_embedded().unwrap()).await;
}

#[tokio::test]
async fn gotmic_refuses_to_enable_with_the_interlock_open() {
    let (emu, mut tx, _endpoint) =
        gotmic_over_serial("gotmic-eband-tx", GotmicEmu::tx_embedded().unwrap()).await;
    emu.set_interlock_open(true);
    let e = bounded(tx.enable(&RfPermit::granted_by_user(), &RfSettings::default()))
        .await
        .unwrap_err();
    assert!(
        e.to_string().contains("interlock") || e.to_string().contains("INTERLOCK"),
        "{e}"
    );
    assert!(!emu.front_end().rf_enabled);
}

#[tokio::test]
async fn gotmic_switches_off_again_without_lo() {
    let (emu, mut tx, _endpoint) =
        gotmic_over_serial("gotmic-eband-tx", GotmicEmu::tx_embedded().unwrap()).await;
    emu.set_lo_present(false);
    let e = bounded(tx.enable(&RfPermit::granted_by_user(), &RfSettings::default()))
        .await
        .unwrap_err();
    assert!(e.to_string().contains("LO not present"), "{e}");
    assert!(!emu.front_end().rf_enabled);
    let sent = emu.log().texts();
    assert!(
        sent.iter().any(|t| t.starts_with("W 02 0000")),
        "switched off after the failed enable: {sent:?}"
    );
}

/// After a capture the driver reads the module back: as it was switched on, it passes; RF
/// tripped off by the interlock is the latched fault it is (not a glitch); a module power-cycled
/// with RF on is found back at its power-on state (here one whose CRC mode is fixed on, so it
/// still answers: registers at reset), or answering in the line mode of power-on (CRC off), or
/// not at all.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn gotmic_read_back_after_a_capture_finds_a_reset_module() {
    let permit = RfPermit::granted_by_user();
    let settings = RfSettings {
        attenuation_db: 12.5,
        lo_frequency_hz: None,
    };
    let emu = GotmicEmu::tx_embedded().unwrap();
    emu.set_crc_fixed(Some(true));
    let (emu, mut tx, endpoint) = gotmic_over_serial("gotmic-eband-tx", emu).await;
    let on = bounded(tx.enable(&permit, &settings)).await.unwrap();
    let now = bounded(tx.confirm_enabled(&on)).await.unwrap();
    assert!(now.rf_enabled && now.attenuation_db == 12.5, "{now:?}");

    emu.set_interlock_open(true);
    let e = bounded(tx.confirm_enabled(&on)).await.unwrap_err();
    assert!(matches!(e, DriverError::RfNotReady { .. }), "{e}");
    assert!(e.to_string().contains("INTERLOCK_OPENED"), "{e}");
    emu.set_interlock_open(false);
    bounded(tx.clear_faults()).await.unwrap();

    let on = bounded(tx.enable(&permit, &settings)).await.unwrap();
    emu.power_cycle();
    let e = bounded(tx.confirm_enabled(&on)).await.unwrap_err();
    assert_eq!(
        e.to_string(),
        "gotmic-eband-tx: the module is back at its power-on state (RF off, CONTROL 0x0000, \
         attenuation 31.5 dB) after the capture: it was reset or lost power during the capture, \
         which is not used"
    );
    assert_eq!(e.kind(), radbench::transport::ErrorKind::Retry);

    // Back at power-on in plain lines (CRC off), as the catalog's modules come up.
    emu.set_crc_fixed(None);
    let on = bounded(tx.enable(&permit, &settings)).await.unwrap();
    emu.power_cycle();
    let e = bounded(tx.confirm_enabled(&on)).await.unwrap_err();
    assert!(
        matches!(e, DriverError::StateLost { certain: true, .. })
            && e.to_string()
                .contains("answers without the CRC-8 framing it was switched to"),
        "{e}"
    );

    // No answer at all (the line gone): it may have been reset.
    drop(endpoint);
    let e = bounded(tx.confirm_enabled(&on)).await.unwrap_err();
    assert!(
        matches!(e, DriverError::StateLost { certain: false, .. })
            && e.to_string().contains("did not answer when read back")
            && e.to_string().contains("may have been reset or lost power"),
        "{e}"
    );
}

/// A module power-cycled after its line was switched to CRC-8 answers in plain lines (CRC off,
/// as at power-on): switching it off still succeeds, in plain lines, instead of a safe state
/// that reports "switch the bench off by hand" for a module that is already off.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn gotmic_switched_off_after_a_power_cycle_in_plain_lines() {
    let permit = RfPermit::granted_by_user();
    let settings = RfSettings {
        attenuation_db: 12.5,
        lo_frequency_hz: None,
    };
    let (emu, mut tx, _endpoint) =
        gotmic_over_serial("gotmic-eband-tx", GotmicEmu::tx_embedded().unwrap()).await;
    bounded(tx.enable(&permit, &settings)).await.unwrap();
    emu.power_cycle();
    bounded(tx.disable()).await.unwrap();
    let now = bounded(tx.status()).await.unwrap();
    assert!(!now.rf_enabled && now.attenuation_db == 31.5, "{now:?}");
}

// ---------------------------------------------------------------- safe state

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn safe_state_leaves_the_emulated_bench_off() {
    let m = model("keysight-m8195a");
    let (awg_emu, mut awg, _awg_server) = awg_over(Net::Socket, &m).await;
    let (tx_emu, mut tx, _endpoint) =
        gotmic_over_serial("gotmic-eband-tx", GotmicEmu::tx_embedded().unwrap()).await;
    let permit = RfPermit::granted_by_user();
    bounded(awg.configure(&AwgSettings::default()))
        .await
        .unwrap();
    bounded(awg.load(&waveform(2048))).await.unwrap();
    bounded(awg.enable_outputs(&permit)).await.unwrap();
    bounded(awg.run()).await.unwrap();
    bounded(tx.enable(&permit, &RfSettings::default()))
        .await
        .unwrap();
    assert!(awg_emu.playback().running && tx_emu.front_end().rf_enabled);
    let (safe, _awg, _tx) = guarded(Box::new(awg), Some(Box::new(tx)));
    // Dropping the guard (an error path that forgot the explicit call) still runs the sequence.
    drop(safe.guard());
    assert!(!tx_emu.front_end().rf_enabled);
    let play = awg_emu.playback();
    assert!(!play.running);
    assert!(play.channels.iter().all(|c| !c.output_on));
    let report = bounded(safe.engage()).await;
    assert!(report.is_safe(), "{report}");
}

/// An AWG over HiSLIP and a transmitter over serial, both emulated, under one safe state.
struct GuardedPair {
    awg_emu: Arc<AwgEmu>,
    tx_emu: Arc<GotmicEmu>,
    safe: radbench::driver::SafeState,
    awg: radbench::driver::Shared<dyn Awg>,
    tx: radbench::driver::Shared<dyn RfFrontEnd>,
    _servers: (ServerHandle, server::serial::SerialHandle),
}

async fn guarded_awg_and_tx() -> GuardedPair {
    let m = model("keysight-m8195a");
    let (awg_emu, awg, awg_server) = awg_over(Net::Hislip, &m).await;
    let (tx_emu, tx, endpoint) =
        gotmic_over_serial("gotmic-eband-tx", GotmicEmu::tx_embedded().unwrap()).await;
    let (safe, awg, tx) = guarded(Box::new(awg), Some(Box::new(tx)));
    GuardedPair {
        awg_emu,
        tx_emu,
        safe,
        awg,
        tx: tx.expect("a transmitter"),
        _servers: (awg_server, endpoint),
    }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn an_interrupted_measurement_still_ends_in_the_safe_state() {
    let bench = guarded_awg_and_tx().await;
    let (awg_emu, tx_emu, safe, awg, tx) =
        (bench.awg_emu, bench.tx_emu, bench.safe, bench.awg, bench.tx);
    let (radiating, interrupt) = tokio::sync::oneshot::channel::<()>();
    let work = async {
        let permit = RfPermit::granted_by_user();
        let mut a = awg.lock().await;
        a.configure(&AwgSettings::default()).await?;
        a.load(&waveform(4096)).await?;
        a.enable_outputs(&permit).await?;
        a.run().await?;
        tx.lock()
            .await
            .enable(&permit, &RfSettings::default())
            .await?;
        let _ = radiating.send(());
        // A capture that never ends, still holding the AWG: the interrupt must cut it short.
        std::future::pending::<()>().await;
        Ok::<(), DriverError>(())
    };
    let interrupt = async {
        interrupt
            .await
            .expect("the work reached the radiating state before the interrupt");
        assert!(tx_emu.front_end().rf_enabled && awg_emu.playback().running);
    };
    let (outcome, report) = bounded(radbench::driver::run_guarded(&safe, work, interrupt)).await;
    assert!(matches!(outcome, radbench::driver::Outcome::Interrupted));
    assert!(report.is_safe(), "{report}");
    assert!(!tx_emu.front_end().rf_enabled);
    let play = awg_emu.playback();
    assert!(!play.running && play.channels.iter().all(|c| !c.output_on));
}

/// The safe state switches every instrument off at once: a transmitter whose driver stays busy
/// (a hung operation holds it) does not keep the AWG playing while the Tx step waits it out.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_busy_transmitter_does_not_hold_the_awg_on() {
    let bench = guarded_awg_and_tx().await;
    let (awg_emu, tx_emu, safe, awg, tx) =
        (bench.awg_emu, bench.tx_emu, bench.safe, bench.awg, bench.tx);
    let permit = RfPermit::granted_by_user();
    {
        let mut a = awg.lock().await;
        bounded(a.configure(&AwgSettings::default())).await.unwrap();
        bounded(a.load(&waveform(2048))).await.unwrap();
        bounded(a.enable_outputs(&permit)).await.unwrap();
        bounded(a.run()).await.unwrap();
    }
    let mut held = tx.lock().await;
    bounded(held.enable(&permit, &RfSettings::default()))
        .await
        .unwrap();
    assert!(awg_emu.playback().running && tx_emu.front_end().rf_enabled);
    let mut engaged = tokio::spawn({
        let safe = safe.clone();
        async move { safe.engage().await }
    });
    // The Tx step waits up to its 5 s for the driver; 2 s in, the AWG is already off.
    let early = tokio::time::timeout(std::time::Duration::from_secs(2), &mut engaged).await;
    assert!(
        early.is_err(),
        "the Tx step cannot be done while its driver is held"
    );
    assert!(!awg_emu.playback().running, "the AWG waited for the Tx");
    assert!(awg_emu.playback().channels.iter().all(|c| !c.output_on));
    drop(held);
    let report = bounded(engaged).await.unwrap();
    assert!(report.is_safe(), "{report}");
    assert!(!tx_emu.front_end().rf_enabled);
    let steps: Vec<&str> = report.steps.iter().map(|s| s.step).collect();
    assert_eq!(steps, ["Tx RF off", "AWG outputs off and :ABOR"]);
}
