//! The bad-input corpus: command-line values, bench files, scene files and background files a
//! user gets wrong. Each one exits 2 (bad input), names the option, file, line or field and what is
//! allowed, sends nothing to any instrument (the I/O journal stays empty) and writes no output.

use crate::process_support::output_within;
use std::path::Path;
use std::process::{Command, Stdio};
use std::time::Duration;

const BIN: &str = env!("CARGO_BIN_EXE_radbench");

/// One case: the arguments (after `radbench --trace-io JOURNAL`) and what stderr must contain.
struct Case {
    args: Vec<String>,
    names: &'static [&'static str],
}

fn case(args: &[&str], names: &'static [&'static str]) -> Case {
    Case {
        args: args.iter().map(|a| a.to_string()).collect(),
        names,
    }
}

fn write(dir: &Path, name: &str, text: &str) -> String {
    let path = dir.join(name);
    std::fs::write(&path, text).unwrap();
    path.display().to_string()
}

/// Runs `case` in `dir`; returns what went wrong, if anything.
fn check(dir: &Path, index: usize, case: &Case) -> Option<String> {
    let journal = dir.join(format!("journal-{index}.jsonl"));
    let out = dir.join(format!("out-{index}"));
    let mut cmd = Command::new(BIN);
    cmd.current_dir(dir)
        .arg("--trace-io")
        .arg(&journal)
        .args(&case.args);
    if case.args[0] == "capture" && !case.args.iter().any(|a| a == "--out") {
        cmd.arg("--out").arg(&out);
    }
    cmd.stdin(Stdio::null());
    let output = output_within(&mut cmd, Duration::from_secs(60));
    let err = String::from_utf8_lossy(&output.stderr);
    let err: String = err.chars().take(600).collect();
    let mut what = case.args.join(" ");
    if what.len() > 100 {
        what = format!("{}...", &what[..100]);
    }
    if output.status.code() != Some(2) {
        return Some(format!(
            "`{what}`: exit {:?}, not 2: {err}",
            output.status.code()
        ));
    }
    if err.contains("panicked") {
        return Some(format!("`{what}`: panicked: {err}"));
    }
    for name in case.names {
        if !err.contains(name) {
            return Some(format!(
                "`{what}`: the message does not name `{name}`: {err}"
            ));
        }
    }
    let exchanges = std::fs::read_to_string(&journal).unwrap_or_default();
    if let Some(first) = exchanges.lines().next() {
        return Some(format!(
            "`{what}`: refused, but instruments were talked to first ({} exchanges, first {first})",
            exchanges.lines().count()
        ));
    }
    if out.exists() {
        return Some(format!(
            "`{what}`: refused, but {} was written",
            out.display()
        ));
    }
    None
}

/// A capture on the built-in mock lab, kept as the background the corpus spoils.
fn background(dir: &Path) -> String {
    let out = dir.join("bg");
    let mut cmd = Command::new(BIN);
    cmd.args(["capture", "--allow-rf", "--out"]).arg(&out);
    let done = output_within(&mut cmd, Duration::from_secs(120));
    assert!(
        done.status.success(),
        "{}",
        String::from_utf8_lossy(&done.stderr)
    );
    out.join("capture.sigmf-meta").display().to_string()
}

/// A copy of the background with its metadata changed by `edit` (or its data cut short).
fn spoiled(dir: &Path, good: &str, name: &str, edit: impl Fn(&mut serde_json::Value)) -> String {
    let to = dir.join(name);
    std::fs::create_dir_all(&to).unwrap();
    let from = Path::new(good).parent().unwrap();
    for f in ["capture.sigmf-meta", "capture.sigmf-data"] {
        std::fs::copy(from.join(f), to.join(f)).unwrap();
    }
    let meta = to.join("capture.sigmf-meta");
    let mut v: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&meta).unwrap()).unwrap();
    edit(&mut v);
    std::fs::write(&meta, serde_json::to_string(&v).unwrap()).unwrap();
    meta.display().to_string()
}

#[test]
fn every_bad_input_is_refused_by_name_before_anything_is_sent() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path();
    let big_payload = "x".repeat(100_000);
    std::fs::write(dir.join("a-file"), "").unwrap();

    let awg =
        "[awg]\nmodel = \"keysight-m8195a\"\nresource = \"TCPIP0::127.0.0.1::hislip0::INSTR\"\n";
    let scope = "[scope]\nmodel = \"lecroy-labmaster10zi-a\"\nresource = \"VICP::127.0.0.1\"\n";
    let unknown_model = write(
        dir,
        "unknown-model.toml",
        &format!("{}{scope}", awg.replace("m8195a", "m8195x")),
    );
    let bad_resource = write(
        dir,
        "bad-resource.toml",
        &format!("{awg}{}", scope.replace("VICP::", "FOO::")),
    );
    let unknown_field = write(
        dir,
        "unknown-field.toml",
        &format!("{awg}voltz = 3\n{scope}"),
    );
    let broken_toml = write(dir, "broken.toml", "[awg\nmodel = 1\n");
    let no_awg = write(dir, "no-awg.toml", scope);
    let three_offsets = write(
        dir,
        "offsets.toml",
        "[impairments]\ndc_offset_v = [0.0, 0.1, 0.2]\n",
    );
    let huge_amplitude = write(
        dir,
        "amplitude.toml",
        "[[targets]]\nrange_m = 1.0\namplitude = 1e300\n",
    );
    let string_snr = write(dir, "snr.toml", "snr_db = \"high\"\n");
    let truncated_meta = write(dir, "truncated.sigmf-meta", "{\"global\": \n");

    let good = background(dir);
    let gain_string = spoiled(dir, &good, "bg-gain", |v| {
        v["global"]["radbench:vertical_gain"] = "big".into();
    });
    let other_rate = spoiled(dir, &good, "bg-rate", |v| {
        v["global"]["core:sample_rate"] = 40e9.into();
    });
    let cut_data = spoiled(dir, &good, "bg-cut", |_| {});
    {
        let data = Path::new(&cut_data).with_extension("sigmf-data");
        let bytes = std::fs::read(&data).unwrap();
        std::fs::write(&data, &bytes[..bytes.len() / 3]).unwrap();
    }

    let cases = vec![
        // Command-line values: sizes checked before allocating, ranges named.
        case(
            &["capture", "--allow-rf", "--sample-rate", "1e15"],
            &["--sample-rate", "allowed"],
        ),
        case(
            &["capture", "--allow-rf", "--pulse-us", "1e6"],
            &["--pulse-us", "allowed"],
        ),
        case(
            &[
                "capture",
                "--allow-rf",
                "--waveform",
                "ofdm",
                "--symbols",
                "100000000",
            ],
            &["--symbols", "allowed"],
        ),
        case(
            &["capture", "--allow-rf", "--zero-pad", "100000000000"],
            &["--zero-pad", "allowed"],
        ),
        case(
            &["capture", "--allow-rf", "--payload", &big_payload],
            &["--payload", "allowed"],
        ),
        case(
            &["capture", "--allow-rf", "--wait", "-1"],
            &["--wait -1", "allowed"],
        ),
        case(
            &["capture", "--allow-rf", "--pfa", "2"],
            &["--pfa 2", "allowed"],
        ),
        case(
            &["capture", "--allow-rf", "--repetitions", "0"],
            &["--repetitions 0", "allowed"],
        ),
        case(
            &["capture", "--allow-rf", "--out", "a-file"],
            &["--out a-file", "is a file"],
        ),
        case(
            &[
                "capture",
                "--allow-rf",
                "--min-range",
                "5",
                "--max-range",
                "1",
            ],
            &["--min-range", "allowed"],
        ),
        case(
            &["capture", "--allow-rf", "--algorithm", "music"],
            &["--algorithm music", "--waveform ofdm"],
        ),
        case(
            &[
                "capture",
                "--allow-rf",
                "--waveform",
                "ofdm",
                "--algorithm",
                "music",
                "--m",
                "0",
            ],
            &["--m 0", "allowed"],
        ),
        case(
            &[
                "capture",
                "--allow-rf",
                "--waveform",
                "ofdm",
                "--algorithm",
                "music",
                "--m",
                "64",
                "--p",
                "70",
            ],
            &["--p 70", "allowed"],
        ),
        case(
            &[
                "simulate",
                "run",
                "--waveform",
                "msk-lfm",
                "--targets",
                "1.0",
                "--trials",
                "1000000000",
            ],
            &["--trials", "allowed"],
        ),
        case(
            &[
                "simulate",
                "run",
                "--waveform",
                "msk-lfm",
                "--targets",
                "1.0",
                "--capture-rate",
                "16e15",
            ],
            &["--capture-rate", "allowed"],
        ),
        case(
            &["simulate", "ber", "--bits", "100000000000000"],
            &["--bits", "allowed"],
        ),
        case(
            &[
                "calibrate",
                "--allow-rf",
                "--reference-range",
                "1.0",
                "--search",
                "0",
            ],
            &["--search 0", "allowed"],
        ),
        case(
            &["calibrate", "--allow-rf", "--reference-range", "NaN"],
            &["--reference-range NaN"],
        ),
        case(
            &["mock-lab", "serve", "--port-base", "65535"],
            &["--port-base 65535"],
        ),
        case(
            &["scpi", "ASRL/dev/null::INSTR", "--baud", "0", "*IDN?"],
            &["--baud 0"],
        ),
        case(&["idn", "FOO::bar"], &["FOO::bar", "accepted forms"]),
        // Absurd magnitudes: the option's own name, the value as given, what is allowed.
        case(
            &[
                "simulate",
                "run",
                "--waveform",
                "msk-lfm",
                "--targets",
                "1:1:1e300",
            ],
            &["--targets", "velocity 1e300", "allowed"],
        ),
        case(
            &[
                "simulate",
                "run",
                "--waveform",
                "ofdm",
                "--targets",
                "1",
                "--cp-fraction",
                "1e300",
            ],
            &["--cp-fraction", "1e300", "below 1"],
        ),
        case(
            &["capture", "--allow-rf", "--max-range", "inf"],
            &["--max-range inf", "0 ..= 10000"],
        ),
        // Bench files: the file, the line and the field.
        case(
            &["capture", "--allow-rf", "--bench", &unknown_model],
            &[
                "unknown-model.toml",
                "line 2",
                "model",
                "keysight-m8195x",
                "allowed",
            ],
        ),
        case(
            &["capture", "--allow-rf", "--bench", &bad_resource],
            &["bad-resource.toml", "line 6", "resource", "accepted forms"],
        ),
        case(
            &["capture", "--allow-rf", "--bench", &unknown_field],
            &["unknown-field.toml", "line 4", "voltz", "expected one of"],
        ),
        case(
            &["capture", "--allow-rf", "--bench", &broken_toml],
            &["broken.toml", "line 1"],
        ),
        case(
            &["capture", "--allow-rf", "--bench", &no_awg],
            &["no-awg.toml", "awg"],
        ),
        case(
            &["capture", "--allow-rf", "--bench", "missing.toml"],
            &["missing.toml"],
        ),
        // Scene files.
        case(
            &["capture", "--allow-rf", "--scene", &three_offsets],
            &["offsets.toml", "line 2", "dc_offset_v", "exactly 2"],
        ),
        case(
            &["capture", "--allow-rf", "--scene", &huge_amplitude],
            &[
                "amplitude.toml",
                "line 3",
                "targets[0].amplitude",
                "allowed",
            ],
        ),
        case(
            &["capture", "--allow-rf", "--scene", &string_snr],
            &["snr.toml", "line 1", "f64"],
        ),
        // Background files: read and checked before RF goes on.
        case(
            &[
                "capture",
                "--allow-rf",
                "--background",
                "missing.sigmf-meta",
            ],
            &["missing.sigmf-meta"],
        ),
        case(
            &["capture", "--allow-rf", "--background", &truncated_meta],
            &["truncated.sigmf-meta", "not SigMF"],
        ),
        case(
            &["capture", "--allow-rf", "--background", &gain_string],
            &["radbench:vertical_gain", "\"big\""],
        ),
        case(
            &["capture", "--allow-rf", "--background", &other_rate],
            &["--background", "40000000000 Sa/s"],
        ),
        case(
            &["capture", "--allow-rf", "--background", &cut_data],
            &["capture.sigmf-data", "core:sha512"],
        ),
        case(
            &[
                "capture",
                "--allow-rf",
                "--bandwidth",
                "2e9",
                "--background",
                &good,
            ],
            &["--background", "bandwidth_hz"],
        ),
        case(
            &[
                "capture",
                "--allow-rf",
                "--waveform",
                "ofdm",
                "--background",
                &good,
            ],
            &["--background", "it holds msk-lfm, this capture sends ofdm"],
        ),
    ];
    let failures: Vec<String> = cases
        .iter()
        .enumerate()
        .filter_map(|(i, c)| check(dir, i, c))
        .collect();
    assert!(
        failures.is_empty(),
        "{} of {} cases:\n{}",
        failures.len(),
        cases.len(),
        failures.join("\n")
    );
}
