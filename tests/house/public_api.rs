//! No public item that nothing outside its crate uses (issue "the house", must hold).
//!
//! `#![warn(unreachable_pub)]` already makes every `pub` item reachable from the crate root; this
//! test checks the other half: that something outside the crate needs it. It parses each crate
//! from `lib.rs` along its `mod` declarations (test modules skipped) and lists its `pub` items:
//! free items and the `pub` functions of inherent impls. An item counts as used when its name is
//! written outside the crate (the binary with its `cli` and `live`, tests, benchmarks, examples, doc examples, the other
//! crate of the workspace), or when it appears in the signature of an item that is used (a field
//! type, an argument, a return type, a variant's payload, a trait's methods). The names are
//! compared as words, so a method called `new` is always "used": the check is a floor, not proof.
//!
//! An item that fails here either becomes `pub(crate)` (or private), or is removed if nothing at
//! all uses it.

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};

use super::layers::sources;
use quote::ToTokens;
use syn::{Attribute, Fields, ImplItem, Item, Visibility};

fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

/// One `pub` item: where it is, and the names its signature mentions.
struct PublicItem {
    name: String,
    place: String,
    signature: BTreeSet<String>,
}

fn is_cfg_test(attrs: &[Attribute]) -> bool {
    attrs
        .iter()
        .any(|a| a.path().is_ident("cfg") && a.meta.to_token_stream().to_string().contains("test"))
}

fn words(text: &str) -> impl Iterator<Item = &str> {
    text.split(|c: char| !(c.is_alphanumeric() || c == '_'))
        .filter(|w| !w.is_empty() && !w.starts_with(|c: char| c.is_ascii_digit()))
}

fn names_in(tokens: &impl ToTokens) -> BTreeSet<String> {
    let text = tokens.to_token_stream().to_string();
    words(&text).map(str::to_owned).collect()
}

fn public_fields(fields: &Fields) -> BTreeSet<String> {
    fields
        .iter()
        .filter(|f| matches!(f.vis, Visibility::Public(_)))
        .flat_map(|f| names_in(&f.ty))
        .collect()
}

/// Walks a module's items; `dir` is where its `mod x;` children live.
fn walk(items: &[Item], file: &Path, dir: &Path, place: &str, out: &mut Vec<PublicItem>) {
    let mut push = |name: String, signature: BTreeSet<String>| {
        out.push(PublicItem {
            name,
            place: format!("{place} ({})", file.display()),
            signature,
        })
    };
    // (items written inline, or None for `mod x;`), the folder of its children, its place
    let mut children: Vec<(Option<&[Item]>, PathBuf, String)> = Vec::new();
    for item in items {
        let public = |vis: &Visibility| matches!(vis, Visibility::Public(_));
        match item {
            Item::Fn(f) if public(&f.vis) => push(f.sig.ident.to_string(), names_in(&f.sig)),
            Item::Struct(s) if public(&s.vis) => {
                let mut sig = public_fields(&s.fields);
                sig.extend(names_in(&s.generics));
                push(s.ident.to_string(), sig);
            }
            Item::Enum(e) if public(&e.vis) => {
                let mut sig: BTreeSet<String> = e
                    .variants
                    .iter()
                    .flat_map(|v| names_in(&v.fields))
                    .collect();
                sig.extend(names_in(&e.generics));
                push(e.ident.to_string(), sig);
            }
            Item::Trait(t) if public(&t.vis) => push(t.ident.to_string(), names_in(t)),
            Item::Type(t) if public(&t.vis) => push(t.ident.to_string(), names_in(&t.ty)),
            Item::Const(c) if public(&c.vis) => push(c.ident.to_string(), names_in(&c.ty)),
            Item::Static(s) if public(&s.vis) => push(s.ident.to_string(), names_in(&s.ty)),
            Item::Impl(imp) if !is_cfg_test(&imp.attrs) => {
                let self_names = names_in(&imp.self_ty);
                for inner in &imp.items {
                    if let ImplItem::Fn(f) = inner {
                        let listed = imp.trait_.is_none() && public(&f.vis);
                        if listed && !is_cfg_test(&f.attrs) {
                            push(f.sig.ident.to_string(), names_in(&f.sig));
                        }
                    }
                }
                // A trait implemented for a type shows its associated types and arguments through
                // that type: count them under the type's name.
                if imp.trait_.is_some() {
                    for name in self_names.iter().take(1) {
                        push(format!("{name} (trait impl)"), names_in(imp));
                    }
                }
            }
            Item::Mod(m) if !is_cfg_test(&m.attrs) => {
                let name = m.ident.to_string();
                let here = format!("{place}::{name}");
                let inline = m.content.as_ref().map(|(_, inner)| inner.as_slice());
                children.push((inline, dir.join(&name), here));
            }
            _ => {}
        }
    }
    for (inline, child_dir, here) in children {
        if let Some(inner) = inline {
            walk(inner, file, &child_dir, &here, out);
            continue;
        }
        let file = if child_dir.with_extension("rs").is_file() {
            child_dir.with_extension("rs")
        } else {
            child_dir.join("mod.rs")
        };
        walk(&parse(&file).items, &file, &child_dir, &here, out);
    }
}

fn parse(file: &Path) -> syn::File {
    let text = std::fs::read_to_string(file).unwrap_or_else(|e| panic!("{}: {e}", file.display()));
    syn::parse_file(&text).unwrap_or_else(|e| panic!("{}: {e}", file.display()))
}

/// The words of Rust code in doc comments (fenced blocks not marked `text`): doc examples are
/// compiled outside the crate.
fn doc_example_words(text: &str, into: &mut BTreeSet<String>) {
    // None outside a fence; Some(true) inside a Rust one.
    let mut fence: Option<bool> = None;
    for line in text.lines() {
        let trimmed = line.trim_start();
        let Some(doc) = trimmed
            .strip_prefix("///")
            .or_else(|| trimmed.strip_prefix("//!"))
        else {
            fence = None;
            continue;
        };
        let doc = doc.trim();
        if let Some(lang) = doc.strip_prefix("```") {
            fence = match fence {
                Some(_) => None,
                None => Some(!lang.starts_with("text")),
            };
            continue;
        }
        if fence == Some(true) {
            into.extend(words(doc).map(str::to_owned));
        }
    }
}

/// Every word written in these files (code outside the crate).
fn words_of(files: &[PathBuf], into: &mut BTreeSet<String>) {
    for file in files {
        let text = std::fs::read_to_string(file).unwrap();
        into.extend(words(&text).map(str::to_owned));
    }
}

/// The `pub` items of the crate at `lib` that neither `outside` nor a used signature names.
fn unused_public_items(lib: &Path, outside_dirs: &[PathBuf]) -> Vec<String> {
    let src = lib.parent().unwrap();
    let mut items = Vec::new();
    walk(&parse(lib).items, lib, src, "crate", &mut items);

    let mut outside = Vec::new();
    for dir in outside_dirs {
        sources(dir, &mut outside);
    }
    let mut used = BTreeSet::new();
    words_of(&outside, &mut used);
    let mut inside = Vec::new();
    sources(src, &mut inside);
    for file in &inside {
        doc_example_words(&std::fs::read_to_string(file).unwrap(), &mut used);
    }

    // Reachable through signatures: grow the used names until nothing new comes in.
    let mut reached = vec![false; items.len()];
    loop {
        let mut grew = false;
        for (i, item) in items.iter().enumerate() {
            let name = item.name.split(' ').next().unwrap();
            if !reached[i] && used.contains(name) {
                reached[i] = true;
                let before = used.len();
                used.extend(item.signature.iter().cloned());
                grew |= used.len() > before;
            }
        }
        if !grew {
            break;
        }
    }
    let mut unused: BTreeMap<String, String> = BTreeMap::new();
    for (item, reached) in items.iter().zip(reached) {
        if !reached && !item.name.ends_with("(trait impl)") {
            unused.insert(format!("{} {}", item.name, item.place), String::new());
        }
    }
    unused.into_keys().collect()
}

fn assert_all_used(crate_name: &str, unused: &[String]) {
    assert!(
        unused.is_empty(),
        "{} pub item(s) of {crate_name} that nothing outside the crate names or reaches; make them \
         pub(crate) or remove them:\n  {}",
        unused.len(),
        unused.join("\n  ")
    );
}

#[test]
fn every_public_item_of_radbench_is_used_outside_it() {
    let root = root();
    // python/src: the Python package's extension module (its own workspace) calls radbench;
    // src/bin/radbench: the binary (`main.rs`, `cli/`, `live/`).
    let outside = [
        "src/bin/radbench",
        "tests",
        "benches",
        "examples",
        "python/src",
    ]
    .map(|p| root.join(p));
    let unused = unused_public_items(&root.join("src/lib.rs"), &outside);
    assert_all_used("radbench", &unused);
}

#[test]
fn every_public_item_of_mock_lab_is_used_outside_it() {
    let root = root();
    let outside = [
        "mock_lab/src/main.rs",
        "mock_lab/tests",
        "mock_lab/benches",
        "mock_lab/examples",
        "src",
        "tests",
        "benches",
        "examples",
    ]
    .map(|p| root.join(p));
    let unused = unused_public_items(&root.join("mock_lab/src/lib.rs"), &outside);
    assert_all_used("mock_lab", &unused);
}

/// Each layer names what it re-exports (issue 42: "0 glob re-exports in the library's layers"):
/// a `mod.rs` is the list of what its layer offers, and a new `pub` item is offered by adding
/// its name there, not by the file it lives in. Glob imports for a file's own use (`use x::*`,
/// e.g. `use super::*` in unit tests) are not re-exports and stay allowed.
#[test]
fn no_layer_re_exports_by_glob() {
    let mut files = Vec::new();
    sources(&root().join("src"), &mut files);
    let mut globs = Vec::new();
    for file in &files {
        let text = std::fs::read_to_string(file).unwrap();
        for (n, line) in text.lines().enumerate() {
            let line = line.trim_start();
            if line.starts_with("pub") && line.contains(" use ") && line.ends_with("::*;") {
                globs.push(format!("{}:{}: {line}", file.display(), n + 1));
            }
        }
    }
    assert!(
        globs.is_empty(),
        "re-export these by name (pub use x::{{A, b}}):\n{}",
        globs.join("\n")
    );
}
