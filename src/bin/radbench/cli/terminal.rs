//! Writing to the terminal safely.
//!
//! - Text that came from an instrument (or a file) is shown with its control bytes escaped
//!   ([`printable`]): an escape sequence in an `*IDN?` reply must not recolour, retitle or clear
//!   the user's terminal, nor a carriage return overwrite what was printed before it.
//! - Standard output may be a pipe its reader closes early (`radbench ... | head`): [`out`]
//!   reports that as `StdoutClosed` instead of panicking as `println!` does, and `main` ends
//!   such a run quietly (see [`is_closed_output_panic`] for the commands that still use
//!   `println!` or `eprintln!`).

use std::borrow::Cow;
use std::io::Write;

/// Standard output was closed by its reader; nothing more can be shown there.
#[derive(Debug, Clone, Copy, thiserror::Error)]
#[error("standard output was closed by its reader")]
pub(crate) struct StdoutClosed;

/// Writes `text` and a newline to standard output. A closed pipe is `StdoutClosed`; other
/// write errors (a full disk behind a redirection) are errors naming standard output.
pub fn out(text: &str) -> anyhow::Result<()> {
    let mut stdout = std::io::stdout().lock();
    let written = stdout
        .write_all(text.as_bytes())
        .and_then(|()| stdout.write_all(b"\n"))
        .and_then(|()| stdout.flush());
    outcome(written)
}

/// A write to standard output as the command's result: a closed pipe is `StdoutClosed`.
fn outcome(written: std::io::Result<()>) -> anyhow::Result<()> {
    match written {
        Ok(()) => Ok(()),
        Err(e) if e.kind() == std::io::ErrorKind::BrokenPipe => Err(StdoutClosed.into()),
        Err(e) => Err(anyhow::Error::new(e).context("cannot write to standard output")),
    }
}

/// Writes `value` as pretty JSON and a newline to standard output, streamed through a buffer:
/// a listing of thousands of rows is never held whole as text (its megabytes of fresh pages
/// cost more than the text itself). Errors as [`out`]'s.
pub fn out_json<T: serde::Serialize + ?Sized>(value: &T) -> anyhow::Result<()> {
    let mut stdout = std::io::BufWriter::with_capacity(1 << 16, std::io::stdout().lock());
    let written = serde_json::to_writer_pretty(&mut stdout, value)
        .map_err(|e| match e.io_error_kind() {
            Some(kind) => std::io::Error::from(kind),
            None => std::io::Error::other(e),
        })
        .and_then(|()| stdout.write_all(b"\n"))
        .and_then(|()| stdout.flush());
    outcome(written)
}

/// True when `err` says standard output was closed.
pub fn is_stdout_closed(err: &anyhow::Error) -> bool {
    err.chain().any(|cause| cause.is::<StdoutClosed>())
}

/// True for the panic `println!` (or `eprintln!`) raises when standard output (error) is a
/// closed pipe.
pub fn is_closed_output_panic(payload: &(dyn std::any::Any + Send)) -> bool {
    let text = payload
        .downcast_ref::<String>()
        .map(String::as_str)
        .or_else(|| payload.downcast_ref::<&str>().copied())
        .unwrap_or("");
    (text.starts_with("failed printing to stdout") || text.starts_with("failed printing to stderr"))
        && text.contains("Broken pipe")
}

/// `text` with every control character except LF and tab shown as `\xNN` (or `\u{NNNN}`), and
/// the invisible characters that reorder or hide text (bidirectional overrides, zero-width
/// marks) shown the same way. Borrowed when nothing needs escaping.
pub fn printable(text: &str) -> Cow<'_, str> {
    if !text.chars().any(needs_escape) {
        return Cow::Borrowed(text);
    }
    let mut out = String::with_capacity(text.len() + 8);
    for c in text.chars() {
        push_char(&mut out, c);
    }
    Cow::Owned(out)
}

/// [`printable`] for bytes that may not be UTF-8: invalid bytes are shown as `\xNN`.
pub(crate) fn printable_bytes(bytes: &[u8]) -> String {
    let mut out = String::with_capacity(bytes.len());
    for chunk in bytes.utf8_chunks() {
        for c in chunk.valid().chars() {
            push_char(&mut out, c);
        }
        for b in chunk.invalid() {
            out.push_str(&format!("\\x{b:02x}"));
        }
    }
    out
}

fn push_char(out: &mut String, c: char) {
    if !needs_escape(c) {
        out.push(c);
    } else if (c as u32) < 0x100 {
        out.push_str(&format!("\\x{:02x}", c as u32));
    } else {
        out.push_str(&format!("\\u{{{:04x}}}", c as u32));
    }
}

fn needs_escape(c: char) -> bool {
    (c.is_control() && c != '\n' && c != '\t')
        || matches!(c,
            '\u{200b}'..='\u{200f}'   // zero-width space/joiners, LRM, RLM
            | '\u{202a}'..='\u{202e}' // bidirectional embeddings and overrides
            | '\u{2066}'..='\u{2069}' // bidirectional isolates
            | '\u{feff}')
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn control_and_invisible_characters_are_escaped() {
        assert!(matches!(printable("1.5E+09"), Cow::Borrowed(_)));
        assert_eq!(printable("a\tb\nc"), "a\tb\nc");
        assert_eq!(
            printable("\u{1b}[2J\u{1b}]0;pwned\u{7}"),
            "\\x1b[2J\\x1b]0;pwned\\x07"
        );
        assert_eq!(printable("ok\rFAIL"), "ok\\x0dFAIL");
        assert_eq!(printable("\u{9b}31m"), "\\x9b31m", "C1 CSI");
        assert_eq!(printable("abc\u{202e}fed"), "abc\\u{202e}fed");
        assert_eq!(printable("Keysight, M8195A °C µ"), "Keysight, M8195A °C µ");
        assert_eq!(printable_bytes(b"ok\xff\x1b["), "ok\\xff\\x1b[");
        assert_eq!(printable_bytes("é".as_bytes()), "é");
    }

    #[test]
    fn the_println_panic_is_recognised() {
        let payload: Box<dyn std::any::Any + Send> =
            Box::new("failed printing to stdout: Broken pipe (os error 32)".to_string());
        assert!(is_closed_output_panic(payload.as_ref()));
        let other: Box<dyn std::any::Any + Send> = Box::new("index out of bounds");
        assert!(!is_closed_output_panic(other.as_ref()));
    }
}
