//! Line protocols in which every request gets exactly one reply line, unlike IEEE 488.2 where only
//! queries answer: the Gotmic modules' project-defined register protocol (instruments/README.md,
//! "Gotmic E-band Tx and Rx"): `R <reg>` answers `OK <value>`, `W <reg> <value>`
//! answers `OK`, a refused request answers `ERR <code> <text>`, and after `CRC ON` every line in
//! both directions ends in `*<hh>`, a CRC-8 of the text before the `*`.
//!
//! The session learns whether the device has CRC on from its replies: a reply with a valid CRC
//! suffix means it has, and a plain request it refused is sent again framed. Pure functions here;
//! the exchange itself is in [`Session`](super::Session).

use super::error::DeviceError;

/// CRC-8 parameters: MSB first, no reflection, no final XOR.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Crc8 {
    pub poly: u8,
    pub init: u8,
}

impl Crc8 {
    pub(crate) fn checksum(&self, data: &[u8]) -> u8 {
        let mut crc = self.init;
        for byte in data {
            crc ^= byte;
            for _ in 0..8 {
                crc = if crc & 0x80 != 0 {
                    (crc << 1) ^ self.poly
                } else {
                    crc << 1
                };
            }
        }
        crc
    }

    /// `line*<hh>`.
    pub fn frame(&self, line: &str) -> String {
        format!("{line}*{:02X}", self.checksum(line.as_bytes()))
    }

    /// The text before a valid `*<hh>` suffix; `None` when the suffix is missing or wrong.
    pub fn unframe<'a>(&self, line: &'a str) -> Option<&'a str> {
        let (body, sum) = line.rsplit_once('*')?;
        if sum.len() != 2 {
            return None;
        }
        let got = u8::from_str_radix(sum, 16).ok()?;
        (got == self.checksum(body.as_bytes())).then_some(body)
    }
}

/// A device that answers every request with one line.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct LineProtocol {
    /// The CRC the device uses once switched on (`CRC ON`); `None` for devices without one.
    pub crc: Option<Crc8>,
}

/// What a reply line says once its CRC (if any) is checked and removed.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum LineReply {
    /// Any reply but a refusal.
    Answer(String),
    /// `ERR <code> <text>`.
    Refused(DeviceError),
}

/// Classifies a reply line (CRC already removed).
pub fn classify(line: &str) -> LineReply {
    let line = line.trim();
    if let Some(rest) = line.strip_prefix("ERR") {
        let rest = rest.trim_start();
        let (code, text) = rest.split_once(' ').unwrap_or((rest, ""));
        if let Ok(code) = code.parse::<i32>() {
            return LineReply::Refused(DeviceError {
                code,
                message: text.trim().to_string(),
            });
        }
    }
    LineReply::Answer(line.to_string())
}

/// Whether `request` switches the device's CRC framing: `Some(true)` for `CRC ON`.
pub(crate) fn crc_switch(request: &str) -> Option<bool> {
    let words: Vec<&str> = request.split_whitespace().collect();
    match words.as_slice() {
        [crc, mode] if crc.eq_ignore_ascii_case("CRC") => {
            if mode.eq_ignore_ascii_case("ON") {
                Some(true)
            } else if mode.eq_ignore_ascii_case("OFF") {
                Some(false)
            } else {
                None
            }
        }
        _ => None,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const SMBUS: Crc8 = Crc8 {
        poly: 0x07,
        init: 0x00,
    };

    #[test]
    fn crc8_check_value_and_framing() {
        // The catalogue check value of CRC-8/SMBUS.
        assert_eq!(SMBUS.checksum(b"123456789"), 0xF4);
        let framed = SMBUS.frame("R 03");
        assert_eq!(SMBUS.unframe(&framed), Some("R 03"));
        assert_eq!(SMBUS.unframe("OK 003F"), None);
        assert_eq!(SMBUS.unframe("OK 003F*0"), None);
        assert_eq!(SMBUS.unframe("OK 003F*ZZ"), None);
        let wrong = format!("OK 003F*{:02X}", SMBUS.checksum(b"OK 003F") ^ 1);
        assert_eq!(SMBUS.unframe(&wrong), None);
    }

    #[test]
    fn replies_are_classified() {
        assert_eq!(classify("OK 003F"), LineReply::Answer("OK 003F".into()));
        assert_eq!(
            classify("ERR 2 unknown register: 0x7F"),
            LineReply::Refused(DeviceError {
                code: 2,
                message: "unknown register: 0x7F".into()
            })
        );
        assert_eq!(classify("ERRATIC"), LineReply::Answer("ERRATIC".into()));
        assert_eq!(crc_switch("crc on"), Some(true));
        assert_eq!(crc_switch("CRC OFF"), Some(false));
        assert_eq!(crc_switch("CRC"), None);
        assert_eq!(crc_switch("R 03"), None);
    }
}
