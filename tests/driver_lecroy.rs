//! The LeCroy driver against mock_lab's scope emulator over loopback. The VICP and VXI-11 servers
//! are being built on another branch; until they land these tests run the same driver over the raw
//! socket and HiSLIP servers (the driver only sees whole messages, so the command sequence, the
//! WAVEDESC decoding and the error paths are the same).

use std::future::Future;
use std::sync::Arc;
use std::time::Duration;

use mock_lab::emulator::lecroy::{Lecroy as Emulator, RemoteInterface, TestSignal};
use mock_lab::server::{self, Handler, ServerHandle, ServerOptions};
use radbench::address::Resource;
use radbench::catalog::Catalog;
use radbench::driver::lecroy::Lecroy;
use radbench::driver::{Digitizer, DigitizerSetup, DriverError};
use radbench::session::SessionOptions;
use radbench::transport::Timeouts;

const LIMIT: Duration = Duration::from_secs(60);

async fn bounded<T>(fut: impl Future<Output = T>) -> T {
    tokio::time::timeout(LIMIT, fut)
        .await
        .expect("finished within the test's time limit")
}

fn options(read: Duration) -> SessionOptions {
    let mut o = SessionOptions::default();
    o.link.timeouts = Timeouts {
        connect: Duration::from_secs(5),
        read,
        write: Duration::from_secs(10),
        min_rate_bytes_per_s: 20_000_000,
    };
    o
}

async fn serve(handler: Arc<dyn Handler>, hislip: bool) -> (ServerHandle, Resource) {
    let any = server::loopback_any();
    let server = if hislip {
        server::hislip::serve(any, handler, ServerOptions::default()).await
    } else {
        server::raw::serve(any, handler, ServerOptions::default()).await
    }
    .expect("server starts");
    let port = server.local_addr().port();
    let text = if hislip {
        format!("TCPIP::127.0.0.1::hislip0,{port}::INSTR")
    } else {
        format!("TCPIP::127.0.0.1::{port}::SOCKET")
    };
    (server, text.parse().unwrap())
}

struct Bench {
    emulator: Arc<Emulator>,
    signal: Arc<TestSignal>,
    driver: Lecroy,
    _server: ServerHandle,
}

async fn start(marker: bool, hislip: bool) -> Bench {
    let signal = Arc::new(TestSignal::new(marker, 1e9, 0.1));
    let emulator = Arc::new(Emulator::embedded_with(signal.clone()).unwrap());
    let (server, resource) = serve(emulator.clone(), hislip).await;
    let catalog = Catalog::embedded().unwrap();
    let model = catalog.get("lecroy-labmaster10zi-a").unwrap();
    let driver = bounded(Lecroy::open(
        resource,
        options(Duration::from_secs(10)),
        model,
    ))
    .await
    .expect("driver connects");
    emulator.log().clear();
    Bench {
        emulator,
        signal,
        driver,
        _server: server,
    }
}

fn setup() -> DigitizerSetup {
    DigitizerSetup {
        sample_rate: 80e9,
        record_seconds: 1.024e-6,
        trigger_level_v: 0.2,
        volts_per_div: 0.05,
    }
}

async fn single_shot(hislip: bool) {
    let mut bench = start(true, hislip).await;
    let applied = bounded(bench.driver.configure(&setup())).await.unwrap();
    assert_eq!(applied.sample_rate, 80e9);
    assert_eq!(applied.points, 81_920);
    assert_eq!(
        bench.emulator.log().texts(),
        [
            "CHDR OFF",
            "CFMT DEF9,WORD,BIN",
            "CORD LO",
            "WFSU SP,0,NP,0,FP,0,SN,0",
            "VBS 'app.Acquisition.Horizontal.Maximize = \"FixedSampleRate\"'",
            "VBS 'app.Acquisition.Horizontal.SampleRate = 8e10'",
            "VBS 'app.Acquisition.Horizontal.HorScale = 1.024e-7'",
            "TRDL -5.12e-7",
            "C1:TRA ON",
            "C2:TRA ON",
            "C1:VDIV 0.05",
            "C2:VDIV 0.05",
            "TRSE EDGE,SR,EX,HT,OFF",
            "EX:TRLV 0.2V",
            "EX:TRSL POS",
            "CMR?",
            "EXR?",
            "VBS? 'return = app.Acquisition.Horizontal.SamplingRate'",
            "VBS? 'return = app.Acquisition.Horizontal.NumPoints'",
        ]
    );
    bench.emulator.log().clear();
    bounded(bench.driver.acquire(Duration::from_secs(5)))
        .await
        .unwrap();
    assert_eq!(
        bench.emulator.log().texts(),
        ["TRMD SINGLE;ARM;WAIT 5;*OPC?", "INR?"]
    );
    let i = bounded(bench.driver.read(1)).await.unwrap();
    let q = bounded(bench.driver.read(2)).await.unwrap();
    assert_eq!(i.codes.len(), 81_920);
    assert!(i.desc.word && i.desc.little_endian);
    assert_eq!(
        i.desc.horiz_offset, 0.0,
        "the record starts at the marker edge"
    );
    assert_eq!(i.sample_rate(), f64::from(1.0f32 / 80e9_f32).recip());
    assert_eq!(q.desc.wave_source, 1);
    let step = 0.05 / 25.0;
    let (iv, it) = (i.volts(), i.times());
    let (qv, qt) = (q.volts(), q.times());
    for k in (0..81_920).step_by(1013) {
        let w = 2.0 * std::f64::consts::PI * 1e9;
        assert!(
            (iv[k] - 0.1 * (w * it[k]).cos()).abs() <= step / 2.0 + 1e-6,
            "I at {k}"
        );
        assert!(
            (qv[k] - 0.1 * (w * qt[k]).sin()).abs() <= step / 2.0 + 1e-6,
            "Q at {k}"
        );
    }
    assert_eq!(
        i.trc,
        bench.emulator.trc_bytes(1).unwrap(),
        "the .trc bytes are the scope's block"
    );
}

#[tokio::test]
async fn single_shot_over_raw_socket() {
    single_shot(false).await;
}

#[tokio::test]
async fn single_shot_over_hislip() {
    single_shot(true).await;
}

#[tokio::test]
async fn no_marker_is_a_clear_no_trigger_error() {
    let mut bench = start(false, false).await;
    bounded(bench.driver.configure(&setup())).await.unwrap();
    let err = bounded(bench.driver.acquire(Duration::from_millis(20)))
        .await
        .unwrap_err();
    assert!(matches!(err, DriverError::NoTrigger { .. }), "{err}");
    assert!(err.to_string().contains("marker"), "{err}");
    bench.signal.set_marker(true);
    bounded(bench.driver.acquire(Duration::from_secs(5)))
        .await
        .unwrap();
}

#[tokio::test]
async fn values_outside_the_catalog_are_refused_before_sending() {
    let mut bench = start(true, false).await;
    for bad in [
        DigitizerSetup {
            sample_rate: 40e9,
            ..setup()
        },
        DigitizerSetup {
            record_seconds: 1.0,
            ..setup()
        },
        DigitizerSetup {
            record_seconds: 0.0,
            ..setup()
        },
        DigitizerSetup {
            trigger_level_v: 2.0,
            ..setup()
        },
        DigitizerSetup {
            volts_per_div: 5.0,
            ..setup()
        },
    ] {
        let err = bounded(bench.driver.configure(&bad)).await.unwrap_err();
        assert!(matches!(err, DriverError::Limit { .. }), "{err}");
    }
    assert!(bench.emulator.log().texts().is_empty(), "nothing was sent");
    assert!(matches!(
        bounded(bench.driver.read(7)).await.unwrap_err(),
        DriverError::Limit { .. }
    ));
}

#[tokio::test]
async fn instrument_errors_are_read_from_cmr_and_exr() {
    let mut bench = start(true, false).await;
    bench.driver.session().write("C1:WF? FOO").await.unwrap();
    let err = bounded(bench.driver.configure(&setup())).await.unwrap_err();
    match err {
        DriverError::Refused { code, ref text, .. } => {
            assert_eq!(code, 26);
            assert!(
                text.contains("not implemented") && text.contains("EXR?"),
                "{text}"
            );
        }
        other => panic!("expected a refusal, got {other}"),
    }
}

#[tokio::test]
async fn remote_interface_set_to_the_other_protocol_is_explained() {
    let emulator = Arc::new(Emulator::embedded().unwrap());
    emulator.set_remote_interface(RemoteInterface::Vicp);
    let port: Arc<dyn Handler> = Arc::new(emulator.port(RemoteInterface::Vxi11));
    let (_server, resource) = serve(port, false).await;
    let catalog = Catalog::embedded().unwrap();
    let model = catalog.get("lecroy-labmaster10zi-a").unwrap();
    let result = bounded(Lecroy::open(
        resource,
        options(Duration::from_millis(300)),
        model,
    ))
    .await;
    let err = result.err().expect("the scope does not answer");
    assert!(matches!(err, DriverError::RemoteInterface { .. }), "{err}");
    assert!(
        err.to_string()
            .contains("Utilities > Utilities Setup > Remote"),
        "{err}"
    );
}
