//! The LeCroy driver against mock_lab's scope emulator over loopback, on the scope's two remote
//! protocols (VICP and VXI-11) and, as extra coverage of the same driver, raw socket and HiSLIP.

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

#[derive(Clone, Copy, Debug)]
enum Proto {
    Vicp,
    Vxi11,
    Socket,
    Hislip,
}

async fn serve(handler: Arc<dyn Handler>, proto: Proto) -> (ServerHandle, Resource) {
    let any = server::loopback_any();
    let options = ServerOptions::default();
    let server = match proto {
        Proto::Vicp => server::vicp::serve(any, handler, options).await,
        Proto::Vxi11 => {
            server::vxi11::serve(server::vxi11::Vxi11Addresses::loopback(), handler, options).await
        }
        Proto::Socket => server::raw::serve(any, handler, options).await,
        Proto::Hislip => server::hislip::serve(any, handler, options).await,
    }
    .expect("server starts");
    let port = server.local_addr().port();
    let text = match proto {
        Proto::Vicp => format!("VICP::127.0.0.1,{port}::INSTR"),
        Proto::Vxi11 => format!("TCPIP::127.0.0.1,{port}::inst0::INSTR"),
        Proto::Socket => format!("TCPIP::127.0.0.1::{port}::SOCKET"),
        Proto::Hislip => format!("TCPIP::127.0.0.1::hislip0,{port}::INSTR"),
    };
    (server, text.parse().unwrap())
}

struct Bench {
    emulator: Arc<Emulator>,
    signal: Arc<TestSignal>,
    driver: Lecroy,
    _server: ServerHandle,
}

async fn start(marker: bool, proto: Proto) -> Bench {
    let signal = Arc::new(TestSignal::new(marker, 1e9, 0.1));
    let emulator = Arc::new(Emulator::embedded_with(signal.clone()).unwrap());
    let remote = match proto {
        Proto::Vxi11 => RemoteInterface::Vxi11,
        _ => RemoteInterface::Vicp,
    };
    emulator.set_remote_interface(remote);
    let (server, resource) = serve(Arc::new(emulator.port(remote)), proto).await;
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

async fn single_shot(proto: Proto) {
    let mut bench = start(true, proto).await;
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
async fn single_shot_over_vicp() {
    single_shot(Proto::Vicp).await;
}

#[tokio::test]
async fn single_shot_over_vxi11() {
    single_shot(Proto::Vxi11).await;
}

#[tokio::test]
async fn single_shot_over_raw_socket() {
    single_shot(Proto::Socket).await;
}

#[tokio::test]
async fn single_shot_over_hislip() {
    single_shot(Proto::Hislip).await;
}

#[tokio::test]
async fn no_marker_is_a_clear_no_trigger_error() {
    let mut bench = start(false, Proto::Vicp).await;
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
    let mut bench = start(true, Proto::Vicp).await;
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
    let mut bench = start(true, Proto::Vicp).await;
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

async fn refused(remote: RemoteInterface, proto: Proto, expected: &str) {
    let emulator = Arc::new(Emulator::embedded().unwrap());
    emulator.set_remote_interface(remote);
    let via = match proto {
        Proto::Vxi11 => RemoteInterface::Vxi11,
        _ => RemoteInterface::Vicp,
    };
    let (_server, resource) = serve(Arc::new(emulator.port(via)), proto).await;
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
    let text = err.to_string();
    assert!(
        text.contains("Utilities > Utilities Setup > Remote"),
        "{text}"
    );
    assert!(text.contains(expected), "{text}");
}

#[tokio::test]
async fn vicp_client_of_a_scope_set_to_vxi11_is_told_why() {
    refused(
        RemoteInterface::Vxi11,
        Proto::Vicp,
        "set Utilities > Utilities Setup > Remote to TCPIP (VICP)",
    )
    .await;
}

#[tokio::test]
async fn vxi11_client_of_a_scope_set_to_vicp_is_told_why() {
    refused(
        RemoteInterface::Vicp,
        Proto::Vxi11,
        "set Utilities > Utilities Setup > Remote to LXI (VXI-11)",
    )
    .await;
}

mod decode_fuzz {
    use proptest::prelude::*;
    use proptest::test_runner::RngSeed;
    use radbench::driver::lecroy::wavedesc::decode;

    fn valid_block() -> Vec<u8> {
        let scope = mock_lab::emulator::lecroy::Lecroy::embedded().unwrap();
        mock_lab::server::Handler::message(&scope, b"CHDR OFF;CFMT DEF9,WORD,BIN;TDIV 1E-10;FRTR");
        scope.trc_bytes(1).unwrap()[11..].to_vec()
    }

    proptest! {
        // Fixed seed: the same cases on every run; no regression files written.
        #![proptest_config(ProptestConfig {
            rng_seed: RngSeed::Fixed(0x7AC3),
            failure_persistence: None,
            ..ProptestConfig::default()
        })]

        #[test]
        fn arbitrary_bytes_are_errors_not_panics(bytes in prop::collection::vec(any::<u8>(), 0..600)) {
            let _ = decode(&bytes);
        }

        #[test]
        fn corrupted_descriptors_are_errors_not_panics(at in 0usize..346, value in any::<u8>(), cut in 0usize..200) {
            let mut block = valid_block();
            block[at] = value;
            let keep = block.len().saturating_sub(cut);
            block.truncate(keep);
            if let Ok(trace) = decode(&block) {
                prop_assert_eq!(trace.codes.len(), trace.desc.points);
            }
        }
    }
}
