//! The layer map of `src/lib.rs` is true: every module imports only the layers below it (the
//! table here is the crate docs' table), and mock_lab depends on nothing of radbench.

use std::collections::BTreeSet;
use std::path::{Path, PathBuf};

/// Module -> the modules it may import. Keep in step with the crate docs in src/lib.rs.
const ALLOWED: &[(&str, &[&str])] = &[
    ("exit", &[]),
    ("physics", &[]),
    ("rng", &[]),
    ("time", &[]),
    ("address", &["exit"]),
    ("trc", &["exit", "rng"]),
    ("transport", &["address", "exit", "time"]),
    ("session", &["address", "exit", "transport", "time"]),
    ("catalog", &["exit"]),
    (
        "driver",
        &[
            "address",
            "catalog",
            "exit",
            "rng",
            "session",
            "transport",
            "time",
            "trc",
        ],
    ),
    ("dsp", &["exit", "physics", "rng"]),
    // The OFDM numerology is checked once, in dsp (`dsp::ofdm_radar::Numerology`); dsp never
    // imports waveform.
    ("waveform", &["dsp", "exit", "physics", "rng"]),
    ("storage", &["exit", "physics", "time", "trc"]),
    (
        "measure",
        &[
            "address", "catalog", "driver", "dsp", "exit", "physics", "storage", "time", "trc",
            "waveform",
        ],
    ),
    (
        "simulate",
        &[
            "dsp", "exit", "measure", "physics", "rng", "storage", "waveform",
        ],
    ),
    // The live view's server (the binary's, `src/bin/radbench/live`): handed everything it shows
    // and does by the CLI.
    ("bin/radbench/live", &[]),
    (
        "campaign",
        &[
            "catalog", "driver", "dsp", "exit", "measure", "physics", "storage", "time", "waveform",
        ],
    ),
    // The in-memory API (the Python package's entry) and the options `radbench process` shares;
    // its warm bench session holds a connected bench as a campaign does (catalog, driver).
    (
        "in_memory",
        &[
            "campaign", "catalog", "driver", "exit", "measure", "simulate", "storage", "waveform",
        ],
    ),
    // The run catalog (SQLite): reads run folders (campaign) and capture folders.
    ("runs_db", &["campaign", "exit", "storage", "time"]),
    // Archive processing over the catalog: the in-memory API's per-capture work, the catalog's
    // queries, content-addressed output folders.
    (
        "archive",
        &["exit", "in_memory", "measure", "runs_db", "storage"],
    ),
    // From an error chain to its exit class: names every layer's error type.
    (
        "classify",
        &[
            "address",
            "campaign",
            "catalog",
            "driver",
            "dsp",
            "exit",
            "measure",
            "runs_db",
            "session",
            "simulate",
            "storage",
            "transport",
            "waveform",
        ],
    ),
];

/// Every `.rs` file under `path` (or `path` itself).
pub(crate) fn sources(path: &Path, out: &mut Vec<PathBuf>) {
    if path.is_dir() {
        for entry in std::fs::read_dir(path).unwrap() {
            sources(&entry.unwrap().path(), out);
        }
    } else if path.extension().is_some_and(|e| e == "rs") {
        out.push(path.to_path_buf());
    }
}

/// The top-level modules a file names as `crate::x` (single and grouped imports, paths in code),
/// comments excluded.
fn imports(text: &str) -> BTreeSet<String> {
    let mut found = BTreeSet::new();
    for line in text.lines() {
        let code = line.split("//").next().unwrap_or("");
        let mut rest = code;
        while let Some(i) = rest.find("crate::") {
            rest = &rest[i + "crate::".len()..];
            if let Some(group) = rest.strip_prefix('{') {
                for item in group.split(['}', ',']) {
                    let name: String = item
                        .trim()
                        .chars()
                        .take_while(|c| c.is_alphanumeric() || *c == '_')
                        .collect();
                    if !name.is_empty() {
                        found.insert(name);
                    }
                }
            } else {
                let name: String = rest
                    .chars()
                    .take_while(|c| c.is_alphanumeric() || *c == '_')
                    .collect();
                found.insert(name);
            }
        }
    }
    found
}

#[test]
fn every_module_imports_only_the_layers_below_it() {
    let src = Path::new(env!("CARGO_MANIFEST_DIR")).join("src");
    let mut violations = Vec::new();
    for (module, allowed) in ALLOWED {
        let dir = src.join(module);
        let file = src.join(format!("{module}.rs"));
        let mut files = Vec::new();
        if dir.is_dir() {
            sources(&dir, &mut files);
        }
        if file.is_file() {
            files.push(file);
        }
        for f in files {
            let text = std::fs::read_to_string(&f).unwrap();
            for used in imports(&text) {
                if used != *module && !allowed.contains(&used.as_str()) {
                    violations.push(format!(
                        "{} imports crate::{used}, above or beside the {module} layer",
                        f.strip_prefix(&src).unwrap().display()
                    ));
                }
            }
        }
    }
    assert!(violations.is_empty(), "{}", violations.join("\n"));
}

#[test]
fn every_module_of_the_crate_is_in_the_layer_table() {
    let lib =
        std::fs::read_to_string(Path::new(env!("CARGO_MANIFEST_DIR")).join("src/lib.rs")).unwrap();
    let declared: Vec<&str> = lib
        .lines()
        .filter_map(|l| l.trim().strip_prefix("pub mod "))
        .map(|l| l.trim_end_matches(';'))
        .collect();
    for m in declared {
        assert!(
            ALLOWED.iter().any(|(name, _)| *name == m),
            "src/lib.rs declares `{m}` but tests/house/layers.rs does not place it in a layer"
        );
    }
}

#[test]
fn the_checker_sees_grouped_and_inline_imports() {
    let found =
        imports("use crate::{dsp::C0, waveform};\nlet x = crate::storage::f(); // crate::cli");
    assert_eq!(
        found.into_iter().collect::<Vec<_>>(),
        ["dsp", "storage", "waveform"]
    );
}

#[test]
fn mock_lab_depends_on_nothing_of_radbench() {
    let manifest =
        std::fs::read_to_string(Path::new(env!("CARGO_MANIFEST_DIR")).join("mock_lab/Cargo.toml"))
            .unwrap();
    assert!(
        !manifest.contains("radbench"),
        "mock_lab must stay independent of radbench (two implementations check each other)"
    );
}

#[test]
fn campaigns_name_no_mock_lab_path() {
    // The simulated bench is reached through the bench's typed scene control
    // (`measure::scene_control`): campaigns send no control JSON and name no mock_lab type.
    let mut files = Vec::new();
    sources(
        &Path::new(env!("CARGO_MANIFEST_DIR")).join("src/campaign"),
        &mut files,
    );
    let mut found = Vec::new();
    for f in files {
        let text = std::fs::read_to_string(&f).unwrap();
        for (i, line) in text.lines().enumerate() {
            let code = line.split("//").next().unwrap_or("");
            if code.contains("mock_lab::") || code.contains("\"cmd\"") {
                found.push(format!("{}:{}: {}", f.display(), i + 1, line.trim()));
            }
        }
    }
    assert!(found.is_empty(), "{}", found.join("\n"));
}

/// The library files that may name mock_lab: the built-in bench (started in-process, its scene
/// behind the typed seam, its offline scope for simulated captures) and the errors it returns.
/// The binary (`src/bin/radbench/`) is not the library and may use it; so may tests.
const MOCK_LAB_USERS: [&str; 6] = [
    "src/measure/bench/in_use.rs",
    "src/measure/bench/scene_control.rs",
    "src/measure/bench/scene_capture.rs",
    "src/measure/error.rs",
    "src/measure/calibration/predistortion_tests.rs",
    "src/simulate/scene_bench.rs",
];

#[test]
fn only_the_built_in_bench_names_mock_lab() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let mut files = Vec::new();
    sources(&root.join("src"), &mut files);
    let mut found = Vec::new();
    for f in files {
        let rel = f
            .strip_prefix(root)
            .unwrap()
            .to_string_lossy()
            .replace('\\', "/");
        if rel.starts_with("src/bin/radbench/") || MOCK_LAB_USERS.contains(&rel.as_str()) {
            continue;
        }
        let text = std::fs::read_to_string(&f).unwrap();
        for (i, line) in text.lines().enumerate() {
            let code = line.split("//").next().unwrap_or("");
            if code.contains("mock_lab::") || code.contains("use mock_lab") {
                found.push(format!("{rel}:{}: {}", i + 1, line.trim()));
            }
        }
    }
    assert!(
        found.is_empty(),
        "only the built-in bench may use mock_lab ({MOCK_LAB_USERS:?}); found:\n{}",
        found.join("\n")
    );
}

#[test]
fn the_mock_lab_users_exist() {
    // A file renamed away from the list would silently widen nothing but rot the list.
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    for f in MOCK_LAB_USERS {
        assert!(
            root.join(f).is_file(),
            "{f} is listed in MOCK_LAB_USERS but does not exist"
        );
    }
}
