//! `radbench export` and `results.csv`: a capture's and a run's arrays equal what radbench
//! itself wrote (summary.json, profile.npy, results.json), bad inputs and outputs are refused
//! with the documented exit codes, and run folders from before results.csv still report and
//! resume. (numpy and h5py read the files in interop/test_export.py.)

use serde_json::Value;
use std::collections::BTreeMap;
use std::path::Path;

async fn radbench(dir: &Path, args: &[&str]) -> (i32, String, String) {
    crate::support::radbench_in(Some(dir), args).await
}

fn json_file(path: &Path) -> Value {
    serde_json::from_str(&std::fs::read_to_string(path).unwrap()).unwrap()
}

fn u16_at(b: &[u8], at: usize) -> usize {
    u16::from_le_bytes([b[at], b[at + 1]]) as usize
}
fn u32_at(b: &[u8], at: usize) -> u32 {
    u32::from_le_bytes(b[at..at + 4].try_into().unwrap())
}
fn u64_at(b: &[u8], at: usize) -> usize {
    u64::from_le_bytes(b[at..at + 8].try_into().unwrap()) as usize
}

/// The arrays of an `.npz` radbench wrote, by name (`name.npy` without `.npy`), read through
/// its ZIP64 central directory.
fn npz(path: &Path) -> BTreeMap<String, Vec<u8>> {
    let zip = std::fs::read(path).unwrap();
    let locator = zip.len() - 22 - 20;
    assert_eq!(u32_at(&zip, locator), 0x0706_4b50);
    let end64 = u64_at(&zip, locator + 8);
    let count = u64_at(&zip, end64 + 32);
    let mut at = u64_at(&zip, end64 + 48);
    let mut out = BTreeMap::new();
    for _ in 0..count {
        assert_eq!(u32_at(&zip, at), 0x0201_4b50);
        let name_len = u16_at(&zip, at + 28);
        let extra_len = u16_at(&zip, at + 30);
        let name = std::str::from_utf8(&zip[at + 46..at + 46 + name_len]).unwrap();
        let extra = at + 46 + name_len;
        let size = u64_at(&zip, extra + 4);
        let offset = u64_at(&zip, extra + 20);
        let data = offset + 30 + u16_at(&zip, offset + 26) + u16_at(&zip, offset + 28);
        out.insert(
            name.strip_suffix(".npy").unwrap().to_string(),
            zip[data..data + size].to_vec(),
        );
        at = extra + extra_len;
    }
    out
}

/// An `.npy`'s header dict, shape and data.
fn npy(bytes: &[u8]) -> (String, Vec<usize>, &[u8]) {
    assert_eq!(&bytes[..8], b"\x93NUMPY\x01\x00");
    let len = u16_at(bytes, 8);
    let dict = std::str::from_utf8(&bytes[10..10 + len])
        .unwrap()
        .to_string();
    let shape_text = dict
        .split("'shape': (")
        .nth(1)
        .unwrap()
        .split(')')
        .next()
        .unwrap();
    let shape = shape_text
        .split(',')
        .map(str::trim)
        .filter(|s| !s.is_empty())
        .map(|s| s.parse().unwrap())
        .collect();
    (dict, shape, &bytes[10 + len..])
}

fn f64s(data: &[u8]) -> Vec<f64> {
    data.chunks_exact(8)
        .map(|c| f64::from_le_bytes(c.try_into().unwrap()))
        .collect()
}

/// A 0-d unicode array's text.
fn text(bytes: &[u8]) -> String {
    let (dict, shape, data) = npy(bytes);
    assert!(dict.contains("'descr': '<U"), "{dict}");
    assert!(shape.is_empty());
    data.chunks_exact(4)
        .map(|c| char::from_u32(u32::from_le_bytes(c.try_into().unwrap())).unwrap())
        .filter(|c| *c != '\0')
        .collect()
}

/// A structured array's column `field` (float64 fields only).
fn column(bytes: &[u8], field: &str) -> Vec<f64> {
    let (dict, shape, data) = npy(bytes);
    let names: Vec<&str> = dict
        .split("('")
        .skip(1)
        .map(|s| s.split('\'').next().unwrap())
        .collect();
    let k = names.iter().position(|n| *n == field).unwrap();
    let values = f64s(data);
    (0..shape[0]).map(|r| values[r * names.len() + k]).collect()
}

fn ranges(targets: &Value) -> Vec<f64> {
    targets
        .as_array()
        .unwrap()
        .iter()
        .map(|t| t["range_m"].as_f64().unwrap())
        .collect()
}

const SCENE: &str = "snr_db = 30.0\n[[targets]]\nrange_m = 1.0\namplitude = 0.5\n\
                     [[targets]]\nrange_m = 1.3\namplitude = 0.3\n";

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_capture_exports_the_arrays_radbench_computed() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    std::fs::write(d.join("scene.toml"), SCENE).unwrap();
    let capture = [
        "capture",
        "--allow-rf",
        "--scene",
        "scene.toml",
        "--repetitions",
        "2",
        "--payload",
        "hello",
        "--out",
        "cap",
    ];
    let (code, _, err) = radbench(d, &capture).await;
    assert_eq!(code, 0, "{err}");
    let (code, stdout, err) = radbench(d, &["export", "cap", "--npz"]).await;
    assert_eq!(code, 0, "{err}");
    assert!(stdout.contains("cap.npz"), "{stdout}");
    let summary = json_file(&d.join("cap/summary.json"));
    let a = npz(&d.join("cap.npz"));

    // The decimated I/Q: both repetitions, one period at the waveform rate each.
    let period = summary["applied"]["segment"]["padded_samples"]
        .as_u64()
        .unwrap() as usize;
    let (dict, shape, _) = npy(&a["iq"]);
    assert!(dict.contains("'<c16'"), "{dict}");
    assert_eq!(shape, [2, period]);
    let rate = f64s(npy(&a["iq_rate_hz"]).2)[0];
    assert_eq!(
        rate,
        summary["transmission"]["sample_rate_hz"].as_f64().unwrap()
    );
    assert_eq!(npy(&a["iq_t0_s"]).1, [2]);

    // The detections are the summary's, to the bit.
    let targets = &a["targets"];
    assert_eq!(column(targets, "range_m"), ranges(&summary["targets"]));
    let levels: Vec<f64> = summary["targets"]
        .as_array()
        .unwrap()
        .iter()
        .map(|t| t["level_db"].as_f64().unwrap())
        .collect();
    assert_eq!(column(targets, "level_db"), levels);

    // The profile is profile.npy's, in linear units, with its phase.
    let table_file = std::fs::read(d.join("cap/profile.npy")).unwrap();
    let (_, table_shape, table) = npy(&table_file);
    let table = f64s(table);
    let width = table_shape[1];
    let range = f64s(npy(&a["range_m"]).2);
    let amplitude = f64s(npy(&a["profile_amplitude"]).2);
    assert_eq!(range.len(), table_shape[0]);
    for (k, (r, amp)) in range.iter().zip(&amplitude).enumerate() {
        assert_eq!(*r, table[k * width]);
        assert_eq!(20.0 * amp.max(1e-300).log10(), table[k * width + 1]);
    }
    let complex = f64s(npy(&a["profile"]).2);
    for (k, amp) in amplitude.iter().enumerate() {
        let norm = complex[2 * k].hypot(complex[2 * k + 1]);
        assert!((norm - amp).abs() <= 1e-12 * amp.max(1e-300), "{k}");
    }

    // What was sent.
    let bits = npy(&a["bits"]);
    assert!(bits.0.contains("'|u1'"));
    assert_eq!(
        bits.1,
        [summary["transmission"]["bits"].as_u64().unwrap() as usize]
    );
    assert_eq!(npy(&a["payload"]).2, b"hello");
    assert_eq!(
        npy(&a["reference"]).1,
        [summary["transmission"]["samples_per_repetition"]
            .as_u64()
            .unwrap() as usize]
    );

    // The metadata: the options and the summary's figures, as summary.json has them.
    let meta: Value = serde_json::from_str(&text(&a["metadata"])).unwrap();
    assert_eq!(meta["processing"], summary["processing"]);
    for key in [
        "targets",
        "width_3db_cm",
        "sidelobe_db",
        "snr_db",
        "payload",
    ] {
        assert_eq!(meta["summary"][key], summary[key], "{key}");
    }
    assert_eq!(meta["spread"], summary["spread"]);
    assert_eq!(meta["scene"], summary["scene"]);
    assert_eq!(meta["units"]["iq"], "V");
    assert_eq!(meta["units"]["range_m"], "m");

    // An existing file is kept unless --force.
    let before = std::fs::read(d.join("cap.npz")).unwrap();
    let (code, _, err) = radbench(d, &["export", "cap", "--npz"]).await;
    assert_eq!(code, 2, "{err}");
    assert!(
        err.contains("exists already") && err.contains("--force"),
        "{err}"
    );
    assert_eq!(std::fs::read(d.join("cap.npz")).unwrap(), before);
    let (code, _, err) = radbench(d, &["export", "cap", "--npz", "--force"]).await;
    assert_eq!(code, 0, "{err}");
    // The same capture gives the same bytes.
    assert_eq!(std::fs::read(d.join("cap.npz")).unwrap(), before);

    // HDF5, from the capture's .sigmf-meta, to a folder made for it.
    let (code, _, err) = radbench(
        d,
        &[
            "export",
            "cap/capture.sigmf-meta",
            "--hdf5",
            "--out",
            "exports/cap.h5",
        ],
    )
    .await;
    assert_eq!(code, 0, "{err}");
    let h5 = std::fs::read(d.join("exports/cap.h5")).unwrap();
    assert_eq!(&h5[..8], b"\x89HDF\r\n\x1a\n");
    // No temporary file is left behind.
    let names: Vec<String> = std::fs::read_dir(d.join("exports"))
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    assert_eq!(names, ["cap.h5"]);
}

/// `results.csv`'s rows, each as column -> text.
fn csv_rows(path: &Path) -> Vec<BTreeMap<String, String>> {
    let text = std::fs::read_to_string(path).unwrap();
    let mut lines = text.lines();
    let header: Vec<&str> = lines.next().unwrap().split(',').collect();
    lines
        .map(|l| {
            let cells: Vec<&str> = l.split(',').collect();
            assert_eq!(cells.len(), header.len(), "{l}");
            header
                .iter()
                .zip(cells)
                .map(|(h, c)| (h.to_string(), c.to_string()))
                .collect()
        })
        .collect()
}

fn manifest_hash(run: &Path, file: &str) -> Option<String> {
    let m = radbench::campaign::Manifest::load(run).unwrap();
    m.files
        .iter()
        .find(|f| f.path == Path::new(file))
        .map(|f| f.sha256.clone())
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_run_exports_each_step_in_its_group_and_results_csv_is_results_json_flat() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let spec = Path::new(env!("CARGO_MANIFEST_DIR")).join("examples/accuracy.toml");
    let (code, _, err) = radbench(
        d,
        &[
            "campaign",
            "run",
            spec.to_str().unwrap(),
            "--allow-rf",
            "--out",
            "run",
        ],
    )
    .await;
    assert_eq!(code, 0, "{err}");
    let run = d.join("run");
    let results = json_file(&run.join("results.json"));
    let steps = results["steps"].as_array().unwrap();

    // results.csv: listed in the manifest with its hash; one row per step (one pillar each),
    // every number as results.json holds it.
    let csv = std::fs::read(run.join("results.csv")).unwrap();
    assert_eq!(
        manifest_hash(&run, "results.csv").unwrap(),
        radbench::storage::sha256(&csv)
    );
    let rows = csv_rows(&run.join("results.csv"));
    assert_eq!(rows.len(), steps.len());
    for (row, step) in rows.iter().zip(steps) {
        let a = &step["algorithms"]["correlation"];
        let num = |k: &str| row[k].parse::<f64>().unwrap();
        assert_eq!(row["step"], step["index"].to_string());
        assert_eq!(row["algorithm"], "correlation");
        assert_eq!(num("range_m"), a["targets"][0]["range_m"].as_f64().unwrap());
        assert_eq!(num("error_m"), a["error_m"].as_f64().unwrap());
        assert_eq!(num("truth_error_m"), a["truth_error_m"].as_f64().unwrap());
        assert_eq!(
            num("nominal_m"),
            step["nominal"]["targets"][0]["range_m"].as_f64().unwrap()
        );
        assert_eq!(num("width_3db_cm"), a["width_3db_cm"].as_f64().unwrap());
        assert_eq!(num("sidelobe_db"), a["sidelobe_db"].as_f64().unwrap());
        assert_eq!(num("snr_db"), a["snr_db"].as_f64().unwrap());
        assert_eq!(num("ber"), a["payload"]["ber"].as_f64().unwrap());
        assert_eq!(row["missed"], "false");
    }

    // The export: a group per step, each step's detections those of results.json.
    let (code, _, err) = radbench(d, &["export", "run", "--npz"]).await;
    assert_eq!(code, 0, "{err}");
    let a = npz(&d.join("run.npz"));
    for step in steps {
        let group = format!("step-{:03}", step["index"].as_u64().unwrap());
        let t = &a[&format!("{group}/targets")];
        assert_eq!(
            column(t, "range_m"),
            ranges(&step["algorithms"]["correlation"]["targets"]),
            "{group}"
        );
        assert_eq!(npy(&a[&format!("{group}/iq")]).1[0], 1);
    }
    let meta: Value = serde_json::from_str(&text(&a["metadata"])).unwrap();
    assert_eq!(meta["steps"].as_array().unwrap().len(), steps.len());
    assert_eq!(meta["results"], results);
    assert_eq!(meta["run"]["name"], "accuracy");
    let (code, _, err) = radbench(d, &["export", "run", "--hdf5"]).await;
    assert_eq!(code, 0, "{err}");
    assert!(d.join("run.h5").is_file());
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn bad_inputs_and_outputs_are_refused_with_the_documented_exit_codes() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let (code, _, err) = radbench(d, &["capture", "--allow-rf", "--out", "cap"]).await;
    assert_eq!(code, 0, "{err}");
    std::fs::create_dir(d.join("empty")).unwrap();
    std::fs::write(d.join("notes.txt"), "not a capture").unwrap();
    let (code, _, err) = radbench(d, &["process", "cap", "--out", "again"]).await;
    assert_eq!(code, 0, "{err}");
    // Exit 2: what is not a capture nor a run folder, with what to give instead.
    for (args, says) in [
        (
            &["export", "nowhere", "--npz"][..],
            "no such file or folder",
        ),
        (
            &["export", "empty", "--npz"],
            "neither a capture nor a run folder",
        ),
        (
            &["export", "notes.txt", "--hdf5"],
            "neither a capture nor a run folder",
        ),
        (
            &["export", "cap/C1.trc", "--npz"],
            "give the capture folder",
        ),
        (&["export", "again/cap", "--npz"], "radbench process"),
        (&["export", "cap"], "--npz|--hdf5"),
        (&["export", "cap", "--npz", "--hdf5"], "cannot be used with"),
        (&["export", "cap", "--npz", "--out", "empty"], "is a folder"),
    ] {
        let (code, _, err) = radbench(d, args).await;
        assert_eq!(code, 2, "{args:?}: {err}");
        assert!(err.contains(says), "{args:?}: {err}");
        assert!(!err.contains("panicked"), "{err}");
    }
    // A truncated recording (its SHA-512 no longer the metadata's): bad input, not a panic.
    std::fs::create_dir(d.join("cut")).unwrap();
    std::fs::copy(
        d.join("cap/capture.sigmf-meta"),
        d.join("cut/capture.sigmf-meta"),
    )
    .unwrap();
    let data = std::fs::read(d.join("cap/capture.sigmf-data")).unwrap();
    let cut = data.len() / 3 / 4 * 4;
    std::fs::write(d.join("cut/capture.sigmf-data"), &data[..cut]).unwrap();
    let (code, _, err) = radbench(d, &["export", "cut", "--npz"]).await;
    assert_eq!(code, 2, "{err}");
    assert!(err.contains("cut/capture.sigmf-data"), "{err}");
    assert!(!d.join("cut.npz").exists());
    // Exit 4: an output that cannot be written (its folder is a file), nothing left behind.
    let (code, _, err) = radbench(d, &["export", "cap", "--npz", "--out", "notes.txt/x.npz"]).await;
    assert_eq!(code, 4, "{err}");
    assert!(err.contains("cannot write"), "{err}");
    // Nothing was written anywhere by the refusals (the run catalog beside `cap` is its capture's
    // registration).
    let mut left: Vec<String> = std::fs::read_dir(d)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .filter(|n| !n.starts_with("catalog.sqlite"))
        .collect();
    left.sort();
    assert_eq!(left, ["again", "cap", "cut", "empty", "notes.txt"]);
}

/// A run folder as radbench wrote it before results.csv: the file and its manifest record gone.
fn as_before_results_csv(run: &Path) {
    let mut m = radbench::campaign::Manifest::load(run).unwrap();
    m.files.retain(|f| f.path != Path::new("results.csv"));
    m.store(run).unwrap();
    std::fs::remove_file(run.join("results.csv")).unwrap();
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_run_folder_from_before_results_csv_resumes_and_reports_with_one() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    // The stage jams once at step 2; the resume finds it working.
    let jam = d.join("jammed-once");
    let spec = format!(
        "[positioner]\nkind = \"command\"\nprogram = \"sh\"\n\
         args = [\"-c\", \"test {{step}} -lt 2 || test -e {jam} || {{ touch {jam}; exit 7; }}\"]\n\
         timeout_s = 20\n[sweep]\nparameter = \"position\"\nvalues = [1.0, 0.97, 0.94]\n",
        jam = jam.display()
    );
    std::fs::write(d.join("spec.toml"), spec).unwrap();
    let (code, _, err) = radbench(
        d,
        &["campaign", "run", "spec.toml", "--allow-rf", "--out", "run"],
    )
    .await;
    assert_eq!(code, 3, "{err}");
    let run = d.join("run");
    as_before_results_csv(&run);
    let (code, _, err) = radbench(d, &["campaign", "resume", "run", "--allow-rf"]).await;
    assert_eq!(code, 0, "{err}");
    let rows = csv_rows(&run.join("results.csv"));
    assert_eq!(rows.len(), 3);
    assert_eq!(
        manifest_hash(&run, "results.csv").unwrap(),
        radbench::storage::sha256(&std::fs::read(run.join("results.csv")).unwrap())
    );

    // `campaign report` writes it for a complete run that lacks it, and records it.
    as_before_results_csv(&run);
    let (code, _, err) = radbench(d, &["campaign", "report", "run"]).await;
    assert_eq!(code, 0, "{err}");
    let csv = std::fs::read(run.join("results.csv")).unwrap();
    assert_eq!(
        manifest_hash(&run, "results.csv").unwrap(),
        radbench::storage::sha256(&csv)
    );
    assert_eq!(csv_rows(&run.join("results.csv")), rows);

    // An edited results.json rendered with --force: results.csv follows it, hash recorded.
    let text = std::fs::read_to_string(run.join("results.json")).unwrap();
    let edited = text.replacen("\"snr_db\": ", "\"snr_db\": 1.5e1, \"was_snr_db\": ", 1);
    assert_ne!(edited, text);
    std::fs::write(run.join("results.json"), &edited).unwrap();
    let (code, _, err) = radbench(d, &["campaign", "report", "run"]).await;
    assert_eq!(code, 2, "{err}");
    let (code, _, err) = radbench(d, &["campaign", "report", "run", "--force"]).await;
    assert_eq!(code, 0, "{err}");
    assert!(err.contains("results.csv"), "{err}");
    let rows = csv_rows(&run.join("results.csv"));
    assert_eq!(rows[0]["snr_db"], "15");
    assert_eq!(
        manifest_hash(&run, "results.csv").unwrap(),
        radbench::storage::sha256(&std::fs::read(run.join("results.csv")).unwrap())
    );
}

/// `--dtype complex64`: every complex array `<c8` (its header says so), half its complex128
/// bytes, each value the complex128 one within float32 precision; real arrays unchanged; the
/// whole file smaller by the complex arrays' half. A bad value names `--dtype` and the allowed
/// ones (exit 2).
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn complex64_halves_the_complex_arrays_within_f32_precision() {
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
            "--out",
            "cap",
        ],
    )
    .await;
    assert_eq!(code, 0, "{err}");
    for (dtype, out) in [("complex128", "c16.npz"), ("complex64", "c8.npz")] {
        let (code, _, err) = radbench(
            d,
            &["export", "cap", "--npz", "--dtype", dtype, "--out", out],
        )
        .await;
        assert_eq!(code, 0, "{err}");
    }
    let (code, _, err) = radbench(d, &["export", "cap", "--npz", "--out", "default.npz"]).await;
    assert_eq!(code, 0, "{err}");
    let wide = npz(&d.join("c16.npz"));
    let narrow = npz(&d.join("c8.npz"));
    assert_eq!(
        npz(&d.join("default.npz")),
        wide,
        "complex128 is the default"
    );
    assert_eq!(
        wide.keys().collect::<Vec<_>>(),
        narrow.keys().collect::<Vec<_>>()
    );
    let (mut complex_wide, mut complex_narrow) = (0usize, 0usize);
    for (name, w) in &wide {
        let (wd, ws, wdata) = npy(w);
        let (nd, ns, ndata) = npy(&narrow[name]);
        assert_eq!(ws, ns, "{name}");
        if !wd.contains("'<c16'") {
            assert_eq!(w, &narrow[name], "{name}: not complex, unchanged");
            continue;
        }
        assert!(nd.contains("'descr': '<c8'"), "{name}: {nd}");
        assert_eq!(ndata.len() * 2, wdata.len(), "{name}: half the bytes");
        complex_wide += wdata.len();
        complex_narrow += ndata.len();
        let parts64 = f64s(wdata);
        let parts32: Vec<f64> = ndata
            .chunks_exact(4)
            .map(|c| f32::from_le_bytes(c.try_into().unwrap()) as f64)
            .collect();
        assert_eq!(parts64.len(), parts32.len());
        for (a, b) in parts64.iter().zip(&parts32) {
            assert!(
                (a - b).abs() <= a.abs() * f64::from(f32::EPSILON),
                "{name}: {a} vs {b}"
            );
        }
    }
    assert!(complex_wide > 1_000_000, "the I/Q is exported");
    assert_eq!(complex_narrow * 2, complex_wide);
    let size = |f: &str| std::fs::metadata(d.join(f)).unwrap().len() as usize;
    assert_eq!(
        size("c16.npz") - size("c8.npz"),
        complex_wide - complex_narrow,
        "the file shrinks by the complex arrays' half, nothing else changes"
    );
    let (code, _, err) = radbench(d, &["export", "cap", "--npz", "--dtype", "float16"]).await;
    assert_eq!(code, 2, "{err}");
    assert!(
        err.contains("--dtype") && err.contains("complex64") && err.contains("complex128"),
        "{err}"
    );
}
