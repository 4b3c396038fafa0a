//! `radbench doctor --verify-catalog`: on the mock lab every queried value is confirmed; a lab
//! whose AWG answers `*OPT?` and `:FREQ:RAST? MAX` differently is reported, and `--write-overrides`
//! writes one overrides file the bench file can point to, after which the values are confirmed.

use super::support::{lab_bench_file, radbench_in, start_lab};
use std::time::Duration;
use tokio::io::{AsyncBufReadExt, AsyncWriteExt, BufReader};

/// One request on the lab's control channel and its one-line answer.
async fn control(lab: &mock_lab::lab::Lab, request: &str) -> serde_json::Value {
    let stream = tokio::net::TcpStream::connect(lab.control).await.unwrap();
    let (rd, mut wr) = stream.into_split();
    wr.write_all(format!("{request}\n").as_bytes())
        .await
        .unwrap();
    let mut line = String::new();
    tokio::time::timeout(
        Duration::from_secs(10),
        BufReader::new(rd).read_line(&mut line),
    )
    .await
    .unwrap()
    .unwrap();
    serde_json::from_str(&line).unwrap()
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn the_catalog_is_checked_on_the_instruments() {
    let lab = start_lab().await;
    let dir = tempfile::tempdir().unwrap();
    let bench = lab_bench_file(dir.path(), &lab);
    let verify = ["doctor", "--bench", &bench, "--verify-catalog"];
    let (code, out, err) = radbench_in(Some(dir.path()), &verify).await;
    assert_eq!(code, 0, "{out}\n{err}");
    assert!(
        out.contains("awg.options") && out.contains("0 differ"),
        "{out}"
    );
    // Every value of the AWG and the scope is asked and confirmed: options, rates, memory, V/div,
    // segment counts.
    let rows: Vec<&str> = out.lines().filter(|l| !l.starts_with(' ')).collect();
    let asked = rows
        .iter()
        .filter(|l| l.starts_with("awg ") || l.starts_with("scope "));
    for line in asked.clone() {
        assert!(line.ends_with("confirmed"), "{line}\n{out}");
    }
    for field in [
        "awg.dac_rate_max",
        "awg.internal_memory_samples",
        "awg.extended_memory_samples",
        "awg.max_segment_id",
        "digitizer.sample_rates",
        "digitizer.max_points_per_channel",
        "digitizer.volts_per_div_min",
        "digitizer.volts_per_div_max",
        "digitizer.max_sequence_segments",
    ] {
        assert!(
            asked.clone().any(|l| l.contains(&format!(" {field} "))),
            "{field}\n{out}"
        );
    }
    // What is left unasked says why (the modules' project-defined protocol).
    assert!(out.contains("cannot be queried"), "{out}");

    // A unit with other options and another top rate, set through the lab's control channel.
    let answer = control(
        &lab,
        r#"{"cmd":"fault","awg_options":["001","002"],"awg_raster_max":6.45e10}"#,
    )
    .await;
    assert_ne!(answer["ok"], false, "{answer}");
    let mut with_overrides = verify.to_vec();
    with_overrides.extend(["--write-overrides", "overrides.toml", "--json"]);
    let (code, out, err) = radbench_in(Some(dir.path()), &with_overrides).await;
    assert_eq!(code, 3, "{out}\n{err}");
    let json: serde_json::Value = serde_json::from_str(&out).unwrap();
    let options = json["values"]
        .as_array()
        .unwrap()
        .iter()
        .find(|v| v["field"] == "awg.options")
        .unwrap();
    assert_eq!(options["verdict"], "differs", "{options}");
    assert_eq!(options["answer"], "001,002", "{options}");
    let rate = json["values"]
        .as_array()
        .unwrap()
        .iter()
        .find(|v| v["field"] == "awg.dac_rate_max")
        .unwrap();
    assert_eq!(rate["verdict"], "differs", "{rate}");
    assert_eq!(rate["answer"], "6.45e10 Sa/s", "{rate}");
    // One file of just the differing values.
    let written = dir.path().join("overrides.toml");
    let text = std::fs::read_to_string(&written).unwrap();
    assert!(text.contains("[keysight-m8195a.awg]"), "{text}");
    assert!(text.contains("options = [\"001\", \"002\"]"), "{text}");
    assert!(text.contains("dac_rate_max = 64500000000"), "{text}");
    assert!(!text.contains("dac_rate_min"), "{text}");
    assert!(
        err.contains("catalog_overrides = \"overrides.toml\""),
        "{err}"
    );

    // The bench pointed at the overrides: confirmed, the unit still answering differently.
    let pointed = format!(
        "catalog_overrides = \"overrides.toml\"\n{}",
        std::fs::read_to_string(&bench).unwrap()
    );
    std::fs::write(&bench, pointed).unwrap();
    let (code, out, err) = radbench_in(Some(dir.path()), &verify).await;
    assert_eq!(code, 0, "{out}\n{err}");
    assert!(out.contains("0 differ"), "{out}");

    // The folder form of earlier versions still loads: a copy of the instrument file with the
    // unit's options in a `catalog` folder, the rate back to the catalog's.
    control(&lab, r#"{"cmd":"fault","awg_raster_max":0}"#).await;
    let folder = dir.path().join("my-instruments");
    std::fs::create_dir(&folder).unwrap();
    let original = std::fs::read_to_string(
        std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("instruments/keysight_m8195a.toml"),
    )
    .unwrap();
    std::fs::write(
        folder.join("keysight_m8195a.toml"),
        original.replace(
            r#"options = ["001", "002", "004", "16G"]"#,
            r#"options = ["001", "002"]"#,
        ),
    )
    .unwrap();
    let own = lab_bench_file(dir.path(), &lab);
    let with_folder = format!(
        "catalog = \"my-instruments\"\n{}",
        std::fs::read_to_string(&own).unwrap()
    );
    std::fs::write(&own, with_folder).unwrap();
    let (code, out, err) = radbench_in(
        Some(dir.path()),
        &["doctor", "--bench", &own, "--verify-catalog"],
    )
    .await;
    assert_eq!(code, 0, "{out}\n{err}");
    assert!(out.contains("0 differ"), "{out}");
}
