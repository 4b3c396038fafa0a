//! Pure parsing of IEEE 488.2 response messages: numbers, booleans, strings, `*IDN?`, `SYST:ERR?`
//! entries and arbitrary blocks. No I/O here.

use super::error::DeviceError;
use bytes::Bytes;
use std::ops::Range;

/// Strips the message terminator (`\n`, `\r\n`) and surrounding blanks.
pub fn trim_reply(text: &str) -> &str {
    text.trim_end_matches(['\n', '\r']).trim()
}

/// A decimal number: `1`, `+6.4000000000E+10`, `-0.5`, `9.9E37` (SCPI's overflow/infinity).
pub fn parse_f64(text: &str) -> Option<f64> {
    let t = trim_reply(text);
    let v: f64 = t.parse().ok()?;
    v.is_finite().then_some(v)
}

/// An integer; also accepts integral floats such as `+1.00000000E+003`, which many instruments send.
pub fn parse_i64(text: &str) -> Option<i64> {
    let t = trim_reply(text);
    if let Ok(v) = t.parse::<i64>() {
        return Some(v);
    }
    let f: f64 = t.parse().ok()?;
    (f.fract() == 0.0 && f.abs() < 9.0e15).then_some(f as i64)
}

/// `1`/`0`/`ON`/`OFF` (any case, `+1` too).
pub(crate) fn parse_bool(text: &str) -> Option<bool> {
    let t = trim_reply(text);
    if t.eq_ignore_ascii_case("ON") {
        return Some(true);
    }
    if t.eq_ignore_ascii_case("OFF") {
        return Some(false);
    }
    match parse_i64(t)? {
        0 => Some(false),
        1 => Some(true),
        _ => None,
    }
}

/// A string response: the quotes of `"text"` removed and doubled quotes undone; unquoted text is
/// returned as is.
pub(crate) fn parse_string(text: &str) -> String {
    let t = trim_reply(text);
    for q in ['"', '\''] {
        if t.len() >= 2 && t.starts_with(q) && t.ends_with(q) {
            let inner = &t[1..t.len() - 1];
            let doubled: String = [q, q].iter().collect();
            return inner.replace(&doubled, &q.to_string());
        }
    }
    t.to_string()
}

/// The parsed reply to `*IDN?`: `manufacturer,model,serial,firmware`.
#[derive(Debug, Clone, PartialEq, Eq, serde::Serialize)]
pub struct Identity {
    pub manufacturer: String,
    pub model: String,
    pub serial: String,
    pub firmware: String,
}

impl std::fmt::Display for Identity {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "{},{},{},{}",
            self.manufacturer, self.model, self.serial, self.firmware
        )
    }
}

/// Parses `*IDN?`; a firmware field containing commas is kept whole.
pub fn parse_idn(text: &str) -> Option<Identity> {
    let t = without_idn_header(trim_reply(text));
    let mut it = t.splitn(4, ',');
    let manufacturer = it.next()?.trim();
    let model = it.next()?.trim();
    let serial = it.next()?.trim();
    let firmware = it.next()?.trim();
    if manufacturer.is_empty() || model.is_empty() {
        return None;
    }
    Some(Identity {
        manufacturer: manufacturer.to_string(),
        model: model.to_string(),
        serial: serial.to_string(),
        firmware: firmware.to_string(),
    })
}

/// An `*IDN?` reply without the response header a LeCroy adds with headers on (its power-on
/// `COMM_HEADER SHORT`: `*IDN LECROY,...`): the header is not the manufacturer.
pub fn without_idn_header(reply: &str) -> &str {
    match reply.split_once(char::is_whitespace) {
        Some((head, rest)) if head.eq_ignore_ascii_case("*IDN") => rest.trim_start(),
        _ => reply,
    }
}

/// Parses a `SYST:ERR?` reply, `<code>,"<text>"`, or an error register's `<code>` (LeCroy
/// `CMR?`), with or without a response header (`CMR 1`, `:SYST:ERR -113,"..."`). Code 0 means
/// the queue is empty.
pub fn parse_error_entry(text: &str) -> Option<DeviceError> {
    let t = without_header(trim_reply(text));
    let (code, message) = match t.split_once(',') {
        Some((c, m)) => (c, m),
        None => (t, ""),
    };
    let code = parse_i64(code)?;
    let code = i32::try_from(code).ok()?;
    Some(DeviceError {
        code,
        message: parse_string(message),
    })
}

/// A response with its header word removed (`CMR 1` -> `1`): instruments with response headers on
/// repeat the query's header before the value.
pub(crate) fn without_header(t: &str) -> &str {
    match t.split_once(char::is_whitespace) {
        Some((head, rest))
            if head.starts_with(|c: char| c.is_ascii_alphabetic() || c == ':' || c == '*') =>
        {
            rest.trim_start()
        }
        _ => t,
    }
}

/// The meaning of a code read from an error register that carries no text: LeCroy's command
/// error register `CMR?` and execution error register `EXR?` (the X-Stream remote control
/// manual's legacy command set \[V-src\]), else a plain description. Drivers reading these
/// registers themselves use the same table.
pub(crate) fn register_error_text(query: &str, code: i32) -> &'static str {
    let register = query.trim();
    if register.eq_ignore_ascii_case("CMR?") {
        command_register_text(code)
    } else if register.eq_ignore_ascii_case("EXR?") {
        execution_register_text(code)
    } else {
        "error reported without text"
    }
}

fn command_register_text(code: i32) -> &'static str {
    match code {
        1 => "command error: unrecognized command/query header",
        2 => "command error: illegal header path",
        3 => "command error: illegal number",
        4 => "command error: illegal number suffix",
        5 => "command error: unrecognized keyword",
        6 => "command error: string error",
        7 => "command error: GET embedded in another message",
        10 => "command error: arbitrary data block expected",
        11 => "command error: non-digit character in byte count field of arbitrary data block",
        12 => "command error: EOI detected during definite length data block transfer",
        13 => "command error: extra bytes detected during definite length data block transfer",
        _ => "command error",
    }
}

fn execution_register_text(code: i32) -> &'static str {
    match code {
        21 => "execution error: permission error",
        22 => "execution error: environment error",
        23 => "execution error: option error",
        24 => "execution error: unresolved parsing error",
        25 => "execution error: parameter error",
        26 => "execution error: command not implemented",
        27 => "execution error: parameter missing",
        30 => "execution error: hex data error",
        31 => "execution error: waveform error",
        32 => "execution error: waveform descriptor error",
        33 => "execution error: waveform text error",
        34 => "execution error: waveform time error",
        35 => "execution error: waveform data error",
        36 => "execution error: panel setup error",
        _ => "execution error",
    }
}

/// How a block's length is given.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum BlockForm {
    /// `#<d><len><bytes>`
    Definite,
    /// `#0<bytes>` then NL^END
    Indefinite,
}

/// An arbitrary block inside a reply. The payload is a view into the received message: it was
/// read once from the socket and is never copied again.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Block {
    message: Bytes,
    /// Offset of the `#` that starts the block.
    hash: usize,
    payload: Range<usize>,
    pub form: BlockForm,
}

impl Block {
    pub fn payload(&self) -> &[u8] {
        &self.message[self.payload.clone()]
    }

    /// The payload as shared bytes (no copy).
    pub fn into_payload(self) -> Bytes {
        self.message.slice(self.payload)
    }

    /// What preceded the `#` (e.g. `ALL,` for a LeCroy `WF? ALL`).
    pub fn prefix(&self) -> &[u8] {
        &self.message[..self.hash]
    }

    pub fn len(&self) -> usize {
        self.payload.len()
    }

    pub fn is_empty(&self) -> bool {
        self.payload.is_empty()
    }
}

/// Why a reply is not a block.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum BlockProblem {
    NoBlock,
    BadLengthDigits,
    Truncated { announced: u64, present: u64 },
}

impl BlockProblem {
    pub fn describe(&self) -> String {
        match self {
            BlockProblem::NoBlock => "an IEEE 488.2 block (#<d><len><bytes> or #0<bytes>)".into(),
            BlockProblem::BadLengthDigits => "a block with a valid length field".into(),
            BlockProblem::Truncated { announced, present } => {
                format!("a whole block ({announced} bytes announced, {present} received)")
            }
        }
    }
}

/// Finds the first block in a reply (after an optional prefix such as `ALL,`).
pub fn parse_block(message: Bytes) -> Result<Block, BlockProblem> {
    let hash = message
        .windows(2)
        .position(|w| w[0] == b'#' && w[1].is_ascii_digit())
        .ok_or(BlockProblem::NoBlock)?;
    let digits = usize::from(message[hash + 1] - b'0');
    if digits == 0 {
        let start = hash + 2;
        let mut end = message.len();
        if message[start..end].ends_with(b"\n") {
            end -= 1;
        }
        return Ok(Block {
            hash,
            payload: start..end,
            message,
            form: BlockForm::Indefinite,
        });
    }
    let len_field = message
        .get(hash + 2..hash + 2 + digits)
        .ok_or(BlockProblem::BadLengthDigits)?;
    if !len_field.iter().all(u8::is_ascii_digit) {
        return Err(BlockProblem::BadLengthDigits);
    }
    let len: u64 = std::str::from_utf8(len_field)
        .ok()
        .and_then(|s| s.parse().ok())
        .ok_or(BlockProblem::BadLengthDigits)?;
    let start = hash + 2 + digits;
    let present = (message.len() - start) as u64;
    if present < len {
        return Err(BlockProblem::Truncated {
            announced: len,
            present,
        });
    }
    Ok(Block {
        hash,
        payload: start..start + len as usize,
        message,
        form: BlockForm::Definite,
    })
}

/// The `#<d><len>` header of a definite block, or `None` above 999 999 999 bytes.
pub(crate) fn definite_header(len: u64) -> Option<String> {
    if len > 999_999_999 {
        return None;
    }
    let digits = len.to_string();
    Some(format!("#{}{}", digits.len(), digits))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_lecroy_response_header_is_not_the_manufacturer() {
        let idn = parse_idn("*IDN LECROY,LABMASTER10-36ZI-A,LCRY1,9.8.0\n").unwrap();
        assert_eq!(idn.manufacturer, "LECROY");
        assert_eq!(idn.model, "LABMASTER10-36ZI-A");
        assert_eq!(without_idn_header("A,B,C,D"), "A,B,C,D");
    }

    #[test]
    fn numbers_and_booleans() {
        assert_eq!(parse_f64("+6.4000000000E+10\n"), Some(6.4e10));
        assert_eq!(parse_f64("abc"), None);
        assert_eq!(parse_i64("+1.00000000E+003\r\n"), Some(1000));
        assert_eq!(parse_i64("1.5"), None);
        assert_eq!(parse_i64("-42"), Some(-42));
        assert_eq!(parse_bool("ON\n"), Some(true));
        assert_eq!(parse_bool("+0"), Some(false));
        assert_eq!(parse_bool("2"), None);
        assert_eq!(parse_string("\"say \"\"hi\"\"\"\n"), "say \"hi\"");
        assert_eq!(parse_string("MARK"), "MARK");
    }

    #[test]
    fn identity() {
        let id = parse_idn("Keysight Technologies,M8195A,MY12345,4.0.1.2\n").unwrap();
        assert_eq!(id.manufacturer, "Keysight Technologies");
        assert_eq!(id.model, "M8195A");
        assert_eq!(id.serial, "MY12345");
        assert_eq!(id.firmware, "4.0.1.2");
        assert_eq!(
            parse_idn("LECROY,LABMASTER,1,9.1,extra").unwrap().firmware,
            "9.1,extra"
        );
        assert!(parse_idn("just text").is_none());
    }

    #[test]
    fn error_entries() {
        assert_eq!(
            parse_error_entry("-222,\"Data out of range\"\n").unwrap(),
            DeviceError {
                code: -222,
                message: "Data out of range".into()
            }
        );
        assert_eq!(parse_error_entry("+0,\"No error\"").unwrap().code, 0);
        assert_eq!(parse_error_entry("0").unwrap().code, 0);
        assert!(parse_error_entry("No error").is_none());
        // Error registers, with response headers on or off.
        assert_eq!(parse_error_entry("CMR 1\n").unwrap().code, 1);
        assert_eq!(parse_error_entry("1").unwrap().code, 1);
        assert_eq!(parse_error_entry("CMR 0").unwrap().code, 0);
        let e = parse_error_entry(":SYST:ERR -113,\"Undefined header\"").unwrap();
        assert_eq!((e.code, e.message.as_str()), (-113, "Undefined header"));
        assert_eq!(
            register_error_text("CMR?", 1),
            "command error: unrecognized command/query header"
        );
        assert_eq!(
            register_error_text("EXR?", 25),
            "execution error: parameter error"
        );
        assert_eq!(
            register_error_text("SYST:ERR?", 1),
            "error reported without text"
        );
    }

    #[test]
    fn blocks() {
        let b = parse_block(Bytes::from_static(b"ALL,#15a\nb\ncX\n")).unwrap();
        assert_eq!(b.payload(), b"a\nb\nc");
        assert_eq!(b.prefix(), b"ALL,");
        assert_eq!(b.form, BlockForm::Definite);
        let b = parse_block(Bytes::from_static(b"#0xyz\n")).unwrap();
        assert_eq!(b.payload(), b"xyz");
        assert_eq!(b.form, BlockForm::Indefinite);
        assert!(b.prefix().is_empty());
        assert_eq!(
            parse_block(Bytes::from_static(b"#15ab")),
            Err(BlockProblem::Truncated {
                announced: 5,
                present: 2
            })
        );
        assert_eq!(
            parse_block(Bytes::from_static(b"#3a1")),
            Err(BlockProblem::BadLengthDigits)
        );
        assert_eq!(
            parse_block(Bytes::from_static(b"1.0")),
            Err(BlockProblem::NoBlock)
        );
        assert_eq!(definite_header(0).unwrap(), "#10");
        assert_eq!(definite_header(67_108_864).unwrap(), "#867108864");
        assert!(definite_header(1_000_000_000).is_none());
    }

    proptest::proptest! {
        #[test]
        fn reply_parsers_never_panic(data in proptest::collection::vec(proptest::num::u8::ANY, 0..64)) {
            let text = String::from_utf8_lossy(&data);
            let _ = parse_f64(&text);
            let _ = parse_i64(&text);
            let _ = parse_bool(&text);
            let _ = parse_idn(&text);
            let _ = parse_error_entry(&text);
            let _ = parse_string(&text);
            let _ = parse_block(Bytes::from(data));
        }

        #[test]
        fn definite_blocks_round_trip(payload in proptest::collection::vec(proptest::num::u8::ANY, 0..300)) {
            let header = definite_header(payload.len() as u64).unwrap();
            let wire = [header.as_bytes(), &payload, b"\n"].concat();
            let block = parse_block(Bytes::from(wire)).unwrap();
            proptest::prop_assert_eq!(block.payload(), &payload[..]);
        }
    }
}
