//! `radbench doctor --verify-catalog`: on the mock lab every queried value is confirmed; a lab
//! whose AWG answers `*OPT?` differently is reported, and `--write-overrides` writes an instrument
//! file the bench file can point to, after which the value is confirmed.

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
    let rows = out.lines().filter(|l| !l.starts_with(' '));
    for line in rows.filter(|l| l.contains(" identity ") || l.contains(" awg.options ")) {
        assert!(line.ends_with("confirmed"), "{line}\n{out}");
    }
    assert!(out.contains("digitizer.max_sequence_segments"), "{out}");
    assert!(out.contains("cannot be queried"), "{out}");

    // A unit with other options, set through the lab's control channel.
    let answer = control(&lab, r#"{"cmd":"fault","awg_options":["001","002"]}"#).await;
    assert_ne!(answer["ok"], false, "{answer}");
    let mut with_overrides = verify.to_vec();
    with_overrides.extend(["--write-overrides", "overrides", "--json"]);
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
    let written = dir.path().join("overrides/keysight_m8195a.toml");
    let text = std::fs::read_to_string(&written).unwrap();
    assert!(text.contains("options = [\"001\", \"002\"]"), "{text}");
    assert!(err.contains("catalog = \"overrides\""), "{err}");

    // The bench pointed at the overrides: confirmed.
    let pointed = format!(
        "catalog = \"overrides\"\n{}",
        std::fs::read_to_string(&bench).unwrap()
    );
    std::fs::write(&bench, pointed).unwrap();
    let (code, out, err) = radbench_in(Some(dir.path()), &verify).await;
    assert_eq!(code, 0, "{out}\n{err}");
    assert!(out.contains("0 differ"), "{out}");
}
