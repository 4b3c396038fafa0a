//! SCPI header matching: long and short forms, optional nodes, numeric suffixes, and the compound
//! header rule (a header without a leading `:` continues the previous header's path).
//!
//! Patterns are written as in instrument manuals: `:TRACe#:DATA`, `[:SOURce]:FREQuency:RASTer`,
//! `:VOLTage#[:LEVel][:IMMediate][:AMPLitude]`. Capitals are the short form; `#` marks a node that
//! takes a numeric suffix (default 1); `[...]` marks an optional node.

use super::error_queue::ScpiError;

#[derive(Debug, Clone, PartialEq, Eq)]
struct PatternNode {
    short: String,
    long: String,
    optional: bool,
    suffix: bool,
}

/// A parsed header pattern.
#[derive(Debug, Clone, PartialEq, Eq)]
pub(crate) struct Pattern {
    nodes: Vec<PatternNode>,
}

impl Pattern {
    /// Parses a manual-style pattern. Patterns are program constants: a malformed one is a bug that
    /// the emulator's unit tests catch, so it is reported by `debug_assert` and otherwise matches nothing.
    pub(crate) fn new(pattern: &str) -> Pattern {
        let mut nodes = Vec::new();
        let mut rest = pattern.trim();
        while !rest.is_empty() {
            let optional = rest.starts_with('[');
            let body;
            if optional {
                let close = rest.find(']').unwrap_or(rest.len());
                body = &rest[1..close];
                rest = rest.get(close + 1..).unwrap_or("");
            } else {
                let start = usize::from(rest.starts_with(':'));
                let end = rest[start..]
                    .find([':', '['])
                    .map(|i| i + start)
                    .unwrap_or(rest.len());
                body = &rest[..end];
                rest = &rest[end..];
            }
            let name = body.trim_start_matches(':');
            let suffix = name.ends_with('#');
            let name = name.trim_end_matches('#');
            debug_assert!(!name.is_empty(), "empty node in pattern {pattern:?}");
            nodes.push(PatternNode {
                short: name.chars().filter(|c| !c.is_ascii_lowercase()).collect(),
                long: name.to_ascii_uppercase(),
                optional,
                suffix,
            });
        }
        Pattern { nodes }
    }

    /// Matches parsed header nodes; returns the numeric suffix of every `#` node (1 when omitted).
    pub(crate) fn matches(&self, input: &[HeaderNode]) -> Option<Vec<u32>> {
        let mut suffixes = Vec::new();
        self.match_from(0, input, &mut suffixes).then_some(suffixes)
    }

    fn match_from(&self, p: usize, input: &[HeaderNode], suffixes: &mut Vec<u32>) -> bool {
        let Some(node) = self.nodes.get(p) else {
            return input.is_empty();
        };
        if let Some((first, rest)) = input.split_first() {
            let name_ok = first.mnemonic == node.short || first.mnemonic == node.long;
            let suffix_ok = node.suffix || first.suffix.is_none();
            if name_ok && suffix_ok {
                let mark = suffixes.len();
                if node.suffix {
                    suffixes.push(first.suffix.unwrap_or(1));
                }
                if self.match_from(p + 1, rest, suffixes) {
                    return true;
                }
                suffixes.truncate(mark);
            }
        }
        if node.optional {
            let mark = suffixes.len();
            if node.suffix {
                suffixes.push(1);
            }
            if self.match_from(p + 1, input, suffixes) {
                return true;
            }
            suffixes.truncate(mark);
        }
        false
    }
}

/// One node of a received header: mnemonic in capitals and its numeric suffix, if written.
#[derive(Debug, Clone, PartialEq, Eq)]
pub(crate) struct HeaderNode {
    pub mnemonic: String,
    pub suffix: Option<u32>,
}

/// A received header split into nodes.
#[derive(Debug, Clone, PartialEq, Eq)]
pub(crate) struct Header {
    /// Written with a leading `:` (absolute path).
    pub absolute: bool,
    pub nodes: Vec<HeaderNode>,
    pub query: bool,
}

impl Header {
    /// Parses `:TRAC1:DATA?`-style headers (`-102` syntax error for malformed nodes).
    pub(crate) fn parse(text: &str) -> Result<Header, ScpiError> {
        let query = text.ends_with('?');
        let body = text.trim_end_matches('?');
        let absolute = body.starts_with(':');
        let body = body.strip_prefix(':').unwrap_or(body);
        let mut nodes = Vec::new();
        for part in body.split(':') {
            let digits_at = part
                .find(|c: char| c.is_ascii_digit())
                .unwrap_or(part.len());
            let (mnemonic, digits) = part.split_at(digits_at);
            let valid = !mnemonic.is_empty()
                && mnemonic
                    .chars()
                    .all(|c| c.is_ascii_alphabetic() || c == '_')
                && digits.chars().all(|c| c.is_ascii_digit());
            if !valid {
                return Err(ScpiError::new(-102, format!("malformed header {text:?}")));
            }
            let suffix =
                if digits.is_empty() {
                    None
                } else {
                    Some(digits.parse().map_err(|_| {
                        ScpiError::new(-114, format!("suffix {digits} is too large"))
                    })?)
                };
            nodes.push(HeaderNode {
                mnemonic: mnemonic.to_ascii_uppercase(),
                suffix,
            });
        }
        Ok(Header {
            absolute,
            nodes,
            query,
        })
    }
}

/// Tracks the current header path within one program message (SCPI-99 6.2.4).
#[derive(Debug, Default)]
pub(crate) struct PathContext {
    path: Vec<HeaderNode>,
}

impl PathContext {
    /// The node lists to try for `header`, most specific first: a relative header is tried under the
    /// previous path first and then from the root.
    pub(crate) fn candidates(&self, header: &Header) -> Vec<Vec<HeaderNode>> {
        let mut out = Vec::new();
        if !header.absolute && !self.path.is_empty() {
            let mut nodes = self.path.clone();
            nodes.extend(header.nodes.iter().cloned());
            out.push(nodes);
        }
        out.push(header.nodes.clone());
        out
    }

    /// Records the nodes that matched, so the next relative header continues under them.
    pub(crate) fn matched(&mut self, nodes: &[HeaderNode]) {
        self.path = nodes[..nodes.len().saturating_sub(1)].to_vec();
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn nodes(text: &str) -> Vec<HeaderNode> {
        Header::parse(text).unwrap().nodes
    }

    #[test]
    fn long_short_optional_and_suffix() {
        let volt = Pattern::new(":VOLTage#[:LEVel][:IMMediate][:AMPLitude]");
        assert_eq!(volt.matches(&nodes(":VOLT2")), Some(vec![2]));
        assert_eq!(volt.matches(&nodes(":VOLT")), Some(vec![1]));
        assert_eq!(volt.matches(&nodes(":voltage3:ampl")), Some(vec![3]));
        assert_eq!(volt.matches(&nodes(":VOLTA")), None);
        assert_eq!(volt.matches(&nodes(":VOLT:AMPL:LEV")), None);
        let rast = Pattern::new("[:SOURce]:FREQuency:RASTer");
        assert!(rast.matches(&nodes(":FREQ:RAST")).is_some());
        assert!(rast.matches(&nodes(":SOUR:FREQ:RAST")).is_some());
        assert!(rast.matches(&nodes(":FREQ1:RAST")).is_none());
        let del = Pattern::new(":TRACe#:DELete:ALL");
        assert_eq!(del.matches(&nodes(":TRAC2:DEL:ALL")), Some(vec![2]));
    }

    #[test]
    fn relative_headers_continue_the_previous_path() {
        let def = Pattern::new(":TRACe#:DEFine");
        let data = Pattern::new(":TRACe#:DATA");
        let mut ctx = PathContext::default();
        let first = Header::parse(":TRAC2:DEF").unwrap();
        let c = ctx.candidates(&first);
        assert!(def.matches(&c[0]).is_some());
        ctx.matched(&c[0]);
        let second = Header::parse("DATA").unwrap();
        assert_eq!(data.matches(&ctx.candidates(&second)[0]), Some(vec![2]));
    }

    #[test]
    fn malformed_headers() {
        assert_eq!(Header::parse(":TR1AC").unwrap_err().code, -102);
        assert_eq!(Header::parse("::X").unwrap_err().code, -102);
    }
}
