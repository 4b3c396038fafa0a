//! Writes `.trc` files saved from the LeCroy emulator, plus the volts and times the emulator recorded,
//! for `interop/test_trc.py` to check with lecroyparser.
//!
//! Usage: `cargo run -p mock_lab --example write_trc -- <out-dir>`
//! Writes `C1.trc` (WORD, LO first) and `C2.trc` (BYTE, HI first) and `expected.json`.

use std::path::PathBuf;
use std::sync::Arc;

use mock_lab::emulator::lecroy::{Lecroy, TestSignal};
use mock_lab::server::Handler;

fn main() -> anyhow::Result<()> {
    let out: PathBuf = std::env::args_os()
        .nth(1)
        .map(PathBuf::from)
        .ok_or_else(|| anyhow::anyhow!("usage: write_trc <out-dir>"))?;
    std::fs::create_dir_all(&out)?;
    let scope = Lecroy::embedded_with(Arc::new(TestSignal::new(true, 0.7e9, 0.12)))?;
    for message in [
        "CHDR OFF;WFSU SP,0,NP,0,FP,0,SN,0;C1:VDIV 0.04;C2:VDIV 0.05;C2:OFST 0.01",
        "VBS 'app.Acquisition.Horizontal.HorScale = 2e-9';TRDL -5E-9",
        "TRSE EDGE,SR,EX,HT,OFF;EX:TRLV 0.2V;TRMD SINGLE;ARM;WAIT 5",
    ] {
        scope.message(message.as_bytes());
    }
    let state = scope.state();
    let acquisition = state
        .acquisition
        .ok_or_else(|| anyhow::anyhow!("the emulator did not acquire"))?;
    let mut expected = serde_json::Map::new();
    for (channel, format) in [
        (1u8, "CFMT DEF9,WORD,BIN;CORD LO"),
        (2, "CFMT DEF9,BYTE,BIN;CORD HI"),
    ] {
        scope.message(format.as_bytes());
        let trc = scope
            .trc_bytes(channel)
            .ok_or_else(|| anyhow::anyhow!("no channel {channel}"))?;
        std::fs::write(out.join(format!("C{channel}.trc")), trc)?;
        let recorded = acquisition.channels[usize::from(channel - 1)]
            .as_ref()
            .ok_or_else(|| anyhow::anyhow!("channel {channel} was off"))?;
        let volts: Vec<f64> = recorded
            .values
            .iter()
            .map(|v| recorded.gain_word * f64::from(*v) - recorded.offset_v)
            .collect();
        let times: Vec<f64> = (0..volts.len())
            .map(|i| acquisition.first_point_s + i as f64 / acquisition.sample_rate)
            .collect();
        expected.insert(
            format!("C{channel}"),
            serde_json::json!({ "volts": volts, "times": times, "interval": 1.0 / acquisition.sample_rate }),
        );
    }
    std::fs::write(
        out.join("expected.json"),
        serde_json::to_string(&serde_json::Value::Object(expected))?,
    )?;
    Ok(())
}
