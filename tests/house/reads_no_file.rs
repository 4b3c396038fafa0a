//! Processing reads no file (issue 42): the pipeline, the transmission it is built on (its
//! pre-distortion included) and the signal code get everything handed to them, the response
//! calibration loaded once where a command resolves its options. A source scan: none of their
//! code (comments and unit tests aside) names the file system, a path or a loader. Their one
//! disk access is the prepared-pieces cache (`storage::cache`: best effort, `RADBENCH_CACHE=off`
//! turns it off), reached through that module only.

use std::path::{Path, PathBuf};

use super::circles::code;
use super::layers::sources;

/// What reading a file takes (a path, the file system, a loader), written in code.
const FORBIDDEN: &[&str] = &[
    "std::fs",
    "fs::",
    "File::",
    "OpenOptions",
    "Path",
    "read_to_string",
    "Calibration::load",
    "load_used",
    "load_recorded",
    "std::env",
];

/// The files of the processing: the pipeline, the transmission and every file of `dsp/`.
fn processing_files(root: &Path) -> Vec<PathBuf> {
    let mut files = vec![
        root.join("src/measure/processing/pipeline.rs"),
        root.join("src/measure/processing/transmit.rs"),
    ];
    sources(&root.join("src/dsp"), &mut files);
    files
}

#[test]
fn processing_names_no_file_system_path_or_loader() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let mut found = Vec::new();
    for file in processing_files(root) {
        let text = std::fs::read_to_string(&file).unwrap();
        for (n, line) in code(&text).lines().enumerate() {
            let storage_other_than_cache = line
                .match_indices("storage::")
                .any(|(i, _)| !line[i..].starts_with("storage::cache"));
            let named = FORBIDDEN.iter().find(|w| line.contains(*w));
            if named.is_some() || storage_other_than_cache {
                let rel = file.strip_prefix(root).unwrap().display();
                found.push(format!("{rel}:{}: {}", n + 1, line.trim()));
            }
        }
    }
    assert!(
        found.is_empty(),
        "processing reads no file (hand it what it needs where the command resolves its \
         options):\n{}",
        found.join("\n")
    );
}
