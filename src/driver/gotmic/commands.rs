//! Every request spelling of the project-defined Gotmic line protocol (instruments.md section 5), in
//! one place. Register addresses come from the catalog, never from here.

pub const IDN: &str = "*IDN?";

pub fn read(address: u8) -> String {
    format!("R {address:02X}")
}

pub fn write(address: u8, value: u16) -> String {
    format!("W {address:02X} {value:04X}")
}

/// Parses `OK <hex4>`.
pub fn parse_value(reply: &str) -> Option<u16> {
    let hex = reply.trim().strip_prefix("OK ")?;
    (hex.len() == 4)
        .then(|| u16::from_str_radix(hex, 16).ok())
        .flatten()
}

/// Parses `ERR <code> <text>` into code and text.
pub fn parse_error(reply: &str) -> Option<(u8, String)> {
    let rest = reply.trim().strip_prefix("ERR ")?;
    let (code, text) = rest.split_once(' ').unwrap_or((rest, ""));
    Some((code.parse().ok()?, text.to_string()))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn spellings_and_replies() {
        assert_eq!(read(3), "R 03");
        assert_eq!(write(2, 0xF), "W 02 000F");
        assert_eq!(parse_value("OK 003F\n"), Some(0x3F));
        assert_eq!(parse_value("OK 3F"), None);
        assert_eq!(
            parse_error("ERR 5 not allowed: interlock open"),
            Some((5, "not allowed: interlock open".into()))
        );
        assert_eq!(parse_error("OK"), None);
    }
}
