//! The SCPI error/event queue (IEEE 488.2 / SCPI-99 chapter 21): FIFO, bounded, `-350` on overflow.

use std::collections::VecDeque;

/// One queue entry: a SCPI error code and its text (`-222,"Data out of range;..."`).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct ScpiError {
    pub code: i32,
    pub text: String,
}

impl ScpiError {
    /// The standard text for `code` followed by `;detail` when a detail is given.
    pub fn new(code: i32, detail: impl AsRef<str>) -> Self {
        let detail = detail.as_ref();
        let base = standard_text(code);
        let text = if detail.is_empty() {
            base.to_string()
        } else {
            format!("{base};{detail}")
        };
        ScpiError { code, text }
    }

    /// The `:SYST:ERR?` reply form: `<code>,"<text>"`.
    pub fn reply(&self) -> String {
        format!("{},\"{}\"", self.code, self.text.replace('"', "'"))
    }

    /// Command errors (-100..-199) abort the rest of the program message.
    pub(crate) fn is_command_error(&self) -> bool {
        (-199..=-100).contains(&self.code)
    }
}

/// Standard SCPI-99 texts of the codes the emulators raise.
pub(crate) fn standard_text(code: i32) -> &'static str {
    match code {
        0 => "No error",
        -100 => "Command error",
        -101 => "Invalid character",
        -102 => "Syntax error",
        -104 => "Data type error",
        -108 => "Parameter not allowed",
        -109 => "Missing parameter",
        -113 => "Undefined header",
        -131 => "Invalid suffix",
        -114 => "Header suffix out of range",
        -141 => "Invalid character data",
        -160 => "Block data error",
        -161 => "Invalid block data",
        -200 => "Execution error",
        -221 => "Settings conflict",
        -222 => "Data out of range",
        -223 => "Too much data",
        -224 => "Illegal parameter value",
        -225 => "Out of memory",
        -241 => "Hardware missing",
        -350 => "Queue overflow",
        -410 => "Query INTERRUPTED",
        _ => "Error",
    }
}

/// Bounded FIFO of errors.
#[derive(Debug, Clone)]
pub(crate) struct ErrorQueue {
    entries: VecDeque<ScpiError>,
    capacity: usize,
}

impl ErrorQueue {
    pub(crate) fn new(capacity: usize) -> Self {
        ErrorQueue {
            entries: VecDeque::new(),
            capacity: capacity.max(2),
        }
    }

    /// Adds an error; when full, the newest entry becomes `-350,"Queue overflow"` (SCPI-99 21.8.2).
    pub(crate) fn push(&mut self, error: ScpiError) {
        tracing::debug!(code = error.code, text = %error.text, "error queued");
        if self.entries.len() >= self.capacity {
            if let Some(last) = self.entries.back_mut() {
                *last = ScpiError::new(-350, "");
            }
            return;
        }
        self.entries.push_back(error);
    }

    /// The oldest error, or `0,"No error"`.
    pub(crate) fn pop(&mut self) -> ScpiError {
        self.entries
            .pop_front()
            .unwrap_or_else(|| ScpiError::new(0, ""))
    }

    pub(crate) fn len(&self) -> usize {
        self.entries.len()
    }

    pub(crate) fn is_empty(&self) -> bool {
        self.entries.is_empty()
    }

    pub(crate) fn clear(&mut self) {
        self.entries.clear();
    }

    /// The queued errors without removing them.
    pub(crate) fn peek_all(&self) -> Vec<ScpiError> {
        self.entries.iter().cloned().collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fifo_with_overflow_marker() {
        let mut q = ErrorQueue::new(3);
        for code in [-113, -222, -223, -224] {
            q.push(ScpiError::new(code, ""));
        }
        assert_eq!(q.pop().code, -113);
        assert_eq!(q.pop().code, -222);
        assert_eq!(q.pop().reply(), "-350,\"Queue overflow\"");
        assert_eq!(q.pop().reply(), "0,\"No error\"");
    }
}
