//! Every relative link of README.md and docs/ points to a file that exists, and a link to a
//! heading of a Markdown file (`page.md#heading`) to a heading that page has.

use super::guide_markdown::{anchors, links};
use std::path::{Path, PathBuf};

/// README.md and every Markdown file under docs/.
fn guide_files(root: &Path) -> Vec<PathBuf> {
    let mut files = vec![root.join("README.md")];
    let mut dirs = vec![root.join("docs")];
    while let Some(dir) = dirs.pop() {
        for entry in std::fs::read_dir(&dir).unwrap() {
            let path = entry.unwrap().path();
            if path.is_dir() {
                dirs.push(path);
            } else if path.extension().is_some_and(|e| e == "md") {
                files.push(path);
            }
        }
    }
    files.sort();
    files
}

/// What is wrong with each relative link of `file` ("file:line: target: why").
fn broken_links(file: &Path) -> Vec<String> {
    let text = std::fs::read_to_string(file).unwrap();
    let mut broken = Vec::new();
    for (line, target) in links(&text) {
        if target.contains("://") || target.starts_with("mailto:") {
            continue;
        }
        let (path, heading) = match target.split_once('#') {
            Some((p, h)) => (p, Some(h)),
            None => (target.as_str(), None),
        };
        let linked = if path.is_empty() {
            file.to_path_buf()
        } else {
            file.parent().unwrap().join(path)
        };
        let why = if !linked.exists() {
            Some("no such file".to_string())
        } else {
            match heading {
                Some(h) if linked.extension().is_some_and(|e| e == "md") => {
                    let known = anchors(&std::fs::read_to_string(&linked).unwrap());
                    (!known.contains(h)).then(|| format!("no heading with anchor `{h}`"))
                }
                _ => None,
            }
        };
        if let Some(why) = why {
            broken.push(format!("{}:{line}: {target}: {why}", file.display()));
        }
    }
    broken
}

#[test]
fn guide_links_point_to_files_and_headings_that_exist() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let files = guide_files(root);
    assert!(files.len() > 10, "the guide's pages: {files:?}");
    let broken: Vec<String> = files.iter().flat_map(|f| broken_links(f)).collect();
    assert!(broken.is_empty(), "broken links:\n{}", broken.join("\n"));
}

#[test]
fn guide_links_check_finds_a_missing_page_and_a_missing_heading() {
    let dir = tempfile::tempdir().unwrap();
    let page = dir.path().join("page.md");
    std::fs::write(dir.path().join("other.md"), "# Other\n## A section\n").unwrap();
    std::fs::write(
        &page,
        "# Page\n[ok](other.md#a-section) [ok](#page) [gone](missing.md)\n\
         [no heading](other.md#nowhere) [web](https://example.org/x.md)\n",
    )
    .unwrap();
    let broken = broken_links(&page);
    assert_eq!(broken.len(), 2, "{broken:?}");
    assert!(
        broken[0].ends_with("missing.md: no such file"),
        "{broken:?}"
    );
    assert!(
        broken[1].contains("no heading with anchor `nowhere`"),
        "{broken:?}"
    );
}
