//! Reading the guide's Markdown for its tests: fenced `sh` blocks (and whether they are marked
//! `no-run`), relative links, and the anchors GitHub gives headings.

use std::collections::BTreeSet;

/// A fenced ```sh block: where it starts (1-based line of the fence), whether it may run, its lines.
#[derive(Debug)]
pub struct ShBlock {
    pub line: usize,
    pub runs: bool,
    pub lines: Vec<String>,
}

/// Every fenced block whose info string starts with `sh`; `sh no-run` blocks are kept, marked.
pub fn sh_blocks(text: &str) -> Vec<ShBlock> {
    let mut blocks = Vec::new();
    let mut open: Option<ShBlock> = None;
    let mut in_other_fence = false;
    for (n, line) in text.lines().enumerate() {
        let fence = line.trim_start().strip_prefix("```");
        match (fence, open.take()) {
            (Some(_), Some(block)) => blocks.push(block),
            (None, Some(mut block)) => {
                block.lines.push(line.to_string());
                open = Some(block);
            }
            (Some(info), None) if !in_other_fence => {
                let words: Vec<&str> = info.split_whitespace().collect();
                if words.first() == Some(&"sh") {
                    open = Some(ShBlock {
                        line: n + 1,
                        runs: !words.contains(&"no-run"),
                        lines: Vec::new(),
                    });
                } else {
                    in_other_fence = true;
                }
            }
            (Some(_), None) => in_other_fence = false,
            (None, None) => {}
        }
    }
    blocks
}

/// The lines outside fenced code blocks, with their 1-based numbers.
fn prose(text: &str) -> Vec<(usize, &str)> {
    let mut fenced = false;
    let mut out = Vec::new();
    for (n, line) in text.lines().enumerate() {
        if line.trim_start().starts_with("```") {
            fenced = !fenced;
        } else if !fenced {
            out.push((n + 1, line));
        }
    }
    out
}

/// A line with its inline code spans (`...`) blanked: links inside them are not links.
fn without_code_spans(line: &str) -> String {
    let mut out = String::with_capacity(line.len());
    let mut in_code = false;
    for c in line.chars() {
        if c == '`' {
            in_code = !in_code;
        } else if !in_code {
            out.push(c);
        }
    }
    out
}

/// Every inline link target `[text](target)` outside code: (line, target).
pub fn links(text: &str) -> Vec<(usize, String)> {
    let mut found = Vec::new();
    for (n, line) in prose(text) {
        let line = without_code_spans(line);
        let mut rest = line.as_str();
        while let Some(at) = rest.find("](") {
            let after = &rest[at + 2..];
            let Some(end) = after.find(')') else { break };
            let target = after[..end].split_whitespace().next().unwrap_or("");
            found.push((n, target.to_string()));
            rest = &after[end..];
        }
    }
    found
}

/// The anchor GitHub gives a heading: lower case, only letters, digits, `-`, `_` and spaces kept,
/// spaces turned into `-`; the text of a link in it stands for the link.
pub fn anchor(heading: &str) -> String {
    let mut text = String::new();
    let mut rest = heading;
    // `[text](target)` -> `text`
    while let Some(open) = rest.find('[') {
        let Some(mid) = rest[open..].find("](") else {
            break;
        };
        let Some(close) = rest[open + mid..].find(')') else {
            break;
        };
        text.push_str(&rest[..open]);
        text.push_str(&rest[open + 1..open + mid]);
        rest = &rest[open + mid + close + 1..];
    }
    text.push_str(rest);
    text.trim()
        .to_lowercase()
        .chars()
        .filter(|c| c.is_alphanumeric() || matches!(c, '-' | '_' | ' '))
        .map(|c| if c == ' ' { '-' } else { c })
        .collect()
}

/// The anchors of every heading of a Markdown file (repeated headings get `-1`, `-2`, ...).
pub fn anchors(text: &str) -> BTreeSet<String> {
    let mut seen = BTreeSet::new();
    for (_, line) in prose(text) {
        let hashes = line.chars().take_while(|&c| c == '#').count();
        if hashes == 0 || !line[hashes..].starts_with(' ') {
            continue;
        }
        let base = anchor(&line[hashes..]);
        let mut candidate = base.clone();
        let mut k = 0;
        while seen.contains(&candidate) {
            k += 1;
            candidate = format!("{base}-{k}");
        }
        seen.insert(candidate);
    }
    seen
}

#[test]
fn guide_markdown_reads_blocks_links_and_anchors() {
    let text = "# A `cmd`: the (mock_lab) page\n\
                ```sh\nradbench doctor\n```\n\
                ```sh no-run\nradbench idn VICP::10.0.0.1\n```\n\
                ```toml\n[link](in-code.md)\n```\n\
                See [b](b.md#x) and `[not](a-link.md)`.\n\
                ## Twice\n## Twice\n";
    let blocks = sh_blocks(text);
    assert_eq!(blocks.len(), 2);
    assert!(blocks[0].runs && !blocks[1].runs);
    assert_eq!(blocks[0].lines, ["radbench doctor"]);
    assert_eq!(links(text), [(11, "b.md#x".to_string())]);
    let a = anchors(text);
    assert!(a.contains("a-cmd-the-mock_lab-page"), "{a:?}");
    assert!(a.contains("twice") && a.contains("twice-1"), "{a:?}");
    assert_eq!(
        anchor("The chain's response (`calibrate response`, `--correction`)"),
        "the-chains-response-calibrate-response---correction"
    );
}
