//! A line protocol other than radbench's, described as data (tests/data/protocols/: no checksum,
//! an address prefix, other request and reply words, decimal numbers, other register addresses),
//! served by mock_lab from the same files, drives the modules with no code change: the doctor
//! identifies them, a capture enables them, and the safe state switches them off and verifies it.

use super::support::{radbench_in, LIMIT};
use mock_lab::server::launch::Transport;
use std::path::Path;
use std::time::Duration;

fn fixture(name: &str) -> String {
    std::fs::read_to_string(
        Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("tests/data/protocols")
            .join(name),
    )
    .unwrap()
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn another_protocol_drives_the_modules_with_no_code_change() {
    let (tx, rx) = (fixture("acme_eband_tx.toml"), fixture("acme_eband_rx.toml"));
    let models = (
        mock_lab::catalog::rf_from_str(&tx).unwrap(),
        mock_lab::catalog::rf_from_str(&rx).unwrap(),
    );
    let lab = tokio::time::timeout(
        Duration::from_secs(10),
        mock_lab::lab::start(mock_lab::lab::LabOptions {
            front_ends: Some(models),
            ..mock_lab::lab::LabOptions::default()
        }),
    )
    .await
    .expect("lab starts")
    .expect("lab starts");
    let dir = tempfile::tempdir().unwrap();
    let folder = dir.path().join("instruments");
    std::fs::create_dir(&folder).unwrap();
    std::fs::write(folder.join("acme_eband_tx.toml"), &tx).unwrap();
    std::fs::write(folder.join("acme_eband_rx.toml"), &rx).unwrap();
    // The lab's bench file names the served files' models, and says where radbench finds them.
    let served = lab.bench_toml(Transport::Hislip, Transport::Vicp);
    assert!(
        served.contains("model = \"acme-eband-tx\"")
            && served.contains("model = \"acme-eband-rx\"")
            && served.contains("add catalog = \"FOLDER\""),
        "{served}"
    );
    let bench = format!(
        "catalog = \"instruments\"\n{served}\n[calibration]\nsystem_delay_s = {:e}\n",
        mock_lab::scene::Scene::default().system_delay_s
    );
    std::fs::write(dir.path().join("bench.toml"), bench).unwrap();

    let (code, out, err) =
        radbench_in(Some(dir.path()), &["doctor", "--bench", "bench.toml"]).await;
    assert_eq!(code, 0, "{out}\n{err}");
    assert!(
        out.contains("tx.crc_mode") && out.contains("the module speaks plain lines"),
        "{out}"
    );
    assert!(out.contains("tx.identity"), "{out}");
    let sent = lab.bench.tx.log().texts().join("\n");
    assert!(sent.contains("#1 ID?") && !sent.contains('*'), "{sent}");

    lab.bench.tx.log().clear();
    let (code, out, err) = tokio::time::timeout(
        LIMIT,
        radbench_in(
            Some(dir.path()),
            &[
                "capture",
                "--bench",
                "bench.toml",
                "--allow-rf",
                "--out",
                "run",
            ],
        ),
    )
    .await
    .unwrap();
    assert_eq!(code, 0, "{out}\n{err}");
    let sent = lab.bench.tx.log().texts().join("\n");
    // CONTROL is at 0x25 = 37 in the fixture: enabled (15), then off (0), each read back.
    assert!(sent.contains("#1 SET 37=15"), "{sent}");
    assert!(sent.contains("#1 SET 37=0"), "{sent}");
    assert!(sent.contains("#1 GET 37"), "{sent}");
    assert!(lab.bench.is_safe());
    assert!(!lab.bench.rx.front_end().rf_enabled);
    let summary = std::fs::read_to_string(dir.path().join("run/summary.json")).unwrap();
    assert!(summary.contains("GOTMIC-EBAND-TX-EMU"), "{summary}");
}
