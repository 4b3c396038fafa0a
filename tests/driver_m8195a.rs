//! The M8195A driver against mock_lab's M8195A emulator over loopback (raw socket, HiSLIP, VXI-11): the
//! exact command sequence of each operation (read from the emulator's received log), what the AWG
//! then plays, limits refused before sending, and instrument refusals surfaced with code and text.

use std::future::Future;
use std::sync::Arc;
use std::time::Duration;

use mock_lab::emulator::m8195a::M8195a as Emulator;
use mock_lab::server::{self, Handler, ServerHandle, ServerOptions};
use radbench::catalog::Catalog;
use radbench::driver::m8195a::M8195a;
use radbench::driver::{Awg, AwgSetup, DriverError, IqWaveform};
use radbench::session::{Session, SessionOptions};
use radbench::transport::Timeouts;

const LIMIT: Duration = Duration::from_secs(60);

async fn bounded<T>(fut: impl Future<Output = T>) -> T {
    tokio::time::timeout(LIMIT, fut)
        .await
        .expect("finished within the test's time limit")
}

#[derive(Clone, Copy, Debug)]
enum Proto {
    Socket,
    Hislip,
    Vxi11,
}

struct Bench {
    emulator: Arc<Emulator>,
    driver: M8195a,
    _server: ServerHandle,
}

async fn start(proto: Proto) -> Bench {
    let emulator = Arc::new(Emulator::embedded().unwrap());
    let handler: Arc<dyn Handler> = emulator.clone();
    let any = server::loopback_any();
    let options = ServerOptions::default();
    let server = match proto {
        Proto::Socket => server::raw::serve(any, handler, options).await,
        Proto::Hislip => server::hislip::serve(any, handler, options).await,
        Proto::Vxi11 => {
            server::vxi11::serve(server::vxi11::Vxi11Addresses::loopback(), handler, options).await
        }
    }
    .expect("server starts");
    let port = server.local_addr().port();
    let resource = match proto {
        Proto::Socket => format!("TCPIP::127.0.0.1::{port}::SOCKET"),
        Proto::Hislip => format!("TCPIP::127.0.0.1::hislip0,{port}::INSTR"),
        Proto::Vxi11 => format!("TCPIP::127.0.0.1,{port}::inst0::INSTR"),
    };
    let mut options = SessionOptions::default();
    options.link.timeouts = Timeouts {
        connect: Duration::from_secs(5),
        read: Duration::from_secs(10),
        write: Duration::from_secs(10),
        min_rate_bytes_per_s: 20_000_000,
    };
    let session = bounded(Session::open(
        resource.parse().unwrap(),
        options,
        None,
        "awg",
    ))
    .await
    .expect("session opens");
    let catalog = Catalog::embedded().unwrap();
    let model = catalog.get("keysight-m8195a").unwrap();
    let driver = bounded(M8195a::connect(session, model))
        .await
        .expect("driver connects");
    emulator.log().clear();
    Bench {
        emulator,
        driver,
        _server: server,
    }
}

fn setup() -> AwgSetup {
    AwgSetup {
        sample_rate: 16e9,
        amplitude_vpp: 0.5,
        marker_low_v: 0.0,
        marker_high_v: 0.8,
    }
}

fn waveform(n: usize) -> IqWaveform {
    let i = (0..n).map(|k| ((k * 3) % 200) as i8).collect();
    let q = (0..n).map(|k| -(((k * 5) % 100) as i8)).collect();
    IqWaveform::with_leading_marker(i, q, 32)
}

fn errs(texts: &[String]) -> usize {
    texts.iter().filter(|t| t.as_str() == "SYST:ERR?").count()
}

async fn full_sequence(proto: Proto) {
    let mut bench = start(proto).await;
    let applied = bounded(bench.driver.configure(&setup())).await.unwrap();
    assert_eq!(applied.dac_mode, "DCM");
    assert_eq!(applied.divider, 4);
    assert_eq!(applied.dac_rate, 64e9);
    assert_eq!(applied.sample_rate, 16e9);
    assert_eq!(applied.amplitude_vpp, [0.5, 0.5]);

    let configure_log = bench.emulator.log().texts();
    assert_eq!(
        &configure_log[..16],
        [
            ":ABOR",
            ":INST:DACM DCM",
            ":INST:MEM:EXT:RDIV DIV4",
            ":TRAC1:MMOD EXT",
            ":TRAC2:MMOD EXT",
            ":FREQ:RAST 6.4E10",
            ":FUNC:MODE ARB",
            ":INIT:CONT 1",
            ":INIT:GATE 0",
            ":VOLT1 0.5",
            ":VOLT2 0.5",
            ":VOLT3:AMPL 0.8",
            ":VOLT3:OFFS 0.4",
            ":VOLT4:AMPL 0.8",
            ":VOLT4:OFFS 0.4",
            "SYST:ERR?",
        ]
    );
    bench.emulator.log().clear();

    let wf = waveform(1000);
    let padded = bounded(bench.driver.load(&wf)).await.unwrap();
    assert_eq!(padded, 1024, "padded to the DIV4 granularity of 64");
    assert_eq!(
        bench.emulator.log().texts(),
        [
            ":ABOR",
            ":TRAC1:DEL:ALL",
            ":TRAC1:DEF 1,1024",
            "SYST:ERR?",
            ":TRAC1:DATA 1,0,#<2048 bytes>",
            ":TRAC2:DATA 1,0,#<1024 bytes>",
            "*OPC?",
            ":TRAC1:SEL 1",
            ":TRAC2:SEL 1",
            "SYST:ERR?",
        ]
    );
    bench.emulator.log().clear();
    bounded(bench.driver.set_outputs(true)).await.unwrap();
    bounded(bench.driver.run()).await.unwrap();
    let texts = bench.emulator.log().texts();
    assert_eq!(
        texts[..4],
        [":OUTP1 ON", ":OUTP2 ON", ":OUTP3 ON", ":OUTP4 ON"]
    );
    assert_eq!(texts[texts.len() - 2..], [":INIT:IMM", "SYST:ERR?"]);

    let play = bench.emulator.playback();
    assert!(play.running && play.marker_active());
    let ch1 = play.channel(1).unwrap();
    assert_eq!(ch1.sample_rate, 16e9);
    assert_eq!(&ch1.samples[..1000], &wf.i[..]);
    assert!(ch1.samples[1000..].iter().all(|s| *s == 0), "zero padding");
    assert_eq!(&play.channel(2).unwrap().samples[..1000], &wf.q[..]);
    assert!(play.markers[..32].iter().all(|m| *m == 0b11));
    assert!(play.markers[32..].iter().all(|m| *m == 0));

    let applied = bounded(bench.driver.applied()).await.unwrap();
    assert_eq!(applied.segment_samples, 1024);
    assert_eq!(applied.outputs, [true; 4]);

    bounded(bench.driver.stop()).await.unwrap();
    assert!(!bench.emulator.playback().running);
    bounded(bench.driver.set_outputs(false)).await.unwrap();
    assert!(bench
        .emulator
        .playback()
        .channels
        .iter()
        .all(|c| !c.output_on));
}

#[tokio::test]
async fn full_sequence_over_raw_socket() {
    full_sequence(Proto::Socket).await;
}

#[tokio::test]
async fn full_sequence_over_hislip() {
    full_sequence(Proto::Hislip).await;
}

#[tokio::test]
async fn full_sequence_over_vxi11() {
    full_sequence(Proto::Vxi11).await;
}

#[tokio::test]
async fn chunked_download_in_ascending_offsets() {
    let mut bench = start(Proto::Socket).await;
    bounded(bench.driver.configure(&setup())).await.unwrap();
    bench.emulator.log().clear();
    // 1.2 M samples: three chunks of at most 512 000 samples.
    let n = 1_200_000;
    let wf = waveform(n);
    let padded = bounded(bench.driver.load(&wf)).await.unwrap();
    assert_eq!(padded, 1_200_000);
    let data: Vec<String> = bench
        .emulator
        .log()
        .texts()
        .into_iter()
        .filter(|t| t.contains(":DATA"))
        .collect();
    assert_eq!(
        data,
        [
            ":TRAC1:DATA 1,0,#<1024000 bytes>",
            ":TRAC2:DATA 1,0,#<512000 bytes>",
            ":TRAC1:DATA 1,512000,#<1024000 bytes>",
            ":TRAC2:DATA 1,512000,#<512000 bytes>",
            ":TRAC1:DATA 1,1024000,#<352000 bytes>",
            ":TRAC2:DATA 1,1024000,#<176000 bytes>",
        ]
    );
    let play = bench.emulator.playback();
    assert_eq!(&play.channel(1).unwrap().samples[..], &wf.i[..]);
    assert_eq!(&play.channel(2).unwrap().samples[..], &wf.q[..]);
}

#[tokio::test]
async fn values_outside_the_catalog_are_refused_before_sending() {
    let mut bench = start(Proto::Socket).await;
    let cases = [
        AwgSetup {
            sample_rate: 20e9,
            ..setup()
        },
        AwgSetup {
            sample_rate: 70e9,
            ..setup()
        },
        AwgSetup {
            amplitude_vpp: 1.2,
            ..setup()
        },
        AwgSetup {
            marker_high_v: 0.05,
            ..setup()
        },
    ];
    for case in cases {
        let err = bounded(bench.driver.configure(&case)).await.unwrap_err();
        assert!(matches!(err, DriverError::Limit { .. }), "{err}");
        assert_eq!(err.kind(), radbench::transport::ErrorKind::FixInput);
    }
    let err = bounded(bench.driver.configure(&AwgSetup {
        sample_rate: 20e9,
        ..setup()
    }))
    .await
    .unwrap_err();
    assert!(
        err.to_string().contains("sample_rate = 20000000000"),
        "{err}"
    );
    let bad = IqWaveform {
        i: vec![0; 10],
        q: vec![0; 9],
        marker: vec![false; 10],
    };
    bounded(bench.driver.configure(&setup())).await.unwrap();
    bench.emulator.log().clear();
    assert!(matches!(
        bounded(bench.driver.load(&bad)).await.unwrap_err(),
        DriverError::Limit { .. }
    ));
    assert!(bench.emulator.log().texts().is_empty(), "nothing was sent");
    // Other rates pick the divider whose raster is in range: 60 GSa/s direct from DIV1.
    let applied = bounded(bench.driver.configure(&AwgSetup {
        sample_rate: 60e9,
        ..setup()
    }))
    .await
    .unwrap();
    assert_eq!((applied.divider, applied.dac_rate), (1, 60e9));
    assert_eq!(errs(&bench.emulator.log().texts()), 1);
}

#[tokio::test]
async fn instrument_refusals_carry_code_and_text() {
    let mut bench = start(Proto::Socket).await;
    bounded(bench.driver.configure(&setup())).await.unwrap();
    let err = bounded(bench.driver.set_outputs(true)).await.unwrap_err();
    let errors = err.to_string();
    assert!(errors.contains("-221"), "{errors}");
    assert!(errors.contains("Settings conflict"), "{errors}");
    let DriverError::Session(session) = &err else {
        panic!("expected a device error, got {err}");
    };
    let device = session.device_errors().expect("device errors");
    assert!(device.iter().all(|e| e.code == -221));
    let err = bounded(bench.driver.run()).await.unwrap_err();
    assert_eq!(err.to_string().matches("-221").count(), 1, "{err}");
}

#[tokio::test]
async fn a_different_instrument_is_refused() {
    let emulator: Arc<dyn Handler> =
        Arc::new(mock_lab::emulator::gotmic::Gotmic::tx_embedded().unwrap());
    let server = server::raw::serve(server::loopback_any(), emulator, ServerOptions::default())
        .await
        .unwrap();
    let resource = format!("TCPIP::127.0.0.1::{}::SOCKET", server.local_addr().port());
    let session = bounded(Session::open(
        resource.parse().unwrap(),
        SessionOptions::default(),
        None,
        "awg",
    ))
    .await
    .unwrap();
    let catalog = Catalog::embedded().unwrap();
    let result = bounded(M8195a::connect(
        session,
        catalog.get("keysight-m8195a").unwrap(),
    ))
    .await;
    assert!(matches!(result, Err(DriverError::WrongInstrument { .. })));
}
