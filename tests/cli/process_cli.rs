//! `radbench process`: saved captures through the pipeline again, as a user would run it long
//! after the bench is gone.

use serde_json::Value;
use std::path::Path;

async fn radbench(dir: &Path, args: &[&str]) -> (i32, String, String) {
    crate::support::radbench_in(Some(dir), args).await
}

fn json_file(path: &Path) -> Value {
    serde_json::from_str(&std::fs::read_to_string(path).unwrap()).unwrap()
}

const SCENE: &str = "snr_db = 30.0\n[[targets]]\nrange_m = 1.0\namplitude = 0.5\n\
                     [[targets]]\nrange_m = 1.3\namplitude = 0.3\n";

/// The figures a summary reports, which re-processing with the original options must repeat.
const FIGURES: [&str; 6] = [
    "targets",
    "width_3db_cm",
    "sidelobe_db",
    "snr_db",
    "payload",
    "spread",
];

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn the_original_options_give_the_original_figures_exactly() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    std::fs::write(d.join("scene.toml"), SCENE).unwrap();
    for (name, extra) in [
        ("msk", &["--repetitions", "2", "--payload", "hello"][..]),
        ("ofdm", &["--waveform", "ofdm", "--window", "hann"][..]),
    ] {
        let mut args = vec![
            "capture",
            "--allow-rf",
            "--scene",
            "scene.toml",
            "--out",
            name,
        ];
        args.extend_from_slice(extra);
        let (code, _, err) = radbench(d, &args).await;
        assert_eq!(code, 0, "{err}");
        let out = format!("{name}-again");
        let (code, _, err) = radbench(d, &["process", name, "--out", &out]).await;
        assert_eq!(code, 0, "{err}");
        let original = json_file(&d.join(name).join("summary.json"));
        let again = json_file(&d.join(&out).join(name).join("summary.json"));
        for key in FIGURES {
            assert_eq!(original[key], again[key], "{name}: {key}");
        }
        assert_eq!(original["processing"], again["processing"]);
        // The link figure: SVG always, PNG only when asked for (the capture wrote both).
        let folder = d.join(&out).join(name);
        assert!(folder.join("link.svg").is_file(), "{name}");
        assert!(!folder.join("link.png").exists(), "{name}");
        assert!(again["files"].get("link_png").is_none(), "{name}");
        assert!(d.join(name).join("link.png").is_file(), "{name}");
        let with_png = format!("{name}-png");
        let (code, _, err) =
            radbench(d, &["process", name, "--link-png", "--out", &with_png]).await;
        assert_eq!(code, 0, "{err}");
        let png = d.join(&with_png).join(name).join("link.png");
        assert!(
            std::fs::read(&png).unwrap().starts_with(b"\x89PNG"),
            "{name}"
        );
        // The manifest names the sources with their SHA-256.
        let manifest: toml::Value = toml::from_str(
            &std::fs::read_to_string(d.join(&out).join(name).join("manifest.toml")).unwrap(),
        )
        .unwrap();
        let sources = manifest["sources"].as_array().unwrap();
        assert_eq!(sources.len(), 2);
        for s in sources {
            let path = Path::new(s["path"].as_str().unwrap());
            let bytes = std::fs::read(d.join(path)).unwrap();
            assert_eq!(
                s["sha256"].as_str().unwrap(),
                radbench::storage::sha256(&bytes)
            );
        }
    }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn another_algorithm_gives_that_algorithms_result() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    std::fs::write(d.join("scene.toml"), SCENE).unwrap();
    let (code, _, err) = radbench(
        d,
        &[
            "capture",
            "--allow-rf",
            "--scene",
            "scene.toml",
            "--waveform",
            "ofdm",
            "--out",
            "c",
        ],
    )
    .await;
    assert_eq!(code, 0, "{err}");
    for alg in ["music", "esprit", "root-music", "correlation"] {
        let out = format!("p-{alg}");
        let (code, _, err) = radbench(
            d,
            &[
                "process",
                "c",
                "--algorithm",
                alg,
                "--p",
                "3",
                "--out",
                &out,
            ],
        )
        .await;
        assert_eq!(code, 0, "{alg}: {err}");
        let s = json_file(&d.join(&out).join("c").join("summary.json"));
        assert_eq!(s["algorithm"], alg);
        let found: Vec<f64> = s["targets"]
            .as_array()
            .unwrap()
            .iter()
            .map(|t| t["range_m"].as_f64().unwrap())
            .collect();
        for truth in [1.0, 1.3] {
            assert!(
                found.iter().any(|r| (r - truth).abs() < 0.01),
                "{alg}: {truth} m not in {found:?}"
            );
        }
    }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_bad_input_is_reported_and_the_others_go_on() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let (code, _, err) = radbench(d, &["capture", "--allow-rf", "--out", "good"]).await;
    assert_eq!(code, 0, "{err}");
    // A .trc pair away from its capture's metadata: nothing says which waveform it holds.
    std::fs::create_dir(d.join("bare")).unwrap();
    for c in ["C1.trc", "C2.trc"] {
        std::fs::copy(d.join("good").join(c), d.join("bare").join(c)).unwrap();
    }
    let (code, out, err) = radbench(
        d,
        &[
            "process",
            "good",
            "missing",
            "bare/C1.trc",
            "bare/C2.trc",
            "--out",
            "p",
            "--json",
        ],
    )
    .await;
    assert_eq!(code, 2, "{err}");
    let doc: Value = serde_json::from_str(&out).unwrap();
    assert_eq!(doc["processed"].as_array().unwrap().len(), 1);
    let failed = doc["failed"].as_array().unwrap();
    assert_eq!(failed.len(), 2, "{failed:?}");
    assert!(
        err.contains("missing") && err.contains("--waveform"),
        "{err}"
    );
    assert!(d.join("p/good/summary.json").is_file());
    // Never over what is there.
    let (code, _, err) = radbench(d, &["process", "good", "--out", "p"]).await;
    assert_eq!(code, 2);
    assert!(err.contains("exists already"), "{err}");
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn the_recorded_background_is_subtracted_again() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    std::fs::write(d.join("empty.toml"), "snr_db = 30.0\ntargets = []\n").unwrap();
    std::fs::write(d.join("scene.toml"), SCENE).unwrap();
    let (code, _, err) = radbench(
        d,
        &[
            "capture",
            "--allow-rf",
            "--scene",
            "empty.toml",
            "--out",
            "bg",
        ],
    )
    .await;
    assert_eq!(code, 0, "{err}");
    let (code, _, err) = radbench(
        d,
        &[
            "capture",
            "--allow-rf",
            "--scene",
            "scene.toml",
            "--background",
            "bg/capture.sigmf-meta",
            "--out",
            "with",
        ],
    )
    .await;
    assert_eq!(code, 0, "{err}");
    let (code, _, err) = radbench(d, &["process", "with", "--out", "again"]).await;
    assert_eq!(code, 0, "{err}");
    let original = json_file(&d.join("with/summary.json"));
    let again = json_file(&d.join("again/with/summary.json"));
    for key in FIGURES {
        assert_eq!(original[key], again[key], "{key}");
    }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_recording_radbench_did_not_make_takes_the_waveform_from_options() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let (code, _, err) = radbench(d, &["capture", "--allow-rf", "--out", "c"]).await;
    assert_eq!(code, 0, "{err}");
    // Another tool's recording of the same samples: cf32, big-endian, no radbench metadata.
    let rec = radbench::storage::read_sigmf(&d.join("c/capture.sigmf-meta")).unwrap();
    let trigger = rec.radbench.as_ref().unwrap().trigger_offset_s.unwrap();
    let mut data = Vec::new();
    for z in &rec.samples {
        data.extend_from_slice(&(z.re as f32).to_be_bytes());
        data.extend_from_slice(&(z.im as f32).to_be_bytes());
    }
    std::fs::write(d.join("other.sigmf-data"), data).unwrap();
    std::fs::write(
        d.join("other.sigmf-meta"),
        serde_json::json!({
            "global": {"core:datatype": "cf32_be", "core:sample_rate": 80e9, "core:version": "1.0.0"},
            "captures": [{"core:sample_start": 0}],
            "annotations": [],
        })
        .to_string(),
    )
    .unwrap();
    let (code, _, err) = radbench(d, &["process", "other.sigmf-meta", "--out", "p1"]).await;
    assert_eq!(code, 2);
    assert!(err.contains("--waveform"), "{err}");
    let trigger = trigger.to_string();
    let (code, _, err) = radbench(
        d,
        &[
            "process",
            "other.sigmf-meta",
            "--waveform",
            "msk-lfm",
            "--trigger-offset",
            &trigger,
            "--system-delay",
            "2.5e-9",
            "--out",
            "p2",
        ],
    )
    .await;
    assert_eq!(code, 0, "{err}");
    let s = json_file(&d.join("p2/other/summary.json"));
    let r = s["targets"][0]["range_m"].as_f64().unwrap();
    assert!((r - 1.0).abs() < 1e-3, "{s}");
}

/// `radbench process C1.trc C2.trc` from a capture folder: the pair is radbench's own, and the
/// capture's metadata beside it gives the waveform and the system delay (the pillar at 1.000 m,
/// not 37.5 cm short with the delay silently taken as 0).
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn radbenchs_own_trc_pair_is_processed_with_its_captures_metadata() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    std::fs::write(
        d.join("scene.toml"),
        "snr_db = 30.0\n[[targets]]\nrange_m = 1.0\namplitude = 0.5\n",
    )
    .unwrap();
    let (code, _, err) = radbench(
        d,
        &[
            "capture",
            "--allow-rf",
            "--scene",
            "scene.toml",
            "--out",
            "cap",
        ],
    )
    .await;
    assert_eq!(code, 0, "{err}");
    let (code, out, err) = radbench(
        &d.join("cap"),
        &["process", "C1.trc", "C2.trc", "--out", "../again", "--json"],
    )
    .await;
    assert_eq!(code, 0, "{err}");
    let summary = json_file(&d.join("again/C1/summary.json"));
    let ranges: Vec<f64> = summary["targets"]
        .as_array()
        .unwrap()
        .iter()
        .map(|t| t["range_m"].as_f64().unwrap())
        .collect();
    assert!(
        ranges.iter().any(|r| (r - 1.0).abs() < 0.002),
        "{ranges:?}: {out}"
    );
    let original = json_file(&d.join("cap/summary.json"));
    assert_eq!(
        original["processing"]["system_delay_s"],
        summary["processing"]["system_delay_s"]
    );
    assert_eq!(
        summary["warnings"],
        serde_json::json!([]),
        "nothing assumed"
    );

    // Away from its capture, with only --waveform: the delay and the bits it had to assume are
    // said, in the summary and on the console.
    std::fs::create_dir(d.join("bare")).unwrap();
    for c in ["C1.trc", "C2.trc"] {
        std::fs::copy(d.join("cap").join(c), d.join("bare").join(c)).unwrap();
    }
    let (code, out, err) = radbench(
        &d.join("bare"),
        &[
            "process",
            "C1.trc",
            "C2.trc",
            "--waveform",
            "msk-lfm",
            "--out",
            "../bare-p",
        ],
    )
    .await;
    assert_eq!(code, 0, "{err}");
    assert!(
        out.contains("warning: the capture does not record the bench's system delay"),
        "{out}"
    );
    assert!(out.contains("PRBS seed 1 was assumed"), "{out}");
    let summary = json_file(&d.join("bare-p/C1/summary.json"));
    let warnings = summary["warnings"].to_string();
    assert!(warnings.contains("0 s was assumed"), "{warnings}");
}

/// `radbench process` with the cache of prepared pieces (`RADBENCH_CACHE_DIR`) in a given state.
async fn process_cached(dir: &Path, cache: &Path, input: &str, out: &str) -> Value {
    let output = tokio::process::Command::new(env!("CARGO_BIN_EXE_radbench"))
        .args(["process", input, "--out", out])
        .current_dir(dir)
        .env("RADBENCH_CACHE_DIR", cache)
        .env_remove("RADBENCH_CACHE")
        .stdin(std::process::Stdio::null())
        .output()
        .await
        .unwrap();
    assert!(
        output.status.success(),
        "{}",
        String::from_utf8_lossy(&output.stderr)
    );
    json_file(&dir.join(out).join(input).join("summary.json"))
}

/// Every file of the cache, by kind.
fn cached_files(cache: &Path) -> Vec<std::path::PathBuf> {
    let mut files = Vec::new();
    for kind in std::fs::read_dir(cache).unwrap() {
        for f in std::fs::read_dir(kind.unwrap().path()).unwrap() {
            files.push(f.unwrap().path());
        }
    }
    files.sort();
    files
}

/// The decimation filter and the detector's point spread are kept on disk between runs; a piece
/// that is corrupt, or another input's piece under this one's name (stale), is rebuilt and never
/// used: the results are the same bytes as without the cache.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_corrupt_or_stale_cached_piece_is_rebuilt_never_used() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let cache = d.join("cache");
    std::fs::write(d.join("scene.toml"), SCENE).unwrap();
    let (code, _, err) = radbench(
        d,
        &[
            "capture",
            "--allow-rf",
            "--scene",
            "scene.toml",
            "--out",
            "c",
        ],
    )
    .await;
    assert_eq!(code, 0, "{err}");
    let same = |a: &str, b: &str| {
        for f in ["profile.npy", "profile.csv"] {
            let (x, y) = (d.join(a).join("c").join(f), d.join(b).join("c").join(f));
            assert_eq!(
                std::fs::read(x).unwrap(),
                std::fs::read(y).unwrap(),
                "{a} {b} {f}"
            );
        }
    };
    let first = process_cached(d, &cache, "c", "cold").await;
    let files = cached_files(&cache);
    assert_eq!(files.len(), 2, "taps and point spread: {files:?}");
    let warm = process_cached(d, &cache, "c", "warm").await;
    same("cold", "warm");
    assert_eq!(first["targets"], warm["targets"]);

    // Corrupt: one bit of each piece flipped.
    let good: Vec<Vec<u8>> = files.iter().map(|f| std::fs::read(f).unwrap()).collect();
    for (f, bytes) in files.iter().zip(&good) {
        let mut bad = bytes.clone();
        let k = bad.len() - 3;
        bad[k] ^= 0x10;
        std::fs::write(f, bad).unwrap();
    }
    let corrupt = process_cached(d, &cache, "c", "corrupt").await;
    same("cold", "corrupt");
    assert_eq!(first["targets"], corrupt["targets"]);
    // Rebuilt and stored again, whole.
    for (f, bytes) in files.iter().zip(&good) {
        assert_eq!(&std::fs::read(f).unwrap(), bytes);
    }

    // Stale: each piece's file holds the other's (a valid piece of another key).
    std::fs::write(&files[0], &good[1]).unwrap();
    std::fs::write(&files[1], &good[0]).unwrap();
    let stale = process_cached(d, &cache, "c", "stale").await;
    same("cold", "stale");
    assert_eq!(first["targets"], stale["targets"]);
    for (f, bytes) in files.iter().zip(&good) {
        assert_eq!(&std::fs::read(f).unwrap(), bytes);
    }
}

/// A run folder's manifest records each data file's SHA-256 as it was written: a capture whose
/// data matches it is not checked a second time against its recording's SHA-512 (one hash
/// instead of two), and one whose data does not match it is checked against that SHA-512 as
/// before, and refused.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_run_manifests_recorded_hash_stands_for_the_recordings_own_and_never_excuses_changed_data(
) {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let spec = "name = \"two\"\nseed = 1\n[waveform]\nkind = \"msk-lfm\"\n[sweep]\n\
                parameter = \"position\"\nstart = 1.0\nstep = -0.03\ncount = 2\n";
    std::fs::write(d.join("two.toml"), spec).unwrap();
    let (code, _, err) = radbench(
        d,
        &["campaign", "run", "two.toml", "--allow-rf", "--out", "run"],
    )
    .await;
    assert_eq!(code, 0, "{err}");
    // Step 1: the recording's own SHA-512 made wrong, its data as written.
    let meta_path = d.join("run/step-001/capture.sigmf-meta");
    let mut meta = json_file(&meta_path);
    meta["global"]["core:sha512"] = Value::from("00".repeat(64));
    std::fs::write(&meta_path, serde_json::to_string_pretty(&meta).unwrap()).unwrap();
    // Step 2: one byte of the data changed after it was recorded.
    let data_path = d.join("run/step-002/capture.sigmf-data");
    let mut data = std::fs::read(&data_path).unwrap();
    data[1000] ^= 0x01;
    std::fs::write(&data_path, &data).unwrap();

    let (code, out, err) = radbench(d, &["process", "run", "--out", "p", "--json"]).await;
    assert_eq!(code, 2, "{err}");
    let doc: Value = serde_json::from_str(&out).unwrap();
    let processed = doc["processed"].as_array().unwrap();
    assert_eq!(processed.len(), 1, "{doc}");
    assert!(d.join("p/step-001/summary.json").is_file());
    assert!(!d.join("p/step-002/summary.json").exists());
    assert!(
        err.contains("step-002") && err.contains("core:sha512"),
        "{err}"
    );
    // Away from its run folder (no manifest), step 1's wrong SHA-512 is refused.
    std::fs::rename(d.join("run/step-001"), d.join("alone")).unwrap();
    let (code, _, err) = radbench(d, &["process", "alone", "--out", "q"]).await;
    assert_eq!(code, 2, "{err}");
    assert!(err.contains("core:sha512"), "{err}");
}
