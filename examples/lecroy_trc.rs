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
use radbench::driver::Lecroy;
use radbench::driver::{Digitizer, DigitizerSettings};

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
    let mut driver = Lecroy::open(resource, model, None, "scope").await?;
    // A 25 ns record (2000 points at 80 GSa/s) starting at the trigger.
    driver
        .configure(&DigitizerSettings {
            sample_rate_hz: 80e9,
            repetition_s: 25e-9,
            longest_echo_s: 0.0,
            pre_trigger_s: 0.0,
            trigger_level_v: 0.2,
            i_volts_per_div: 0.05,
            q_volts_per_div: 0.05,
            ..DigitizerSettings::default()
        })
        .await?;
    tokio::time::timeout(Duration::from_secs(30), driver.acquire(5.0)).await??;
    let mut decoded = serde_json::Map::new();
    for channel in [1u8, 2] {
        let trace = driver.fetch(channel).await?;
        let native = trace
            .native
            .as_ref()
            .ok_or_else(|| anyhow::anyhow!("the LeCroy driver keeps the .trc bytes"))?;
        std::fs::write(out.join(format!("rb_C{channel}.trc")), native.to_vec())?;
        decoded.insert(
            format!("C{channel}"),
            serde_json::json!({
                "volts": trace.segment_volts(0),
                "times": trace.segment_times(0),
                "interval": trace.sample_interval_s,
            }),
        );
    }
    std::fs::write(
        out.join("radbench.json"),
        serde_json::to_string(&serde_json::Value::Object(decoded))?,
    )?;
    Ok(())
}
