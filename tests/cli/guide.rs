//! The guide's commands run: every fenced `sh` block of docs/tutorial.md and of README.md that is
//! not marked `sh no-run` is executed line by line, in the page's order, on the built-in mock lab,
//! in a fresh folder holding a copy of examples/; each command must exit 0. A block that needs a
//! real bench, runs until Ctrl-C or takes minutes is marked `no-run` in the page and skipped.

use super::guide_markdown::sh_blocks;
use std::path::Path;

/// Commands a runnable block may hold that are not radbench's: the test suite itself and the
/// tooling around it. They are skipped (and named on the test's output).
const TOOLING: &[&str] = &["cargo test", "cargo build", "pip install"];

/// What one line of a runnable block asks for.
#[derive(Debug, PartialEq)]
enum Command {
    /// radbench with these arguments (`radbench ARGS` or `cargo run [--release] -- ARGS`).
    Radbench(Vec<String>),
    /// One of [`TOOLING`]: not run here.
    Tooling(String),
}

/// A command line split into words as a shell would for the simple lines the guide holds:
/// quotes group, an unquoted `#` after a space starts a comment. Redirections, pipes, variables
/// and the like are refused: the test would not run what the reader runs.
fn words(line: &str) -> Result<Vec<String>, String> {
    let mut words = Vec::new();
    let mut word: Option<String> = None;
    let mut quote: Option<char> = None;
    for c in line.chars() {
        match (quote, c) {
            (Some(q), c) if c == q => quote = None,
            (Some(_), c) => word.get_or_insert_with(String::new).push(c),
            (None, '"' | '\'') => {
                quote = Some(c);
                word.get_or_insert_with(String::new);
            }
            (None, c) if c.is_whitespace() => words.extend(word.take()),
            (None, '#') if word.is_none() => break,
            (None, '|' | '>' | '<' | ';' | '&' | '$' | '`' | '*') => {
                return Err(format!(
                    "`{c}`: shell syntax the guide test does not run; mark the block `sh no-run`"
                ))
            }
            (None, c) => word.get_or_insert_with(String::new).push(c),
        }
    }
    if quote.is_some() {
        return Err("an unclosed quote".into());
    }
    words.extend(word);
    Ok(words)
}

/// The command of one line of a runnable block (`None` for a blank line or a comment).
fn command(line: &str) -> Result<Option<Command>, String> {
    let words = words(line)?;
    let Some(first) = words.first() else {
        return Ok(None);
    };
    if first == "radbench" {
        return Ok(Some(Command::Radbench(words[1..].to_vec())));
    }
    if words.len() >= 2 && first == "cargo" && words[1] == "run" {
        let dashes = words
            .iter()
            .position(|w| w == "--")
            .ok_or("`cargo run` without `--`")?;
        return Ok(Some(Command::Radbench(words[dashes + 1..].to_vec())));
    }
    let head = words.iter().take(2).cloned().collect::<Vec<_>>().join(" ");
    if TOOLING.contains(&head.as_str()) {
        return Ok(Some(Command::Tooling(head)));
    }
    Err(format!(
        "`{first}` is not radbench: a runnable block holds radbench commands only (or mark it `sh no-run`)"
    ))
}

/// Runs every runnable block of `text` (the page `page`) in `dir`, in order; the output of each
/// radbench command (its arguments, stdout, stderr), or the first failure.
async fn run_page(
    page: &str,
    text: &str,
    dir: &Path,
) -> Result<Vec<(Vec<String>, String, String)>, String> {
    let mut outputs = Vec::new();
    for block in sh_blocks(text).into_iter().filter(|b| b.runs) {
        for (i, line) in block.lines.iter().enumerate() {
            let at = format!("{page}:{}: `{}`", block.line + 1 + i, line.trim());
            match command(line).map_err(|e| format!("{at}: {e}"))? {
                None => {}
                Some(Command::Tooling(what)) => eprintln!("{at}: skipped ({what} is not radbench)"),
                Some(Command::Radbench(args)) => {
                    let argv: Vec<&str> = args.iter().map(String::as_str).collect();
                    let (code, out, err) = crate::support::radbench_in(Some(dir), &argv).await;
                    if code != 0 {
                        return Err(format!(
                            "{at} exited {code}\nstdout:\n{out}\nstderr:\n{err}"
                        ));
                    }
                    outputs.push((args, out, err));
                }
            }
        }
    }
    Ok(outputs)
}

/// A fresh folder with a copy of examples/, as a reader's checkout has it.
fn reader_folder() -> tempfile::TempDir {
    let dir = tempfile::tempdir().unwrap();
    let examples = Path::new(env!("CARGO_MANIFEST_DIR")).join("examples");
    std::fs::create_dir(dir.path().join("examples")).unwrap();
    for entry in std::fs::read_dir(&examples).unwrap() {
        let path = entry.unwrap().path();
        if path.is_file() {
            std::fs::copy(
                &path,
                dir.path().join("examples").join(path.file_name().unwrap()),
            )
            .unwrap();
        }
    }
    dir
}

fn page(relative: &str) -> String {
    std::fs::read_to_string(Path::new(env!("CARGO_MANIFEST_DIR")).join(relative)).unwrap()
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn guide_tutorial_commands_run_on_the_mock_lab() {
    let dir = reader_folder();
    let text = page("docs/tutorial.md");
    let outputs = run_page("docs/tutorial.md", &text, dir.path())
        .await
        .unwrap_or_else(|e| panic!("{e}"));
    assert!(outputs.len() >= 8, "the tutorial's commands: {outputs:?}");
    // What the page says the commands leave behind.
    for file in [
        "runs/first/summary.json",
        "runs/first.npz",
        "runs/accuracy/report.html",
        "runs/accuracy/results.csv",
    ] {
        assert!(dir.path().join(file).is_file(), "{file} after the tutorial");
    }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn guide_readme_commands_run_on_the_mock_lab() {
    let dir = reader_folder();
    let text = page("README.md");
    let outputs = run_page("README.md", &text, dir.path())
        .await
        .unwrap_or_else(|e| panic!("{e}"));
    // The quick start's first command prints what the README shows.
    let (_, out, err) = outputs
        .iter()
        .find(|(args, _, _)| args.join(" ") == "campaign run examples/accuracy.toml --allow-rf")
        .expect("the README's first set-up command runs");
    let all = format!("{out}{err}");
    for shown in [
        "no bench file: running on the built-in mock lab",
        "complete: 6 steps (6 measured, 0 kept from before); largest error",
    ] {
        assert!(all.contains(shown), "`{shown}` in\n{all}");
    }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn guide_a_failing_command_or_a_foreign_one_fails_the_page() {
    let dir = reader_folder();
    let failing = "```sh\nradbench doctor --no-such-option\n```\n";
    let e = run_page("page.md", failing, dir.path()).await.unwrap_err();
    assert!(
        e.starts_with("page.md:2: `radbench doctor --no-such-option` exited 2"),
        "{e}"
    );
    let foreign = "```sh\nrm -r runs\n```\n";
    let e = run_page("page.md", foreign, dir.path()).await.unwrap_err();
    assert!(e.contains("`rm` is not radbench"), "{e}");
    let skipped = "```sh no-run\nradbench idn VICP::192.0.2.1\n```\n";
    assert!(run_page("page.md", skipped, dir.path())
        .await
        .unwrap()
        .is_empty());
}

#[test]
fn guide_command_lines_are_read_as_a_shell_would() {
    assert_eq!(
        command(r#"cargo run -- capture --payload "hello at 80 GHz" --out runs/x   # comment"#),
        Ok(Some(Command::Radbench(
            ["capture", "--payload", "hello at 80 GHz", "--out", "runs/x"]
                .map(String::from)
                .to_vec()
        )))
    );
    assert_eq!(
        command("cargo test --workspace   # the tests"),
        Ok(Some(Command::Tooling("cargo test".into())))
    );
    assert_eq!(command("# only a comment"), Ok(None));
    assert!(command("radbench mock-lab serve > bench.toml").is_err());
}

/// Issue 39: the README is a first screen, not the development log (that is under docs/dev/).
#[test]
fn guide_readme_is_at_most_400_lines() {
    let lines = page("README.md").lines().count();
    assert!(
        lines <= 400,
        "README.md has {lines} lines: move detail into docs/"
    );
}
