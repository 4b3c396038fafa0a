//! radbench's LeCroy driver captures from mock_lab's scope emulator over VICP (loopback), saves the
//! `.trc` file of each channel exactly as received, and writes the volts and times radbench decoded,
//! for `interop/test_trc.py` to compare with lecroyparser.
//!
//! Usage: `cargo run --example lecroy_trc -- <out-dir>`; writes `rb_C1.trc`, `rb_C2.trc` and
//! `radbench.json`.

use std::path::PathBuf;
use std::sync::Arc;
use std::time::Duration;

use mock_lab::emulator::lecroy::{Lecroy as Emulator, RemoteInterface, TestSignal};
use mock_lab::server::{self, ServerOptions};
use radbench::catalog::Catalog;
use radbench::driver::lecroy::Lecroy;
use radbench::driver::{Digitizer, DigitizerSetup};
use radbench::session::SessionOptions;

#[tokio::main]
async fn main() -> anyhow::Result<()> {
    let out: PathBuf = std::env::args_os()
        .nth(1)
        .map(PathBuf::from)
        .ok_or_else(|| anyhow::anyhow!("usage: lecroy_trc <out-dir>"))?;
    std::fs::create_dir_all(&out)?;

    let scope = Arc::new(Emulator::embedded_with(Arc::new(TestSignal::new(
        true, 0.9e9, 0.15,
    )))?);
    let port = Arc::new(scope.port(RemoteInterface::Vicp));
    let server =
        server::vicp::serve(server::loopback_any(), port, ServerOptions::default()).await?;
    let resource = format!("VICP::127.0.0.1,{}::INSTR", server.local_addr().port()).parse()?;

    let catalog = Catalog::embedded()?;
    let model = catalog.get("lecroy-labmaster10zi-a")?;
    let mut driver = Lecroy::open(resource, SessionOptions::default(), model).await?;
    driver
        .configure(&DigitizerSetup {
            sample_rate: 80e9,
            record_seconds: 25e-9,
            trigger_level_v: 0.2,
            volts_per_div: 0.05,
        })
        .await?;
    driver.acquire(Duration::from_secs(5)).await?;
    let mut decoded = serde_json::Map::new();
    for channel in [1u8, 2] {
        let trace = driver.read(channel).await?;
        std::fs::write(out.join(format!("rb_C{channel}.trc")), &trace.trc)?;
        decoded.insert(
            format!("C{channel}"),
            serde_json::json!({
                "volts": trace.volts(),
                "times": trace.times(),
                "interval": f64::from(trace.desc.horiz_interval),
            }),
        );
    }
    std::fs::write(
        out.join("radbench.json"),
        serde_json::to_string(&serde_json::Value::Object(decoded))?,
    )?;
    Ok(())
}
