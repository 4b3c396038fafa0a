//! IEEE 488.2 program messages: split into units at `;` (and newlines) outside quoted strings and
//! `#N` binary blocks, then each unit into a header and its comma-separated parameters.
//!
//! Blocks may contain any byte, including `;`, `,` and LF: they are framed by their length only.
//! Whitespace around units and parameters is dropped, but never a byte of a block: a payload
//! whose last byte is a space, tab or LF stays whole.

use super::error_queue::ScpiError;

/// One parameter of a program message unit.
#[derive(Debug, Clone, PartialEq, Eq)]
pub(crate) enum Param {
    /// Character, numeric or quoted-string data as written (trimmed; quotes kept).
    Text(String),
    /// The payload of a definite (`#<d><len>`) or indefinite (`#0`) arbitrary block.
    Block(Vec<u8>),
}

impl Param {
    /// The text of a non-block parameter.
    pub(crate) fn text(&self) -> Option<&str> {
        match self {
            Param::Text(t) => Some(t),
            Param::Block(_) => None,
        }
    }
}

/// One program message unit: `header[?] param,param,...`.
#[derive(Debug, Clone, PartialEq, Eq)]
pub(crate) struct Unit {
    /// The header as written, including a leading `:` or `*` and a trailing `?`.
    pub header: String,
    pub params: Vec<Param>,
}

/// Parses the `#<d><digits>` header of a definite block at the start of `data`: returns the header
/// length and the payload length it announces. `#0` (indefinite) announces everything after it.
pub(crate) fn block_header(data: &[u8]) -> Option<(usize, usize)> {
    if data.first() != Some(&b'#') {
        return None;
    }
    let d = data.get(1).filter(|b| b.is_ascii_digit())?;
    let digits = usize::from(d - b'0');
    if digits == 0 {
        return Some((2, data.len() - 2));
    }
    let len_text = data.get(2..2 + digits)?;
    if !len_text.iter().all(u8::is_ascii_digit) {
        return None;
    }
    let len = std::str::from_utf8(len_text).ok()?.parse().ok()?;
    Some((2 + digits, len))
}

/// Splits a program message into its units. Errors are SCPI command errors (`-160` block data).
pub(crate) fn split_units(message: &[u8]) -> Result<Vec<&[u8]>, ScpiError> {
    let mut units = Vec::new();
    let mut start = 0;
    // End of the last block seen in the current unit: trimming stops there.
    let mut block_end = 0;
    let mut i = 0;
    let mut quote: Option<u8> = None;
    while i < message.len() {
        let b = message[i];
        if let Some(q) = quote {
            if b == q {
                quote = None;
            }
            i += 1;
            continue;
        }
        match b {
            b'"' | b'\'' => {
                quote = Some(b);
                i += 1;
            }
            b'#' if message.get(i + 1).is_some_and(u8::is_ascii_digit) => {
                let (header, payload) = block_header(&message[i..]).ok_or_else(|| {
                    ScpiError::new(-161, "the block length digits are missing or not digits")
                })?;
                let end = i + header + payload;
                if end > message.len() {
                    return Err(ScpiError::new(
                        -161,
                        format!(
                            "the block announces {payload} bytes but only {} arrived",
                            message.len() - i - header
                        ),
                    ));
                }
                i = end;
                block_end = end;
            }
            b';' | b'\n' => {
                push_unit(
                    &mut units,
                    &message[start..i],
                    block_end.saturating_sub(start),
                );
                i += 1;
                start = i;
            }
            _ => i += 1,
        }
    }
    if quote.is_some() {
        return Err(ScpiError::new(-102, "unterminated quoted string"));
    }
    push_unit(
        &mut units,
        &message[start..],
        block_end.saturating_sub(start),
    );
    Ok(units)
}

/// Pushes `unit` without its surrounding whitespace; the first `keep` bytes (up to the end of
/// its last block) are never trimmed from the end.
fn push_unit<'a>(units: &mut Vec<&'a [u8]>, unit: &'a [u8], keep: usize) {
    let mut end = unit.len();
    while end > keep && unit[end - 1].is_ascii_whitespace() {
        end -= 1;
    }
    let trimmed = trim_start(&unit[..end]);
    if !trimmed.is_empty() {
        units.push(trimmed);
    }
}

/// Leading whitespace is never block data (a block starts with `#`).
fn trim_start(data: &[u8]) -> &[u8] {
    let start = data
        .iter()
        .position(|b| !b.is_ascii_whitespace())
        .unwrap_or(data.len());
    &data[start..]
}

/// Both ends: only for text that holds no block.
fn trim(data: &[u8]) -> &[u8] {
    let data = trim_start(data);
    let end = data
        .iter()
        .rposition(|b| !b.is_ascii_whitespace())
        .map_or(0, |e| e + 1);
    &data[..end]
}

/// Parses one unit into header and parameters. Trailing whitespace is left to the parameter
/// parser, which knows where a block ends.
pub(crate) fn parse_unit(unit: &[u8]) -> Result<Unit, ScpiError> {
    let unit = trim_start(unit);
    let header_end = unit
        .iter()
        .position(|b| b.is_ascii_whitespace())
        .unwrap_or(unit.len());
    let header = std::str::from_utf8(&unit[..header_end])
        .map_err(|_| ScpiError::new(-101, "the header is not ASCII"))?
        .to_string();
    if header.is_empty() {
        return Err(ScpiError::new(-102, "empty header"));
    }
    let params = parse_params(trim_start(&unit[header_end..]))?;
    Ok(Unit { header, params })
}

fn parse_params(data: &[u8]) -> Result<Vec<Param>, ScpiError> {
    let mut params = Vec::new();
    if data.iter().all(u8::is_ascii_whitespace) {
        return Ok(params);
    }
    let mut i = 0;
    loop {
        while i < data.len() && data[i].is_ascii_whitespace() {
            i += 1;
        }
        if data.get(i) == Some(&b'#') && data.get(i + 1).is_some_and(u8::is_ascii_digit) {
            let (header, payload) =
                block_header(&data[i..]).ok_or_else(|| ScpiError::new(-161, "bad block header"))?;
            let end = i + header + payload;
            if end > data.len() {
                return Err(ScpiError::new(-161, "the block is shorter than announced"));
            }
            params.push(Param::Block(data[i + header..end].to_vec()));
            i = end;
            while i < data.len() && data[i].is_ascii_whitespace() {
                i += 1;
            }
            if i < data.len() && data[i] != b',' {
                return Err(ScpiError::new(
                    -161,
                    "more bytes follow the block than it announced",
                ));
            }
        } else {
            let start = i;
            let mut quote: Option<u8> = None;
            while i < data.len() {
                let b = data[i];
                match quote {
                    Some(q) if b == q => quote = None,
                    Some(_) => {}
                    None if b == b'"' || b == b'\'' => quote = Some(b),
                    None if b == b',' => break,
                    None => {}
                }
                i += 1;
            }
            let text = std::str::from_utf8(trim(&data[start..i]))
                .map_err(|_| ScpiError::new(-101, "a parameter is not ASCII"))?;
            if text.is_empty() {
                return Err(ScpiError::new(-109, "empty parameter between commas"));
            }
            params.push(Param::Text(text.to_string()));
        }
        if i >= data.len() {
            return Ok(params);
        }
        i += 1; // the comma
        if i >= data.len() {
            return Err(ScpiError::new(
                -109,
                "a parameter is missing after the last comma",
            ));
        }
    }
}

/// Removes one pair of matching surrounding quotes (`"..."` or `'...'`), if present.
pub(crate) fn unquote(text: &str) -> &str {
    let t = text.trim();
    for q in ['"', '\''] {
        if t.len() >= 2 && t.starts_with(q) && t.ends_with(q) {
            return &t[1..t.len() - 1];
        }
    }
    t
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn splits_around_blocks_and_quotes() {
        let msg = b":TRAC1:DATA 1,0,#14;\n,\x7f;VBS 'a;b';*OPC?\r\n";
        let units = split_units(msg).unwrap();
        assert_eq!(units.len(), 3);
        let data = parse_unit(units[0]).unwrap();
        assert_eq!(data.header, ":TRAC1:DATA");
        assert_eq!(
            data.params,
            [
                Param::Text("1".into()),
                Param::Text("0".into()),
                Param::Block(b";\n,\x7f".to_vec())
            ]
        );
        assert_eq!(
            parse_unit(units[1]).unwrap().params,
            [Param::Text("'a;b'".into())]
        );
        assert!(parse_unit(units[2]).unwrap().header.ends_with('?'));
    }

    #[test]
    fn short_blocks_and_stray_bytes_are_block_errors() {
        assert_eq!(
            split_units(b":TRAC:DATA 1,0,#15abc").unwrap_err().code,
            -161
        );
        let unit = parse_unit(b":TRAC:DATA 1,0,#12abX").unwrap_err();
        assert_eq!(unit.code, -161);
        assert_eq!(parse_unit(b"A 1,").unwrap_err().code, -109);
        assert_eq!(block_header(b"#0abc"), Some((2, 3)));
    }

    #[test]
    fn blocks_ending_in_whitespace_stay_whole() {
        for tail in [b' ', b'\n', b'\t', b'\r'] {
            let payload = [b'a', tail, tail];
            for message in [
                [&b":TRAC1:DATA 1,0,#13"[..], &payload].concat(),
                [&b":TRAC1:DATA 1,0,#13"[..], &payload, b" \r"].concat(),
                [&b":TRAC1:DATA 1,0,#13"[..], &payload, b" ;*OPC?"].concat(),
            ] {
                let units = split_units(&message).unwrap();
                let unit = parse_unit(units[0]).unwrap();
                assert_eq!(
                    unit.params[2],
                    Param::Block(payload.to_vec()),
                    "{message:?}"
                );
            }
            let indefinite = [&b"DATA #0ab"[..], &[tail]].concat();
            let units = split_units(&indefinite).unwrap();
            assert_eq!(
                parse_unit(units[0]).unwrap().params,
                [Param::Block([&b"ab"[..], &[tail]].concat())]
            );
        }
        // Text keeps being trimmed.
        let units = split_units(b"  :VOLT1 0.5 \t; *IDN? \r").unwrap();
        assert_eq!(units, [&b":VOLT1 0.5"[..], b"*IDN?"]);
        assert_eq!(
            parse_unit(units[0]).unwrap().params,
            [Param::Text("0.5".into())]
        );
        assert!(parse_unit(b"*RST   ").unwrap().params.is_empty());
    }
}
