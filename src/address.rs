//! VISA-style resource strings, parsed into a [`Resource`] and printed back identically.
//!
//! Accepted forms (keywords are case-insensitive and printed in the canonical case shown here;
//! host names, device names and serial device paths are kept exactly as written):
//!
//! | form | protocol |
//! |---|---|
//! | `TCPIP[n]::host::port::SOCKET` | raw socket, messages end with a newline |
//! | `TCPIP[n]::host[,port]::device[::INSTR]`, `TCPIP[n]::host[,port]::INSTR` | VXI-11 (device `inst0` when not given); an explicit port skips the portmapper |
//! | `TCPIP[n]::host::hislipN[,port][::INSTR]` | HiSLIP (default port 4880) |
//! | `VICP::host[,port][::INSTR]` | LeCroy VICP (default port 1861) |
//! | `ASRL<device>::INSTR` | serial; speed and framing come from the bench file |
//!
//! The optional parts are those pyvisa and instrument manuals leave out: `TCPIP0::host::INSTR`
//! (device `inst0` implied), `TCPIP0::host::inst0`, `TCPIP0::host::hislip0,4880`. Each prints back
//! the way it was written. IPv6 hosts are written in brackets: `TCPIP::[::1]::5025::SOCKET`.

use std::fmt;
use std::str::FromStr;

/// The IANA port of HiSLIP.
pub(crate) const HISLIP_DEFAULT_PORT: u16 = 4880;
/// LeCroy's VICP port.
pub(crate) const VICP_DEFAULT_PORT: u16 = 1861;
/// The ONC-RPC portmapper port, asked for the VXI-11 core channel when no port is given.
pub(crate) const PORTMAPPER_PORT: u16 = 111;

/// The accepted forms, shown in every parse error.
pub(crate) const ACCEPTED_FORMS: &str =
    "TCPIP[n]::host::port::SOCKET, TCPIP[n]::host[,port][::inst0]::INSTR, TCPIP[n]::host[,port]::inst0, \
TCPIP[n]::host::hislipN[,port][::INSTR], VICP::host[,port][::INSTR], ASRL<device>::INSTR";

/// A parsed instrument resource string.
#[derive(Debug, Clone, PartialEq, Eq, Hash)]
pub enum Resource {
    /// `TCPIP[n]::host::port::SOCKET`
    Socket {
        board: Option<u32>,
        host: String,
        port: u16,
    },
    /// `TCPIP[n]::host[,port][::device][::INSTR]` (VXI-11)
    Vxi11 {
        board: Option<u32>,
        host: String,
        /// An explicit core-channel port: the portmapper is skipped.
        port: Option<u16>,
        /// The VXI-11 device name, e.g. `inst0` or `gpib0,5`.
        device: String,
        /// The string left the device out (`TCPIP0::host::INSTR`): `inst0`, not printed.
        device_implied: bool,
        /// Whether the string ended in `::INSTR` (kept so it prints back identically).
        instr_suffix: bool,
    },
    /// `TCPIP[n]::host::hislipN[,port][::INSTR]`
    Hislip {
        board: Option<u32>,
        host: String,
        /// The sub-address index N of `hislipN`.
        index: u32,
        port: Option<u16>,
        /// Whether the string ended in `::INSTR` (kept so it prints back identically).
        instr_suffix: bool,
    },
    /// `VICP::host[,port][::INSTR]`
    Vicp {
        host: String,
        port: Option<u16>,
        /// Whether the string ended in `::INSTR` (kept so it prints back identically).
        instr_suffix: bool,
    },
    /// `ASRL<device>::INSTR`
    Serial { device: String },
}

/// A resource string that is not one of the accepted forms.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("resource string `{input}`: {reason}; accepted forms: {ACCEPTED_FORMS}")]
pub struct AddressError {
    pub input: String,
    pub reason: String,
}

impl crate::exit::Classify for AddressError {
    fn exit_class(&self) -> crate::exit::ExitClass {
        crate::exit::ExitClass::BadInput
    }
}

impl Resource {
    /// The host for network resources, `None` for serial.
    pub fn host(&self) -> Option<&str> {
        match self {
            Resource::Socket { host, .. }
            | Resource::Vxi11 { host, .. }
            | Resource::Hislip { host, .. }
            | Resource::Vicp { host, .. } => Some(host),
            Resource::Serial { .. } => None,
        }
    }

    /// The HiSLIP sub-address sent in Initialize, e.g. `hislip0`.
    pub(crate) fn hislip_sub_address(index: u32) -> String {
        format!("hislip{index}")
    }

    /// A short protocol name for logs and the I/O journal.
    pub fn protocol(&self) -> &'static str {
        match self {
            Resource::Socket { .. } => "socket",
            Resource::Vxi11 { .. } => "vxi11",
            Resource::Hislip { .. } => "hislip",
            Resource::Vicp { .. } => "vicp",
            Resource::Serial { .. } => "serial",
        }
    }
}

impl FromStr for Resource {
    type Err = AddressError;

    fn from_str(input: &str) -> Result<Self, Self::Err> {
        let err = |reason: &str| AddressError {
            input: input.to_string(),
            reason: reason.to_string(),
        };
        let trimmed = input.trim();
        if trimmed.is_empty() {
            return Err(err("it is empty"));
        }
        let parts = split_parts(trimmed).map_err(|r| err(&r))?;
        let first = parts[0].as_str();
        let upper = first.to_ascii_uppercase();
        if let Some(rest) = upper.strip_prefix("TCPIP") {
            let board = parse_board(rest).ok_or_else(|| {
                err("`TCPIP` may only be followed by a board number, e.g. `TCPIP0`")
            })?;
            parse_tcpip(board, &parts[1..]).map_err(|r| err(&r))
        } else if upper == "VICP" {
            parse_vicp(&parts[1..]).map_err(|r| err(&r))
        } else if upper.starts_with("ASRL") {
            let device = &first[4..];
            if device.is_empty() {
                return Err(err(
                    "`ASRL` needs a device, e.g. `ASRL/dev/ttyUSB0::INSTR` or `ASRL1::INSTR`",
                ));
            }
            match parts.len() {
                2 if parts[1].eq_ignore_ascii_case("INSTR") => Ok(Resource::Serial {
                    device: device.to_string(),
                }),
                _ => Err(err("a serial resource is `ASRL<device>::INSTR`")),
            }
        } else {
            let letters = first.trim_end_matches(|c: char| c.is_ascii_digit());
            Err(err(&format!(
                "unknown interface `{first}` (expected TCPIP, VICP or ASRL){}",
                crate::exit::did_you_mean(letters, ["TCPIP", "VICP", "ASRL"])
            )))
        }
    }
}

/// Splits on `::`, keeping bracketed IPv6 hosts (`[::1]`) whole.
fn split_parts(s: &str) -> Result<Vec<String>, String> {
    let mut parts = Vec::new();
    let mut current = String::new();
    let mut chars = s.chars().peekable();
    let mut in_brackets = false;
    while let Some(c) = chars.next() {
        match c {
            '[' => {
                in_brackets = true;
                current.push(c);
            }
            ']' => {
                in_brackets = false;
                current.push(c);
            }
            ':' if !in_brackets && chars.peek() == Some(&':') => {
                chars.next();
                parts.push(std::mem::take(&mut current));
            }
            _ => current.push(c),
        }
    }
    if in_brackets {
        return Err("an IPv6 host is missing its closing `]`".into());
    }
    parts.push(current);
    if parts.iter().any(|p| p.is_empty()) {
        return Err("it has an empty field between `::` separators".into());
    }
    Ok(parts)
}

fn parse_board(rest: &str) -> Option<Option<u32>> {
    if rest.is_empty() {
        Some(None)
    } else if rest.bytes().all(|b| b.is_ascii_digit()) && rest.len() <= 9 {
        rest.parse().ok().map(Some)
    } else {
        None
    }
}

fn parse_port(text: &str, what: &str) -> Result<u16, String> {
    match text.parse::<u16>() {
        Ok(p) if p > 0 && text.bytes().all(|b| b.is_ascii_digit()) => Ok(p),
        _ => Err(format!("{what} `{text}` is not a TCP port (1..65535)")),
    }
}

fn check_host(host: &str) -> Result<(), String> {
    let bad = host.is_empty()
        || host.contains(char::is_whitespace)
        || host.contains(',')
        || (host.starts_with('[') != host.ends_with(']'));
    if bad {
        Err(format!("host `{host}` is not a host name or address"))
    } else {
        Ok(())
    }
}

/// Splits `name[,port]`.
fn split_port(field: &str) -> Result<(String, Option<u16>), String> {
    match field.rsplit_once(',') {
        Some((name, port)) if !name.starts_with("gpib") => {
            Ok((name.to_string(), Some(parse_port(port, "port")?)))
        }
        _ => Ok((field.to_string(), None)),
    }
}

/// The VXI-11 device a `TCPIP::host::INSTR` string means.
pub(crate) const VXI11_DEFAULT_DEVICE: &str = "inst0";

fn parse_tcpip(board: Option<u32>, parts: &[String]) -> Result<Resource, String> {
    let (host_field, middle, instr_suffix) = match parts {
        [] => {
            return Err(
                "a TCPIP resource needs a host, e.g. `TCPIP0::192.168.1.5::INSTR`".to_string(),
            )
        }
        // pyvisa also reads a bare `TCPIP::host` as VXI-11; here it is refused, as a string cut
        // short is likelier than a deliberate abbreviation.
        [host] => {
            return Err(format!(
                "`TCPIP::{host}` needs its resource class: `TCPIP::{host}::INSTR` (VXI-11), \
                 `TCPIP::{host}::hislip0` (HiSLIP) or `TCPIP::{host}::PORT::SOCKET`"
            ))
        }
        [host, last] if last.eq_ignore_ascii_case("INSTR") => (host, None, true),
        [_, last] if last.eq_ignore_ascii_case("SOCKET") => {
            return Err("a raw socket needs its port: `TCPIP::host::5025::SOCKET`".to_string())
        }
        [_, middle] if !middle.is_empty() && middle.bytes().all(|b| b.is_ascii_digit()) => {
            return Err(format!(
                "`{middle}` looks like a port: a raw socket is `TCPIP::host::{middle}::SOCKET`"
            ))
        }
        [host, middle] => (host, Some(middle), false),
        [host, middle, last] if last.eq_ignore_ascii_case("SOCKET") => {
            check_host(host)?;
            return Ok(Resource::Socket {
                board,
                host: host.clone(),
                port: parse_port(middle, "socket port")?,
            });
        }
        [host, middle, last] if last.eq_ignore_ascii_case("INSTR") => (host, Some(middle), true),
        [_, _, last] => {
            return Err(format!(
                "resource class `{last}` is not SOCKET or INSTR{}",
                crate::exit::did_you_mean(last, ["SOCKET", "INSTR"])
            ))
        }
        _ => return Err("a TCPIP resource has at most four `::`-separated fields".to_string()),
    };
    let Some(middle) = middle else {
        let (host, port) = split_port(host_field)?;
        check_host(&host)?;
        return Ok(Resource::Vxi11 {
            board,
            host,
            port,
            device: VXI11_DEFAULT_DEVICE.to_string(),
            device_implied: true,
            instr_suffix,
        });
    };
    let lower = middle.to_ascii_lowercase();
    if let Some(rest) = lower.strip_prefix("hislip") {
        check_host(host_field)?;
        let (index_text, port) = split_port(rest)?;
        let index = index_text
            .parse::<u32>()
            .ok()
            .filter(|_| !index_text.is_empty() && index_text.bytes().all(|b| b.is_ascii_digit()))
            .ok_or_else(|| format!("`{middle}` must be hislipN[,port] with N a number"))?;
        return Ok(Resource::Hislip {
            board,
            host: host_field.clone(),
            index,
            port,
            instr_suffix,
        });
    }
    check_near_miss(middle, instr_suffix)?;
    let (host, port) = split_port(host_field)?;
    check_host(&host)?;
    if middle.contains(char::is_whitespace) {
        return Err(format!("device name `{middle}` contains white space"));
    }
    Ok(Resource::Vxi11 {
        board,
        host,
        port,
        device: middle.clone(),
        device_implied: false,
        instr_suffix,
    })
}

/// Refuses a VXI-11 device name one slip away from a keyword (`hislp0`, `isnt0`, `INSRT`): taken
/// as written it would send the connection to the portmapper (port 111) and fail far from the
/// typo.
fn check_near_miss(middle: &str, instr_suffix: bool) -> Result<(), String> {
    let lower = middle.to_ascii_lowercase();
    let name = lower.trim_end_matches(|c: char| c.is_ascii_digit() || c == ',');
    let number = &middle[name.len()..];
    if !instr_suffix && number.is_empty() && name != "inst" {
        if let Some(class) = crate::exit::nearest(name, ["INSTR", "SOCKET"]) {
            return Err(format!(
                "`{middle}` is not a VXI-11 device or resource class; did you mean `{class}`?"
            ));
        }
    }
    let (keyword, meant) = match crate::exit::nearest(name, ["hislip", "inst"]) {
        Some("hislip") => ("hislip", "HiSLIP"),
        Some(_) => ("inst", "VXI-11"),
        None => return Ok(()),
    };
    let number = if number.is_empty() { "0" } else { number };
    Err(format!(
        "`{middle}` is not a device name radbench knows; did you mean `{keyword}{number}` \
         ({meant})? Taken as a VXI-11 device it would be looked up through the portmapper"
    ))
}

fn parse_vicp(parts: &[String]) -> Result<Resource, String> {
    let (host_field, instr_suffix) = match parts {
        [host] => (host, false),
        [host, class] if class.eq_ignore_ascii_case("INSTR") => (host, true),
        [_, class] => {
            return Err(format!(
                "a VICP resource is `VICP::host[,port][::INSTR]`{}",
                crate::exit::did_you_mean(class, ["INSTR"])
            ))
        }
        _ => return Err("a VICP resource is `VICP::host[,port][::INSTR]`".into()),
    };
    let (host, port) = split_port(host_field)?;
    check_host(&host)?;
    Ok(Resource::Vicp {
        host,
        port,
        instr_suffix,
    })
}

fn board_text(board: &Option<u32>) -> String {
    board.map(|b| b.to_string()).unwrap_or_default()
}

fn port_text(port: &Option<u16>) -> String {
    port.map(|p| format!(",{p}")).unwrap_or_default()
}

fn instr_text(f: &mut fmt::Formatter<'_>, instr_suffix: bool) -> fmt::Result {
    if instr_suffix {
        f.write_str("::INSTR")?;
    }
    Ok(())
}

impl fmt::Display for Resource {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Resource::Socket { board, host, port } => {
                write!(f, "TCPIP{}::{host}::{port}::SOCKET", board_text(board))
            }
            Resource::Vxi11 {
                board,
                host,
                port,
                device,
                device_implied,
                instr_suffix,
            } => {
                write!(f, "TCPIP{}::{host}{}", board_text(board), port_text(port))?;
                if !device_implied {
                    write!(f, "::{device}")?;
                }
                instr_text(f, *instr_suffix)
            }
            Resource::Hislip {
                board,
                host,
                index,
                port,
                instr_suffix,
            } => {
                write!(
                    f,
                    "TCPIP{}::{host}::hislip{index}{}",
                    board_text(board),
                    port_text(port)
                )?;
                instr_text(f, *instr_suffix)
            }
            Resource::Vicp {
                host,
                port,
                instr_suffix,
            } => {
                write!(f, "VICP::{host}{}", port_text(port))?;
                instr_text(f, *instr_suffix)
            }
            Resource::Serial { device } => write!(f, "ASRL{device}::INSTR"),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn round_trip(s: &str) -> Resource {
        let r: Resource = s.parse().unwrap_or_else(|e| panic!("{s}: {e}"));
        assert_eq!(r.to_string(), s, "printed back differently");
        r
    }

    #[test]
    fn canonical_forms_round_trip() {
        assert_eq!(
            round_trip("TCPIP0::192.168.1.5::5025::SOCKET"),
            Resource::Socket {
                board: Some(0),
                host: "192.168.1.5".into(),
                port: 5025
            }
        );
        assert_eq!(
            round_trip("TCPIP::127.0.0.1,19009::inst0::INSTR"),
            Resource::Vxi11 {
                board: None,
                host: "127.0.0.1".into(),
                port: Some(19009),
                device: "inst0".into(),
                device_implied: false,
                instr_suffix: true,
            }
        );
        round_trip("TCPIP0::scope.lab::inst0::INSTR");
        round_trip("TCPIP0::gw::gpib0,5::INSTR");
        assert_eq!(
            round_trip("TCPIP0::localhost::hislip0::INSTR"),
            Resource::Hislip {
                board: Some(0),
                host: "localhost".into(),
                index: 0,
                port: None,
                instr_suffix: true,
            }
        );
        round_trip("TCPIP::127.0.0.1::hislip3,14880::INSTR");
        round_trip("VICP::10.0.0.7");
        round_trip("VICP::10.0.0.7,18610::INSTR");
        round_trip("ASRL/dev/ttyUSB0::INSTR");
        round_trip("ASRL3::INSTR");
        round_trip("TCPIP::[::1]::5025::SOCKET");
    }

    /// The forms pyvisa and instrument manuals print, which leave out the device or `::INSTR`.
    #[test]
    fn short_forms_as_pyvisa_writes_them() {
        let r = round_trip("TCPIP0::192.168.1.5::INSTR");
        assert_eq!(
            r,
            Resource::Vxi11 {
                board: Some(0),
                host: "192.168.1.5".into(),
                port: None,
                device: "inst0".into(),
                device_implied: true,
                instr_suffix: true,
            }
        );
        assert_eq!(r.protocol(), "vxi11");
        let r = round_trip("TCPIP0::192.168.1.5::inst0");
        assert!(
            matches!(r, Resource::Vxi11 { ref device, instr_suffix: false, .. } if device == "inst0")
        );
        round_trip("TCPIP::127.0.0.1,19009::INSTR");
        round_trip("TCPIP::127.0.0.1,19009::gpib0,5");
        let r = round_trip("TCPIP0::host::hislip0");
        assert!(matches!(
            r,
            Resource::Hislip {
                index: 0,
                port: None,
                instr_suffix: false,
                ..
            }
        ));
        let r = round_trip("TCPIP0::host::hislip0,4881");
        assert!(matches!(
            r,
            Resource::Hislip {
                port: Some(4881),
                ..
            }
        ));
        // The user's spelling of keywords is normalised, the rest kept.
        let r: Resource = "tcpip0::Host::HiSLIP2,4881".parse().unwrap();
        assert_eq!(r.to_string(), "TCPIP0::Host::hislip2,4881");
        let r: Resource = "tcpip::h::instr".parse().unwrap();
        assert_eq!(r.to_string(), "TCPIP::h::INSTR");
    }

    #[test]
    fn a_forgotten_socket_suffix_is_named() {
        let e = "TCPIP::x".parse::<Resource>().unwrap_err();
        assert!(e.to_string().contains("TCPIP::x::INSTR"), "{e}");
        let e = "TCPIP::host::5025".parse::<Resource>().unwrap_err();
        assert!(e.to_string().contains("TCPIP::host::5025::SOCKET"), "{e}");
        let e = "TCPIP::host::SOCKET".parse::<Resource>().unwrap_err();
        assert!(e.to_string().contains("needs its port"), "{e}");
    }

    #[test]
    fn keywords_are_case_insensitive() {
        let r: Resource = "tcpip0::host::hislip1::instr".parse().unwrap();
        assert_eq!(r.to_string(), "TCPIP0::host::hislip1::INSTR");
        let r: Resource = "vicp::h::instr".parse().unwrap();
        assert_eq!(r.to_string(), "VICP::h::INSTR");
    }

    #[test]
    fn a_misspelt_keyword_gets_a_did_you_mean() {
        let msg = |s: &str| s.parse::<Resource>().unwrap_err().to_string();
        let hislip = msg("TCPIP0::192.168.1.20::hislp0::INSTR");
        assert!(
            hislip.contains("did you mean `hislip0` (HiSLIP)?"),
            "{hislip}"
        );
        assert!(msg("TCPIP0::h::hsilip1").contains("did you mean `hislip1`"));
        assert!(msg("TCPIP0::h::isnt0::INSTR").contains("did you mean `inst0` (VXI-11)?"));
        assert!(msg("TCPIP0::h::5025::SOKET").contains("did you mean `SOCKET`?"));
        assert!(msg("TCPIP0::h::inst0::INSRT").contains("did you mean `INSTR`?"));
        assert!(msg("TCPIP0::h::INSRT").contains("did you mean `INSTR`?"));
        assert!(msg("TCIPIP0::h::INSTR").contains("did you mean `TCPIP`?"));
        assert!(msg("VICP::h::INTSR").contains("did you mean `INSTR`?"));
        // Device names far from a keyword are VXI-11 devices as written.
        for ok in [
            "TCPIP::h::gpib0,5::INSTR",
            "TCPIP::h::inst3",
            "TCPIP::h::hpib7::INSTR",
        ] {
            assert!(ok.parse::<Resource>().is_ok(), "{ok}");
        }
    }

    #[test]
    fn malformed_strings_list_the_accepted_forms() {
        for bad in [
            "",
            "GPIB0::5::INSTR",
            "TCPIP::host::SOCKET",
            "TCPIP::host::99999::SOCKET",
            "TCPIP::host::5025::RAW",
            "TCPIPx::host::5025::SOCKET",
            "TCPIP::host::hislipA::INSTR",
            "TCPIP::host,abc::inst0::INSTR",
            "VICP::host::SOCKET",
            "ASRL::INSTR",
            "TCPIP::[::1::5025::SOCKET",
            "TCPIP::::5025::SOCKET",
        ] {
            let e = bad.parse::<Resource>().unwrap_err();
            let msg = e.to_string();
            assert!(msg.contains("accepted forms"), "{bad}: {msg}");
            assert!(msg.contains("hislipN"), "{bad}: {msg}");
        }
    }

    proptest::proptest! {
        #[test]
        fn parse_never_panics_and_display_reparses(s in "\\PC{0,40}") {
            if let Ok(r) = s.parse::<Resource>() {
                let again: Resource = r.to_string().parse().unwrap();
                proptest::prop_assert_eq!(again, r);
            }
        }

        #[test]
        fn generated_resources_round_trip(host in "[a-z][a-z0-9.-]{0,12}", port in 1u16.., idx in 0u32..10, board in proptest::option::of(0u32..4)) {
            for r in [
                Resource::Socket { board, host: host.clone(), port },
                Resource::Vxi11 { board, host: host.clone(), port: Some(port), device: "inst0".into(), device_implied: false, instr_suffix: true },
                Resource::Vxi11 { board, host: host.clone(), port: None, device: "inst0".into(), device_implied: true, instr_suffix: true },
                Resource::Vxi11 { board, host: host.clone(), port: Some(port), device: "inst1".into(), device_implied: false, instr_suffix: false },
                Resource::Hislip { board, host: host.clone(), index: idx, port: Some(port), instr_suffix: true },
                Resource::Hislip { board, host: host.clone(), index: idx, port: None, instr_suffix: false },
                Resource::Vicp { host: host.clone(), port: None, instr_suffix: true },
            ] {
                let text = r.to_string();
                proptest::prop_assert_eq!(text.parse::<Resource>().unwrap(), r);
            }
        }
    }
}
