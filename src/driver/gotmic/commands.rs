//! The Gotmic line protocol's grammar, read from the catalog's `[protocol]` (instruments/README.md,
//! "The line protocol as data"): the identity request, the register read and write requests, the
//! reply words and how numbers are written. The built-in description is radbench's own
//! project-defined protocol, NOT the vendor's (which is not public); a lab whose modules speak
//! another one describes it in an instrument file, without Rust. One request per line, one reply
//! line per request:
//!
//! | request (built-in spelling) | reply |
//! |---|---|
//! | `*IDN?` (`identify`) | `<manufacturer>,<model>,<serial>,<firmware>` |
//! | `R <reg hex2>` (`read`) | `OK <value hex4>` (`reply_ok`, `value_format`) |
//! | `W <reg hex2> <value hex4>` (`write`) | `OK` |
//! | anything refused | `ERR <code> <text>` (`reply_error`) |

use crate::catalog::{InstrumentModel, LineProtocol};

/// The catalog's grammar of one module model.
#[derive(Debug, Clone)]
pub(crate) struct Grammar {
    p: LineProtocol,
}

/// A reply line, parsed.
#[derive(Debug, Clone, PartialEq, Eq)]
pub(crate) enum Reply {
    /// `OK` with the value of a read, if any.
    Ok(Option<u16>),
    /// `ERR <code> <text>`.
    Err { code: i32, text: String },
}

impl Grammar {
    /// The model's grammar (the built-in spelling when it has no `[protocol]`).
    pub(crate) fn of(model: &InstrumentModel) -> Grammar {
        Grammar {
            p: model.protocol.clone().unwrap_or_default(),
        }
    }

    pub(crate) fn identify(&self) -> &str {
        &self.p.identify
    }

    /// The request that switches the checksum on; `None` when the module always uses it.
    pub(crate) fn checksum_on(&self) -> Option<&str> {
        Some(self.p.checksum_on.as_str()).filter(|s| !s.is_empty())
    }

    /// `body` with the request prefix.
    pub(crate) fn request(&self, body: &str) -> String {
        format!("{}{body}", self.p.request_prefix)
    }

    /// The reply without its prefix; `None` when the prefix is missing.
    pub(crate) fn reply<'a>(&self, line: &'a str) -> Option<&'a str> {
        line.trim().strip_prefix(self.p.reply_prefix.as_str())
    }

    pub(crate) fn read(&self, address: u8) -> String {
        self.p.read.replace(
            "{address}",
            &self.p.address_format.write(u16::from(address)),
        )
    }

    pub(crate) fn write(&self, address: u8, value: u16) -> String {
        self.p
            .write
            .replace(
                "{address}",
                &self.p.address_format.write(u16::from(address)),
            )
            .replace("{value}", &self.p.value_format.write(value))
    }

    /// What an accepted and a refused reply look like, for messages.
    pub(crate) fn reply_forms(&self) -> String {
        format!(
            "{ok} [value] or {err} <code> <text>",
            ok = self.p.reply_ok,
            err = self.p.reply_error
        )
    }

    /// Parses one reply line (prefix removed); `None` when it is neither an acceptance (with an
    /// optional value in the catalog's format) nor a refusal with a numeric code.
    pub(crate) fn parse_reply(&self, line: &str) -> Option<Reply> {
        let line = line.trim();
        if let Some(rest) = line.strip_prefix(self.p.reply_error.as_str()) {
            let rest = rest.trim_start();
            let (code, text) = rest.split_once(' ').unwrap_or((rest, ""));
            return Some(Reply::Err {
                code: code.parse().ok()?,
                text: text.trim().to_string(),
            });
        }
        let rest = line.strip_prefix(self.p.reply_ok.as_str())?.trim();
        if rest.is_empty() {
            return Some(Reply::Ok(None));
        }
        self.p.value_format.read(rest).map(|v| Reply::Ok(Some(v)))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::catalog::{Checksum, NumberFormat};

    #[test]
    fn the_built_in_spelling() {
        let g = Grammar {
            p: LineProtocol::default(),
        };
        assert_eq!(g.read(3), "R 03");
        assert_eq!(g.write(2, 0xF), "W 02 000F");
        assert_eq!(g.parse_reply("OK 003F"), Some(Reply::Ok(Some(63))));
        assert_eq!(g.parse_reply("OK"), Some(Reply::Ok(None)));
        assert_eq!(
            g.parse_reply("ERR 5 not allowed"),
            Some(Reply::Err {
                code: 5,
                text: "not allowed".into()
            })
        );
        assert_eq!(g.parse_reply("OK 12345"), None);
        assert_eq!(g.parse_reply("hello"), None);
        assert_eq!(g.parse_reply("ERR x y"), None);
    }

    #[test]
    fn another_spelling_from_data() {
        let g = Grammar {
            p: LineProtocol {
                checksum: Checksum::None,
                read: "GET {address}".into(),
                write: "SET {address}={value}".into(),
                address_format: NumberFormat::Dec,
                value_format: NumberFormat::Dec,
                reply_ok: "ACK".into(),
                reply_error: "NAK".into(),
                request_prefix: "#1 ".into(),
                ..LineProtocol::default()
            },
        };
        assert_eq!(g.read(18), "GET 18");
        assert_eq!(g.write(18, 63), "SET 18=63");
        assert_eq!(g.request("GET 18"), "#1 GET 18");
        assert_eq!(g.parse_reply("ACK 63"), Some(Reply::Ok(Some(63))));
        assert_eq!(g.parse_reply("ACK 3F"), None);
        assert_eq!(
            g.parse_reply("NAK 2 unknown register"),
            Some(Reply::Err {
                code: 2,
                text: "unknown register".into()
            })
        );
    }
}
