//! Build script: the instrument catalog's files, and the git commit radbench is built from.
//!
//! Every `instruments/*.toml` is compiled in (`$OUT_DIR/embedded_catalog.rs`, included by
//! `src/catalog/mod.rs`): adding an instrument file adds a built-in model, with no list to edit.
//!
//! The commit is for the run manifests of campaigns (`RADBENCH_GIT_COMMIT`; absent outside a git
//! checkout). A value already in the environment (a packager's) wins.
//!
//! Cargo reruns this script (and so recompiles radbench) when a file named with
//! `rerun-if-changed` is newer than the last run, **or missing**. So only paths that exist are
//! named, and only those that change when HEAD moves:
//!
//! * `HEAD` itself (a checkout, or a commit on a detached HEAD);
//! * the branch's loose ref file when there is one (a commit on the branch renames a new one
//!   into place);
//! * otherwise the branch lives in `packed-refs` (after `git pack-refs`, or in some clones):
//!   that file, and the folder the loose ref would be created in, since the next commit on the
//!   branch writes a loose ref beside the packed one and leaves `packed-refs` as it was;
//! * with the reftable backend, its `tables.list`, which every ref update rewrites.
//!
//! Naming `packed-refs` unconditionally made every build in a checkout without it (a
//! repository that never packed its refs) recompile radbench.

use std::path::{Path, PathBuf};
use std::process::Command;

fn git(args: &[&str]) -> Option<String> {
    let out = Command::new("git").args(args).output().ok()?;
    out.status
        .success()
        .then(|| String::from_utf8_lossy(&out.stdout).trim().to_string())
        .filter(|s| !s.is_empty())
}

/// The path git uses for `name` inside the repository (worktree-aware), relative to here.
fn git_path(name: &str) -> Option<PathBuf> {
    git(&["rev-parse", "--git-path", name]).map(PathBuf::from)
}

fn watch(path: &Path) {
    println!("cargo:rerun-if-changed={}", path.display());
}

/// Names `path` when it exists; says whether it did.
fn watch_if_exists(path: &Path) -> bool {
    let exists = path.exists();
    if exists {
        watch(path);
    }
    exists
}

/// Writes `$OUT_DIR/embedded_catalog.rs`: the `(file name, text)` of every `instruments/*.toml`.
///
/// The folder is found from the manifest directory cargo passes at *run* time: a build script
/// compiled in another checkout (a worktree sharing this target folder; cargo reuses the compiled
/// script when its source is the same) would otherwise read that checkout's folder, or none, and
/// build a radbench with an empty catalog. An unreadable or empty folder stops the build.
fn embed_catalog() {
    let manifest = std::env::var_os("CARGO_MANIFEST_DIR").expect("cargo sets CARGO_MANIFEST_DIR");
    let dir = Path::new(&manifest).join("instruments");
    watch(&dir);
    let listing = std::fs::read_dir(&dir).unwrap_or_else(|e| {
        panic!(
            "the instrument catalog {} cannot be read: {e}",
            dir.display()
        )
    });
    let mut names: Vec<String> = listing
        .filter_map(Result::ok)
        .map(|e| e.path())
        .filter(|p| p.is_file() && p.extension().is_some_and(|e| e == "toml"))
        .filter_map(|p| p.file_name().map(|n| n.to_string_lossy().into_owned()))
        .collect();
    assert!(
        !names.is_empty(),
        "the instrument catalog {} holds no .toml file",
        dir.display()
    );
    // The four files built in before this list was generated keep their order (listings and
    // error messages name the models in it); every other file follows, sorted by name.
    const FIRST: [&str; 4] = [
        "keysight_m8195a.toml",
        "lecroy_labmaster10zi_a.toml",
        "gotmic_eband_tx.toml",
        "gotmic_eband_rx.toml",
    ];
    names.sort_by_key(|n| {
        (
            FIRST.iter().position(|f| f == n).unwrap_or(FIRST.len()),
            n.clone(),
        )
    });
    let mut out = String::from("&[\n");
    for name in &names {
        let path = dir.join(name);
        watch(&path);
        out.push_str(&format!(
            "    ({name:?}, include_str!({:?})),\n",
            path.display().to_string()
        ));
    }
    out.push_str("]\n");
    let target = PathBuf::from(std::env::var_os("OUT_DIR").expect("cargo sets OUT_DIR"))
        .join("embedded_catalog.rs");
    std::fs::write(target, out).expect("OUT_DIR is writable");
}

fn main() {
    embed_catalog();
    println!("cargo:rerun-if-env-changed=RADBENCH_GIT_COMMIT");
    if std::env::var_os("RADBENCH_GIT_COMMIT").is_some() {
        return;
    }
    let Some(commit) = git(&["rev-parse", "HEAD"]) else {
        // Not a git checkout (a source archive), or no commit yet: nothing to record. When
        // HEAD exists (an unborn branch), its first commit must still be noticed.
        if let Some(head) = git_path("HEAD") {
            watch_if_exists(&head);
        }
        if let Some(parent) = git(&["symbolic-ref", "-q", "HEAD"])
            .and_then(|branch| git_path(&branch))
            .and_then(|loose| existing_ancestor(&loose))
        {
            watch(&parent);
        }
        return;
    };
    if let Some(head) = git_path("HEAD") {
        watch_if_exists(&head);
    }
    if let Some(tables) = git_path("reftable/tables.list") {
        watch_if_exists(&tables);
    }
    if let Some(branch) = git(&["symbolic-ref", "-q", "HEAD"]) {
        if let Some(loose) = git_path(&branch) {
            if !watch_if_exists(&loose) {
                if let Some(packed) = git_path("packed-refs") {
                    watch_if_exists(&packed);
                }
                if let Some(parent) = existing_ancestor(&loose) {
                    watch(&parent);
                }
            }
        }
    }
    println!("cargo:rustc-env=RADBENCH_GIT_COMMIT={commit}");
}

/// The nearest folder above `path` that exists (where a loose ref for it would be created).
fn existing_ancestor(path: &Path) -> Option<PathBuf> {
    path.ancestors()
        .skip(1)
        .find(|p| !p.as_os_str().is_empty() && p.is_dir())
        .map(Path::to_path_buf)
}
