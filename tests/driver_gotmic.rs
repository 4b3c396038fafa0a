//! The Gotmic driver against mock_lab's Gotmic emulators: over a pseudo-terminal (the module's real
//! link is serial) and, for the other checks, the same line protocol over the raw socket server.

use std::future::Future;
use std::sync::Arc;
use std::time::Duration;

use mock_lab::emulator::gotmic::Gotmic as Emulator;
use mock_lab::server::{self, Handler, ServerHandle, ServerOptions};
use radbench::catalog::Catalog;
use radbench::driver::gotmic::Gotmic;
use radbench::driver::{DriverError, RfFrontEnd, RfPermit};
use radbench::session::{Session, SessionOptions};

const LIMIT: Duration = Duration::from_secs(60);

async fn bounded<T>(fut: impl Future<Output = T>) -> T {
    tokio::time::timeout(LIMIT, fut)
        .await
        .expect("finished within the test's time limit")
}

/// Held only to keep the endpoint serving while the test runs.
#[allow(dead_code)]
enum Endpoint {
    Socket(ServerHandle),
    Serial(server::serial::SerialHandle),
}

struct Bench {
    emulator: Arc<Emulator>,
    driver: Gotmic,
    _server: Endpoint,
}

async fn start(tx: bool) -> Bench {
    start_on(tx, false).await
}

async fn start_on(tx: bool, serial: bool) -> Bench {
    let emulator = Arc::new(if tx {
        Emulator::tx_embedded().unwrap()
    } else {
        Emulator::rx_embedded().unwrap()
    });
    let handler: Arc<dyn Handler> = emulator.clone();
    let (server, resource) = if serial {
        let pty = server::serial::serve(handler, ServerOptions::default()).unwrap();
        let resource = format!("ASRL{}::INSTR", pty.device_path());
        (Endpoint::Serial(pty), resource)
    } else {
        let server = server::raw::serve(server::loopback_any(), handler, ServerOptions::default())
            .await
            .unwrap();
        let resource = format!("TCPIP::127.0.0.1::{}::SOCKET", server.local_addr().port());
        (Endpoint::Socket(server), resource)
    };
    let session = bounded(Session::open(
        resource.parse().unwrap(),
        SessionOptions::default(),
        None,
        "tx",
    ))
    .await
    .unwrap();
    let catalog = Catalog::embedded().unwrap();
    let key = if tx {
        "gotmic-eband-tx"
    } else {
        "gotmic-eband-rx"
    };
    let driver = bounded(Gotmic::connect(session, catalog.get(key).unwrap()))
        .await
        .expect("driver connects");
    emulator.log().clear();
    Bench {
        emulator,
        driver,
        _server: server,
    }
}

#[tokio::test]
async fn enable_and_disable_over_a_serial_pty() {
    let mut bench = start_on(true, true).await;
    let permit = RfPermit::grant("test bench, dummy load");
    let status = bounded(bench.driver.enable(&permit, 6.0)).await.unwrap();
    assert!(status.rf_enabled);
    assert_eq!(bench.emulator.front_end().attenuation_db, 6.0);
    bounded(bench.driver.disable()).await.unwrap();
    assert!(!bench.emulator.front_end().rf_enabled);
}

#[tokio::test]
async fn enable_sequence_is_safe_and_verified() {
    let mut bench = start(true).await;
    let permit = RfPermit::grant("test bench, dummy load");
    let status = bounded(bench.driver.enable(&permit, 10.0)).await.unwrap();
    assert!(status.rf_enabled && status.lo_locked);
    assert_eq!(status.attenuation_db, 10.0);
    assert_eq!(
        bench.emulator.log().texts(),
        [
            "W 03 003F", // maximum attenuation first
            "R 03",
            "W 02 000F", // then enable
            "R 02",
            "R 01", // verify STATUS
            "R 06",
            "R 03",
            "R 07",
            "W 03 0014", // then the requested attenuation
            "R 03",
            "R 01",
            "R 06",
            "R 03",
            "R 07",
        ]
    );
    assert!(bench.emulator.front_end().rf_enabled);
    bench.emulator.log().clear();
    bounded(bench.driver.disable()).await.unwrap();
    assert_eq!(bench.emulator.log().texts(), ["W 02 0000", "R 02", "R 01"]);
    assert!(!bench.emulator.front_end().rf_enabled);
}

#[tokio::test]
async fn interlock_refusal_carries_code_and_text_and_leaves_rf_off() {
    let mut bench = start(true).await;
    bench.emulator.set_interlock_open(true);
    let permit = RfPermit::grant("test");
    let err = bounded(bench.driver.enable(&permit, 0.0))
        .await
        .unwrap_err();
    match &err {
        DriverError::Refused { code, text, .. } => {
            assert_eq!(*code, 5);
            assert!(text.contains("interlock open"), "{text}");
        }
        other => panic!("expected a refusal, got {other}"),
    }
    let fe = bench.emulator.front_end();
    assert!(!fe.rf_enabled);
    assert_eq!(fe.attenuation_db, 31.5, "left at maximum attenuation");
}

#[tokio::test]
async fn tripped_interlock_latches_a_fault_that_must_be_cleared() {
    let mut bench = start(true).await;
    let permit = RfPermit::grant("test");
    bounded(bench.driver.enable(&permit, 5.0)).await.unwrap();
    bench.emulator.set_interlock_open(true);
    let status = bounded(bench.driver.status()).await.unwrap();
    assert!(!status.rf_enabled && status.interlock_open);
    assert_eq!(status.fault_latch, 0b010);
    bench.emulator.set_interlock_open(false);
    assert!(matches!(
        bounded(bench.driver.enable(&permit, 5.0))
            .await
            .unwrap_err(),
        DriverError::Refused { code: 5, .. }
    ));
    assert_eq!(bounded(bench.driver.clear_faults()).await.unwrap(), 0b010);
    bounded(bench.driver.enable(&permit, 5.0)).await.unwrap();
}

#[tokio::test]
async fn receiver_temperature_and_limits() {
    let mut bench = start(false).await;
    bench.emulator.set_temperature_c(41.3);
    let status = bounded(bench.driver.status()).await.unwrap();
    assert_eq!(status.temperature_c, 41.3);
    assert_eq!(
        bounded(bench.driver.set_attenuation_db(3.2)).await.unwrap(),
        3.0
    );
    bench.emulator.log().clear();
    for bad in [40.0, -1.0, f64::NAN] {
        let err = bounded(bench.driver.set_attenuation_db(bad))
            .await
            .unwrap_err();
        assert!(matches!(err, DriverError::Limit { .. }), "{err}");
    }
    let err = bounded(bench.driver.write("GAIN_ATT", 64))
        .await
        .unwrap_err();
    assert!(matches!(err, DriverError::Limit { .. }), "{err}");
    assert!(bench.emulator.log().texts().is_empty(), "nothing was sent");
}

#[tokio::test]
async fn a_transmitter_file_does_not_accept_a_receiver() {
    let emulator: Arc<dyn Handler> = Arc::new(Emulator::rx_embedded().unwrap());
    let server = server::raw::serve(server::loopback_any(), emulator, ServerOptions::default())
        .await
        .unwrap();
    let resource = format!("TCPIP::127.0.0.1::{}::SOCKET", server.local_addr().port());
    let session = bounded(Session::open(
        resource.parse().unwrap(),
        SessionOptions::default(),
        None,
        "tx",
    ))
    .await
    .unwrap();
    let catalog = Catalog::embedded().unwrap();
    let result = bounded(Gotmic::connect(
        session,
        catalog.get("gotmic-eband-tx").unwrap(),
    ))
    .await;
    assert!(matches!(result, Err(DriverError::WrongInstrument { .. })));
}
