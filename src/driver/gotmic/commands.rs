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

pub const IDN: &str = "*IDN?";
/// Switches CRC framing on. Sent unframed: a module with CRC off switches it on and answers `OK`;
/// a module already in CRC mode refuses the unframed line with the CRC error and stays on. Either
/// way CRC framing is on afterwards.
pub const CRC_ON: &str = "CRC ON";

/// CRC-8, MSB first, no reflection, no final XOR (CRC-8/SMBUS for poly 0x07, init 0x00).
pub fn crc8(data: &[u8], poly: u8, init: u8) -> u8 {
    let mut crc = init;
    for byte in data {
        crc ^= byte;
        for _ in 0..8 {
            crc = if crc & 0x80 != 0 {
                (crc << 1) ^ poly
            } else {
                crc << 1
            };
        }
    }
    crc
}

/// A request with its CRC suffix: `R 03*hh`.
pub fn framed(line: &str, poly: u8, init: u8) -> String {
    format!("{line}*{:02X}", crc8(line.as_bytes(), poly, init))
}

/// Checks and strips the CRC suffix of a reply; `None` when it is missing or wrong.
pub fn unframe(reply: &str, poly: u8, init: u8) -> Option<&str> {
    let reply = reply.trim();
    let (body, sum) = reply.rsplit_once('*')?;
    let got = u8::from_str_radix(sum, 16)
        .ok()
        .filter(|_| sum.len() == 2)?;
    (got == crc8(body.as_bytes(), poly, init)).then_some(body)
}

pub fn read(address: u8) -> String {
    format!("R {address:02X}")
}

pub fn write(address: u8, value: u16) -> String {
    format!("W {address:02X} {value:04X}")
}

/// A reply line, parsed.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Reply {
    /// `OK` with the value of a read, if any.
    Ok(Option<u16>),
    /// `ERR <code> <text>`.
    Err { code: i32, text: String },
}

/// Parses one reply line; `None` when it is neither `OK [hhhh]` nor `ERR <code> <text>`.
pub fn parse_reply(line: &str) -> Option<Reply> {
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

    #[test]
    fn crc_framing() {
        assert_eq!(crc8(b"123456789", 0x07, 0x00), 0xF4);
        let line = framed("R 03", 0x07, 0);
        assert_eq!(unframe(&line, 0x07, 0), Some("R 03"));
        assert_eq!(unframe("OK 003F*00", 0x07, 0), None);
        assert_eq!(unframe("OK 003F", 0x07, 0), None);
    }
}
