//! The spellings of the project-defined Gotmic line protocol (instruments.md section 5), in one
//! place. This is NOT the vendor's protocol (which is not public): it is radbench's own documented
//! register-over-serial protocol, spoken by the mock_lab emulator, and meant to be replaced behind
//! the same driver when the real one is known. One request per line, one reply line per request:
//!
//! | request | reply |
//! |---|---|
//! | `*IDN?` | `<manufacturer>,<model>,<serial>,<firmware>` |
//! | `R <reg hex2>` | `OK <value hex4>` |
//! | `W <reg hex2> <value hex4>` | `OK` |
//! | anything refused | `ERR <code> <text>` |

pub(crate) const IDN: &str = "*IDN?";
/// Switches CRC framing on. Sent unframed: a module with CRC off switches it on and answers `OK`;
/// a module already in CRC mode refuses the unframed line with the CRC error and stays on. Either
/// way CRC framing is on afterwards.
pub(crate) const CRC_ON: &str = "CRC ON";

// CRC framing (`*<hh>` suffixes) is the session's [`Crc8`](crate::session::Crc8): one CRC-8 for
// the driver and the session's line protocol.

pub(crate) fn read(address: u8) -> String {
    format!("R {address:02X}")
}

pub(crate) fn write(address: u8, value: u16) -> String {
    format!("W {address:02X} {value:04X}")
}

/// A reply line, parsed.
#[derive(Debug, Clone, PartialEq, Eq)]
pub(crate) enum Reply {
    /// `OK` with the value of a read, if any.
    Ok(Option<u16>),
    /// `ERR <code> <text>`.
    Err { code: i32, text: String },
}

/// Parses one reply line; `None` when it is neither `OK [hhhh]` nor `ERR <code> <text>`.
pub(crate) fn parse_reply(line: &str) -> Option<Reply> {
    let line = line.trim();
    if let Some(rest) = line.strip_prefix("ERR") {
        let rest = rest.trim_start();
        let (code, text) = rest.split_once(' ').unwrap_or((rest, ""));
        return Some(Reply::Err {
            code: code.parse().ok()?,
            text: text.trim().to_string(),
        });
    }
    let rest = line.strip_prefix("OK")?;
    let rest = rest.trim();
    if rest.is_empty() {
        return Some(Reply::Ok(None));
    }
    if rest.len() > 4 || !rest.chars().all(|c| c.is_ascii_hexdigit()) {
        return None;
    }
    u16::from_str_radix(rest, 16)
        .ok()
        .map(|v| Reply::Ok(Some(v)))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn requests_and_replies() {
        assert_eq!(read(3), "R 03");
        assert_eq!(write(2, 0xF), "W 02 000F");
        assert_eq!(parse_reply("OK 003F"), Some(Reply::Ok(Some(63))));
        assert_eq!(parse_reply("OK"), Some(Reply::Ok(None)));
        assert_eq!(
            parse_reply("ERR 5 not allowed"),
            Some(Reply::Err {
                code: 5,
                text: "not allowed".into()
            })
        );
        assert_eq!(parse_reply("OK 12345"), None);
        assert_eq!(parse_reply("hello"), None);
        assert_eq!(parse_reply("ERR x y"), None);
    }
}
