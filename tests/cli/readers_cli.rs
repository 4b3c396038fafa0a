//! The readers of recorded captures as a user meets them: `radbench trc` and `radbench recording`
//! on files in a temporary folder, and the golden `.trc` file written by
//! `tests/data/make_golden_trc.py` (struct-packed from the template, not by radbench).

use crate::process_support;

use std::path::{Path, PathBuf};
use std::process::{Command, Output};
use std::time::Duration;

use bytes::Bytes;
use radbench::storage::{read_sigmf, read_trc, SampleUnit};
use radbench::trc::{BlockBuilder, ByteOrder, Trace};
use serde_json::{json, Value};

const GOLDEN: &str = "tests/data/lecroy_seq_hifirst_byte.trc";

fn radbench(args: &[&str]) -> Output {
    process_support::output_within(
        Command::new(env!("CARGO_BIN_EXE_radbench")).args(args),
        Duration::from_secs(120),
    )
}

fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

fn json_out(o: &Output) -> Value {
    serde_json::from_slice(&o.stdout).unwrap_or_else(|e| {
        panic!(
            "not JSON ({e}): {}\n{}",
            String::from_utf8_lossy(&o.stdout),
            stderr(o)
        )
    })
}

fn golden() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join(GOLDEN)
}

#[test]
fn golden_sequence_file_decodes_to_the_packed_values() {
    let t = read_trc(&golden()).unwrap();
    assert_eq!(t.desc.order, ByteOrder::HiFirst);
    assert_eq!(t.desc.comm_type, 0);
    assert_eq!(t.channel, 4);
    assert_eq!(t.user_text, "golden");
    assert_eq!(t.desc.instrument_name, "LECROYWR8208HD");
    assert_eq!(t.desc.trace_label, "probe");
    assert_eq!(t.desc.trigger_time.iso(), "2024-02-29T23:59:59.500000");
    assert_eq!(t.segment_count(), 3);
    let want_codes = [[-128, -1, 0, 127], [1, 2, 3, 4], [-5, -6, -7, -8]];
    let want_timing = [(0.0, -2.0e-9), (1.0e-3, -1.75e-9), (2.5e-3, -2.25e-9)];
    let gain = f64::from(0.01f32);
    for (k, s) in t.segments().enumerate() {
        assert_eq!(s.codes, want_codes[k]);
        assert_eq!(s.trigger_time_s, Some(want_timing[k].0));
        assert_eq!(s.trigger_offset_s, want_timing[k].1);
        assert_eq!(s.volts()[0], gain * f64::from(want_codes[k][0]) - 0.5);
        assert_eq!(s.times()[3], 3.0 * f64::from(1e-9f32) + want_timing[k].1);
    }
}

#[test]
fn trc_json_lists_every_segment() {
    let out = radbench(&["trc", "--json", "--points", "2", golden().to_str().unwrap()]);
    assert!(out.status.success(), "{}", stderr(&out));
    let doc = json_out(&out);
    assert_eq!(doc["errors"], json!([]));
    let t = &doc["traces"][0];
    assert_eq!(t["segment_count"], 3);
    assert_eq!(t["points_per_segment"], 4);
    assert_eq!(t["channel"], 4);
    assert_eq!(t["header"]["instrument_name"], "LECROYWR8208HD");
    assert_eq!(t["trigger_time"], "2024-02-29T23:59:59.500000");
    let seg = &t["segments"][1];
    assert_eq!(seg["trigger_time_s"], 1.0e-3);
    assert_eq!(seg["trigger_offset_s"], -1.75e-9);
    let first: Vec<f64> = serde_json::from_value(seg["first_volts"].clone()).unwrap();
    let gain = f64::from(0.01f32);
    // serde_json's parser may be one ulp off; radbench prints the shortest exact text.
    let close = |a: f64, b: f64| (a - b).abs() <= 1e-15 * b.abs().max(1e-9);
    assert!(
        close(first[0], gain - 0.5) && close(first[1], 2.0 * gain - 0.5),
        "{first:?}"
    );
    let last_t: Vec<f64> = serde_json::from_value(seg["last_times_s"].clone()).unwrap();
    assert!(
        close(last_t[1], 3.0 * f64::from(1e-9f32) - 1.75e-9),
        "{last_t:?}"
    );
    assert!((seg["stats"]["mean_v"].as_f64().unwrap() - (2.5 * gain - 0.5)).abs() < 1e-12);
    let text = radbench(&["trc", golden().to_str().unwrap()]);
    assert!(text.status.success());
    let text = String::from_utf8_lossy(&text.stdout);
    assert!(text.contains("12 in 3 segments of 4"), "{text}");
    assert!(text.contains("HIFIRST") && text.contains("8-bit"), "{text}");
}

#[test]
fn a_truncated_or_foreign_file_exits_2_naming_it() {
    let dir = tempfile::tempdir().unwrap();
    let block = BlockBuilder {
        segments: vec![(0.0, -1e-9), (1e-3, -1e-9)],
        ..BlockBuilder::default()
    }
    .build(&[1, 2, 3, 4, 5, 6]);
    let whole = Trace::decode(1, Bytes::from(block)).unwrap().trc_bytes();
    let cut = dir.path().join("cut.trc");
    std::fs::write(&cut, &whole[..whole.len() - 5]).unwrap();
    let out = radbench(&["trc", cut.to_str().unwrap()]);
    assert_eq!(out.status.code(), Some(2), "{}", stderr(&out));
    let err = stderr(&out);
    assert!(
        err.contains("cut.trc") && err.contains("truncated") && err.contains("WAVE_ARRAY_1"),
        "{err}"
    );

    let good = dir.path().join("good.trc");
    std::fs::write(&good, &whole).unwrap();
    let text = dir.path().join("notes.trc");
    std::fs::write(&text, "these are my notes, not a waveform").unwrap();
    let missing = dir.path().join("missing.trc");
    let out = radbench(&[
        "trc",
        "--json",
        good.to_str().unwrap(),
        text.to_str().unwrap(),
        missing.to_str().unwrap(),
    ]);
    assert_eq!(out.status.code(), Some(2), "{}", stderr(&out));
    let doc = json_out(&out);
    assert_eq!(doc["traces"].as_array().unwrap().len(), 1);
    let errors = doc["errors"].as_array().unwrap();
    assert_eq!(errors.len(), 2);
    assert!(errors[0]["file"].as_str().unwrap().ends_with("notes.trc"));
    assert!(errors[0]["error"].as_str().unwrap().contains("WAVEDESC"));
    assert!(errors[1]["file"].as_str().unwrap().ends_with("missing.trc"));
    assert!(stderr(&out).contains("2 of 3 files"), "{}", stderr(&out));
}

/// Writes a recording by hand: metadata JSON and the data bytes.
fn recording(dir: &Path, name: &str, global: Value, data: &[u8]) -> PathBuf {
    let meta = json!({
        "global": global,
        "captures": [{"core:sample_start": 0, "core:datetime": "2026-11-21T19:55:00Z", "core:frequency": 8e10}],
        "annotations": []
    });
    let base = dir.join(name);
    std::fs::write(base.with_extension("sigmf-meta"), meta.to_string()).unwrap();
    std::fs::write(base.with_extension("sigmf-data"), data).unwrap();
    base.with_extension("sigmf-meta")
}

#[test]
fn recording_json_reports_native_and_volt_scales() {
    let dir = tempfile::tempdir().unwrap();
    let data: Vec<u8> = [3i16, -4, 6, 8]
        .iter()
        .flat_map(|v| v.to_be_bytes())
        .collect();
    let foreign = recording(
        dir.path(),
        "foreign",
        json!({"core:datatype": "ci16_be", "core:sample_rate": 2e6, "core:version": "1.0.0"}),
        &data,
    );
    let out = radbench(&["recording", "--json", foreign.to_str().unwrap()]);
    assert!(out.status.success(), "{}", stderr(&out));
    let r = &json_out(&out)["recordings"][0];
    assert_eq!(r["datatype"], "ci16_be");
    assert_eq!(r["unit"], "native");
    assert_eq!(r["samples"], 2);
    assert_eq!(r["duration_s"], 1e-6);
    assert_eq!(r["first_samples"], json!([[3.0, -4.0], [6.0, 8.0]]));
    assert_eq!(r["stats"]["mean_i"], 4.5);
    assert_eq!(
        r["stats"]["rms"],
        ((9.0 + 16.0 + 36.0 + 64.0) / 2.0f64).sqrt()
    );

    let ours = recording(
        dir.path(),
        "ours",
        json!({
            "core:datatype": "ci8",
            "core:sample_rate": 8e10,
            "core:extensions": [{"name": "radbench", "version": "1.0.0", "optional": true}],
            "radbench:vertical_gain": [0.5, 0.25],
            "radbench:vertical_offset": [0.0, 1.0],
            "radbench:trigger_offset_s": 1e-9,
            "radbench:waveform": {"kind": "ofdm"}
        }),
        &[2, 4],
    );
    let r = read_sigmf(&ours).unwrap();
    assert_eq!(r.unit, SampleUnit::Volts);
    let out = radbench(&["recording", ours.to_str().unwrap()]);
    assert!(out.status.success(), "{}", stderr(&out));
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(text.contains("in volts") && text.contains("ofdm"), "{text}");
    assert!(
        text.contains("1e0+0e0j") || text.contains("1.000000e0+0.000000e0j"),
        "{text}"
    );
}

#[test]
fn a_bad_recording_exits_2_naming_the_file_and_field() {
    let dir = tempfile::tempdir().unwrap();
    let odd = recording(
        dir.path(),
        "odd",
        json!({"core:datatype": "cf32_le", "core:sample_rate": 1e6}),
        &[0; 12],
    );
    let out = radbench(&["recording", odd.to_str().unwrap()]);
    assert_eq!(out.status.code(), Some(2));
    assert!(
        stderr(&out).contains("odd.sigmf-data") && stderr(&out).contains("12 bytes"),
        "{}",
        stderr(&out)
    );
    let real = recording(
        dir.path(),
        "real",
        json!({"core:datatype": "rf32_le"}),
        &[0; 8],
    );
    let out = radbench(&["recording", real.to_str().unwrap()]);
    assert_eq!(out.status.code(), Some(2));
    assert!(stderr(&out).contains("core:datatype"), "{}", stderr(&out));
}

/// What `radbench capture` writes reads back the same through the recording reader and the
/// `.trc` reader (the SigMF volts equal the traces' volts sample for sample).
#[test]
fn a_radbench_capture_reads_back_identically() {
    let dir = tempfile::tempdir().unwrap();
    let out = radbench(&[
        "capture",
        "--allow-rf",
        "--json",
        "--out",
        dir.path().to_str().unwrap(),
    ]);
    assert!(out.status.success(), "{}", stderr(&out));
    let r = read_sigmf(&dir.path().join("capture.sigmf-meta")).unwrap();
    assert_eq!(r.unit, SampleUnit::Volts);
    assert!(r.sha512_checked);
    assert_eq!(r.sample_rate_hz, Some(80e9));
    let rb = r.radbench.as_ref().unwrap();
    assert!(rb.waveform().is_some() && rb.processing().is_some());
    let i = read_trc(&dir.path().join("C1.trc")).unwrap();
    let q = read_trc(&dir.path().join("C2.trc")).unwrap();
    assert_eq!((i.channel, q.channel), (1, 2));
    let iv = i.volts();
    let qv = q.volts();
    assert_eq!(iv.len(), r.samples.len());
    assert_eq!(rb.trigger_offset_s, Some(i.first_sample_s()));
    for (k, z) in r.samples.iter().enumerate().step_by(997) {
        assert_eq!((z.re, z.im), (iv[k], qv[k]), "sample {k}");
    }
}
