//! Recognising a model from its `*IDN?` reply.

/// The four comma-separated fields of an IEEE 488.2 `*IDN?` reply.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Idn {
    pub manufacturer: String,
    pub model: String,
    pub serial: String,
    pub firmware: String,
}

impl Idn {
    /// Splits a reply such as `Keysight Technologies,M8195A,MY1234,4.0.0`. Surrounding whitespace and
    /// quotes are trimmed; missing trailing fields are empty. Returns `None` when there is no model field.
    pub fn parse(reply: &str) -> Option<Idn> {
        let reply = reply.trim().trim_matches('"');
        let mut fields = reply.splitn(4, ',').map(|f| f.trim().to_string());
        let manufacturer = fields.next().filter(|f| !f.is_empty())?;
        let model = fields.next().filter(|f| !f.is_empty())?;
        Some(Idn {
            manufacturer,
            model,
            serial: fields.next().unwrap_or_default(),
            firmware: fields.next().unwrap_or_default(),
        })
    }
}

/// Case-insensitive match where `*` stands for any run of characters (including none).
pub(crate) fn pattern_matches(pattern: &str, text: &str) -> bool {
    let pattern = pattern.to_ascii_uppercase();
    let text = text.to_ascii_uppercase();
    let parts: Vec<&str> = pattern.split('*').collect();
    if parts.len() == 1 {
        return pattern == text;
    }
    let (first, last) = (parts[0], parts[parts.len() - 1]);
    if !text.starts_with(first) || text.len() < first.len() + last.len() || !text.ends_with(last) {
        return false;
    }
    let mut rest = &text[first.len()..text.len() - last.len()];
    for middle in &parts[1..parts.len() - 1] {
        match rest.find(middle) {
            Some(at) => rest = &rest[at + middle.len()..],
            None => return false,
        }
    }
    true
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn glob_patterns() {
        assert!(pattern_matches("M8195A", "m8195a"));
        assert!(!pattern_matches("M8195A", "M8195AB"));
        assert!(pattern_matches("LABMASTER*", "LABMASTER10-36ZI-A"));
        assert!(pattern_matches("*TX*", "GOTMIC-TX"));
        assert!(pattern_matches("A*B*C", "AxxBxxC"));
        assert!(!pattern_matches("A*B*C", "AxxCxxB"));
        assert!(!pattern_matches("AB*BA", "ABA"));
    }

    #[test]
    fn idn_fields() {
        let idn = Idn::parse("Keysight Technologies,M8195A,MY1,4.0\n").unwrap();
        assert_eq!(idn.model, "M8195A");
        assert_eq!(idn.firmware, "4.0");
        assert!(Idn::parse("garbage").is_none());
    }
}
