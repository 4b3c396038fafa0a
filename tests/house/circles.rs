//! No two modules (files) import each other: first in the dsp and waveform layers (issue 25,
//! "the four small import circles": a child that needed its parent's types now gets them from a
//! sibling file, and the parent only re-exports), now everywhere (issue 42). Paths in comments and in `#[cfg(test)] mod tests` do not
//! count.

use std::collections::BTreeSet;
use std::path::Path;

use super::layers::sources;

type Module = Vec<String>;

fn module_of(src: &Path, file: &Path) -> Module {
    let rel = file.strip_prefix(src).unwrap().with_extension("");
    let mut parts: Module = rel
        .iter()
        .map(|p| p.to_string_lossy().into_owned())
        .collect();
    if parts.last().is_some_and(|p| p == "mod") {
        parts.pop();
    }
    parts
}

/// The code of a file without comments and without its unit tests.
pub(crate) fn code(text: &str) -> String {
    let text = text
        .find("#[cfg(test)]\nmod tests")
        .map_or(text, |i| &text[..i]);
    text.lines()
        .map(|l| l.split("//").next().unwrap_or(""))
        .collect::<Vec<_>>()
        .join("\n")
}

fn is_word(c: char) -> bool {
    c.is_alphanumeric() || c == '_'
}

/// Every path written in `text` (`a::b::c`, and `a::{b, c::d}` as `a::b` and `a::c::d`), as
/// segments; single identifiers are left out.
fn paths(text: &str) -> Vec<Vec<String>> {
    let chars: Vec<char> = text.chars().collect();
    let mut out = Vec::new();
    let mut i = 0;
    while i < chars.len() {
        let starts = is_word(chars[i])
            && !chars[i].is_ascii_digit()
            && (i == 0 || !(is_word(chars[i - 1]) || chars[i - 1] == ':'));
        if !starts {
            i += 1;
            continue;
        }
        let mut segs = Vec::new();
        loop {
            let s = i;
            while i < chars.len() && is_word(chars[i]) {
                i += 1;
            }
            segs.push(chars[s..i].iter().collect::<String>());
            if i + 2 < chars.len() && chars[i] == ':' && chars[i + 1] == ':' {
                i += 2;
                if chars[i] == '{' {
                    let mut depth = 0;
                    let s = i + 1;
                    while i < chars.len() {
                        match chars[i] {
                            '{' => depth += 1,
                            '}' => {
                                depth -= 1;
                                if depth == 0 {
                                    break;
                                }
                            }
                            _ => {}
                        }
                        i += 1;
                    }
                    let group: String = chars[s..i.min(chars.len())].iter().collect();
                    for item in group.split(',') {
                        let item: Vec<String> = item
                            .split("::")
                            .map(|p| p.trim().chars().take_while(|&c| is_word(c)).collect())
                            .take_while(|p: &String| !p.is_empty())
                            .collect();
                        let mut full = segs.clone();
                        full.extend(item);
                        out.push(full);
                    }
                    segs.clear();
                    break;
                }
                if i < chars.len() && is_word(chars[i]) {
                    continue;
                }
            }
            break;
        }
        if segs.len() > 1 {
            out.push(segs);
        }
    }
    out
}

/// `text` without the statements that re-export a child module's items (`pub use child::{A, b};`,
/// `pub(crate) use self::child::C;`): a layer naming what it offers from its own files is its
/// public face, not a dependency on them (the parent only re-exports; the glob form of the
/// same statement, `pub use child::*`, was never counted either).
fn without_child_re_exports(me: &Module, text: &str, modules: &BTreeSet<Module>) -> String {
    let mut out = String::with_capacity(text.len());
    let mut rest = text;
    while let Some(at) = rest.find("pub") {
        let (before, from) = rest.split_at(at);
        out.push_str(before);
        let statement_end = from.find(';').map_or(from.len(), |e| e + 1);
        let statement = &from[..statement_end];
        let after_vis = statement
            .strip_prefix("pub(crate)")
            .or_else(|| statement.strip_prefix("pub"))
            .unwrap_or(statement);
        let child = after_vis
            .trim_start()
            .strip_prefix("use ")
            .map(|p| p.trim_start().trim_start_matches("self::"))
            .and_then(|p| p.split("::").next())
            .map(|first| {
                let mut m = me.clone();
                m.push(first.trim().to_owned());
                m
            });
        let starts_word = before.chars().last().is_none_or(|c| !is_word(c));
        if starts_word && child.is_some_and(|c| modules.contains(&c)) {
            rest = &from[statement_end..];
        } else {
            out.push_str("pub");
            rest = &from[3..];
        }
    }
    out.push_str(rest);
    out
}

/// The modules of `modules` that module `me` names.
fn imports(me: &Module, text: &str, modules: &BTreeSet<Module>) -> BTreeSet<Module> {
    let mut found = BTreeSet::new();
    for path in paths(&without_child_re_exports(me, &code(text), modules)) {
        let mut base: Module = match path[0].as_str() {
            "crate" => Vec::new(),
            "self" => me.clone(),
            "super" => me.clone(),
            first => {
                let mut child = me.clone();
                child.push(first.to_owned());
                if !modules.contains(&child) {
                    continue;
                }
                me.clone()
            }
        };
        let mut rest = &path[..];
        if rest[0] == "crate" || rest[0] == "self" {
            rest = &rest[1..];
        }
        while rest.first().is_some_and(|s| s == "super") {
            base.pop();
            rest = &rest[1..];
        }
        base.extend(rest.iter().cloned());
        while !base.is_empty() && !modules.contains(&base) {
            base.pop();
        }
        if !base.is_empty() && base != *me {
            found.insert(base);
        }
    }
    found
}

/// Each module of `layers` (folders of `src`) and the modules it imports.
fn import_graph(src: &Path, layers: &[&str]) -> Vec<(Module, BTreeSet<Module>)> {
    let mut files = Vec::new();
    for layer in layers {
        sources(&src.join(layer), &mut files);
    }
    // `src/bin/radbench` is the binary, a crate of its own (its `crate::` is not the library's):
    // read as its own root.
    files.retain(|f| !f.strip_prefix(src).unwrap().starts_with("bin"));
    let modules: BTreeSet<Module> = files.iter().map(|f| module_of(src, f)).collect();
    files
        .iter()
        .map(|f| {
            let me = module_of(src, f);
            let text = std::fs::read_to_string(f).unwrap();
            let found = imports(&me, &text, &modules);
            (me, found)
        })
        .collect()
}

/// The groups of modules that reach each other through imports, of any length (a -> b -> c -> a
/// as well as a <-> b): the strongly connected components of more than one module.
fn loops_in(src: &Path, layers: &[&str]) -> Vec<Vec<String>> {
    let graph = import_graph(src, layers);
    let index: std::collections::BTreeMap<&Module, usize> =
        graph.iter().enumerate().map(|(i, (m, _))| (m, i)).collect();
    let next: Vec<Vec<usize>> = graph
        .iter()
        .map(|(_, to)| to.iter().filter_map(|m| index.get(m).copied()).collect())
        .collect();
    let reach = |from: usize| {
        let mut seen = vec![false; next.len()];
        let mut stack = vec![from];
        while let Some(n) = stack.pop() {
            for &m in &next[n] {
                if !seen[m] {
                    seen[m] = true;
                    stack.push(m);
                }
            }
        }
        seen
    };
    let reached: Vec<Vec<bool>> = (0..next.len()).map(reach).collect();
    let mut grouped = vec![false; next.len()];
    let mut loops = Vec::new();
    for a in 0..next.len() {
        if grouped[a] || !reached[a][a] {
            continue;
        }
        let group: Vec<usize> = (0..next.len())
            .filter(|&b| reached[a][b] && reached[b][a])
            .collect();
        for &b in &group {
            grouped[b] = true;
        }
        let mut names: Vec<String> = group.iter().map(|&b| graph[b].0.join("::")).collect();
        names.sort();
        loops.push(names);
    }
    loops
}

/// Pairs of modules of `layers` (folders of `src`) that import each other, as `a <-> b`.
fn circles_in(src: &Path, layers: &[&str]) -> Vec<String> {
    let edges = import_graph(src, layers);
    let mut circles = Vec::new();
    for (a, from_a) in &edges {
        for (b, from_b) in &edges {
            if a < b && from_a.contains(b) && from_b.contains(a) {
                circles.push(format!("{} <-> {}", a.join("::"), b.join("::")));
            }
        }
    }
    circles
}

#[test]
fn no_two_modules_of_dsp_or_waveform_import_each_other() {
    let src = Path::new(env!("CARGO_MANIFEST_DIR")).join("src");
    let circles = circles_in(&src, &["dsp", "waveform"]);
    assert!(circles.is_empty(), "import circles: {circles:?}");
}

/// No two modules anywhere import each other: every file of `src/` (the library's layers, and
/// the binary's `cli/` and `live/` under `src/bin/radbench/`, read as its own crate) and of mock_lab (issue 42: 52 pairs on 2026-12-05, 0 since
/// 2026-12-06; docs/architecture.md says how they went).
#[test]
fn no_two_modules_anywhere_import_each_other() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let mut circles = circles_in(&root.join("src"), &[""]);
    circles.extend(circles_in(&root.join("src/bin/radbench"), &[""]));
    circles.extend(circles_in(&root.join("mock_lab/src"), &[""]));
    assert!(circles.is_empty(), "import circles: {circles:#?}");
}

/// Longer loops (a -> b -> c -> a), which the pair check does not see: none since 2026-12-07
/// (docs/architecture.md names those there were and how they went). `--nocapture` prints each
/// loop's modules and the imports inside it.
const KNOWN_LOOPS: usize = 0;

#[test]
fn longer_import_loops_do_not_grow() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let mut loops = loops_in(&root.join("src"), &[""]);
    let graph = import_graph(&root.join("src"), &[""]);
    for group in &loops {
        println!("loop of {} modules:", group.len());
        for (m, to) in &graph {
            let name = m.join("::");
            if group.contains(&name) {
                let inside: Vec<String> = to
                    .iter()
                    .map(|t| t.join("::"))
                    .filter(|t| group.contains(t))
                    .collect();
                println!("  {name} -> {inside:?}");
            }
        }
    }
    loops.extend(loops_in(&root.join("src/bin/radbench"), &[""]));
    loops.extend(loops_in(&root.join("mock_lab/src"), &[""]));
    // `==`, not `<=`: a loop taken apart lowers the count here too (and at 0 clippy refuses
    // `<=` as always equal).
    assert!(
        loops.len() == KNOWN_LOOPS,
        "{} import loops, not the {KNOWN_LOOPS} known: {loops:#?}",
        loops.len()
    );
}

#[test]
fn the_circle_check_sees_parents_children_and_groups() {
    let m = |s: &str| s.split("::").map(str::to_owned).collect::<Module>();
    let modules: BTreeSet<Module> = ["dsp", "dsp::music", "dsp::music::root", "dsp::metrics"]
        .into_iter()
        .map(m)
        .collect();
    let text = "use super::{metrics::Axis, DspError};\nmod root;\nuse root::f; // crate::dsp::x\n";
    let found = imports(&m("dsp::music"), text, &modules);
    let found: Vec<String> = found.iter().map(|p| p.join("::")).collect();
    assert_eq!(found, ["dsp", "dsp::metrics", "dsp::music::root"]);
    let found = imports(&m("dsp::music::root"), "use super::Music;", &modules);
    assert!(found.contains(&m("dsp::music")));
    // A parent naming its child's items is its public face, not an import of the child; a
    // re-export from elsewhere still counts.
    let text =
        "pub use root::{A, b};\npub(crate) use self::root::C;\npub use super::metrics::Axis;";
    let found = imports(&m("dsp::music"), text, &modules);
    let found: Vec<String> = found.iter().map(|p| p.join("::")).collect();
    assert_eq!(found, ["dsp::metrics"]);
}

#[test]
fn the_loop_check_sees_a_loop_of_three() {
    let dir = tempfile::tempdir().unwrap();
    let src = dir.path();
    std::fs::create_dir(src.join("layer")).unwrap();
    for (file, text) in [
        ("mod.rs", "mod a;\nmod b;\nmod c;\nmod d;\n"),
        ("a.rs", "use super::b::B;\n"),
        ("b.rs", "use crate::layer::c::C;\n"),
        ("c.rs", "use super::a::A;\nuse super::d::D;\n"),
        ("d.rs", "pub struct D;\n"),
    ] {
        std::fs::write(src.join("layer").join(file), text).unwrap();
    }
    assert!(circles_in(src, &["layer"]).is_empty());
    assert_eq!(
        loops_in(src, &["layer"]),
        [["layer::a", "layer::b", "layer::c"]]
    );
}
