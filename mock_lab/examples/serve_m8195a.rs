//! Serves one M8195A emulator on raw socket, HiSLIP and VXI-11 (loopback, free ports), prints one
//! JSON line with the VISA resource of each, and runs until stdin closes. Used by
//! `interop/test_m8195a_pyvisa.py` to drive the emulator with pyvisa-py.
//!
//! Usage: `cargo run -p mock_lab --example serve_m8195a`

use std::io::Read;
use std::sync::Arc;

use mock_lab::emulator::m8195a::M8195a;
use mock_lab::server::{self, Handler, ServerOptions};

#[tokio::main]
async fn main() -> anyhow::Result<()> {
    let awg: Arc<dyn Handler> = Arc::new(M8195a::embedded()?);
    let any = server::loopback_any();
    let raw = server::raw::serve(any, awg.clone(), ServerOptions::default()).await?;
    let hislip = server::hislip::serve(any, awg.clone(), ServerOptions::default()).await?;
    let vxi11 = server::vxi11::serve(
        server::vxi11::Vxi11Addresses::loopback(),
        awg,
        ServerOptions::default(),
    )
    .await?;
    let endpoints = serde_json::json!({
        "raw": format!("TCPIP::127.0.0.1::{}::SOCKET", raw.local_addr().port()),
        "hislip": format!("TCPIP::127.0.0.1::hislip0,{}::INSTR", hislip.local_addr().port()),
        "vxi11": format!("TCPIP::127.0.0.1,{}::inst0::INSTR", vxi11.local_addr().port()),
    });
    println!("{endpoints}");
    // Serve until the parent closes our stdin.
    tokio::task::spawn_blocking(|| {
        let mut sink = Vec::new();
        let _ = std::io::stdin().read_to_end(&mut sink);
    })
    .await?;
    Ok(())
}
