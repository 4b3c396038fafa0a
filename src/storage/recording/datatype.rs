//! SigMF complex datatypes (`ci16_le`, `cf32_be`, ...): parsing, sizes, and one component's
//! value from its bytes.

/// Number format of one component of a complex sample.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Component {
    I8,
    U8,
    I16,
    U16,
    I32,
    U32,
    F32,
    F64,
}

impl Component {
    /// Bytes of one component.
    pub fn bytes(self) -> usize {
        match self {
            Component::I8 | Component::U8 => 1,
            Component::I16 | Component::U16 => 2,
            Component::I32 | Component::U32 | Component::F32 => 4,
            Component::F64 => 8,
        }
    }
    fn name(self) -> &'static str {
        match self {
            Component::I8 => "i8",
            Component::U8 => "u8",
            Component::I16 => "i16",
            Component::U16 => "u16",
            Component::I32 => "i32",
            Component::U32 => "u32",
            Component::F32 => "f32",
            Component::F64 => "f64",
        }
    }
}

/// A SigMF complex datatype, e.g. `ci16_le`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Datatype {
    pub component: Component,
    /// Little endian (`_le`); meaningless for 8-bit types.
    pub little_endian: bool,
}

impl Datatype {
    /// Parses a `core:datatype` value; the error says why it is refused.
    pub fn parse(text: &str) -> Result<Datatype, &'static str> {
        let (body, little_endian) = match text.rsplit_once('_') {
            Some((b, "le")) => (b, Some(true)),
            Some((b, "be")) => (b, Some(false)),
            Some(_) => return Err("the endianness suffix must be _le or _be"),
            None => (text, None),
        };
        let (kind, number) = body.split_at(body.len().min(1));
        let component = match number {
            "i8" => Component::I8,
            "u8" => Component::U8,
            "i16" => Component::I16,
            "u16" => Component::U16,
            "i32" => Component::I32,
            "u32" => Component::U32,
            "f32" => Component::F32,
            "f64" => Component::F64,
            _ => return Err("unknown number format"),
        };
        match kind {
            "c" => {}
            "r" => return Err("it is real-valued, and radbench needs I/Q (complex) samples"),
            _ => return Err("a SigMF datatype starts with c (complex) or r (real)"),
        }
        let little_endian = match (component.bytes(), little_endian) {
            (1, order) => order.unwrap_or(true),
            (_, Some(order)) => order,
            (_, None) => return Err("a multi-byte type needs _le or _be"),
        };
        Ok(Datatype {
            component,
            little_endian,
        })
    }

    /// Bytes of one complex sample.
    pub(crate) fn sample_bytes(self) -> usize {
        2 * self.component.bytes()
    }

    /// One component from its bytes (exactly `component.bytes()` of them), in native scale.
    pub(super) fn value(self, b: &[u8]) -> f64 {
        macro_rules! read {
            ($t:ty) => {{
                let mut a = [0u8; std::mem::size_of::<$t>()];
                a.copy_from_slice(b);
                f64::from(if self.little_endian {
                    <$t>::from_le_bytes(a)
                } else {
                    <$t>::from_be_bytes(a)
                })
            }};
        }
        match self.component {
            Component::I8 => f64::from(b[0] as i8),
            Component::U8 => f64::from(b[0]),
            Component::I16 => read!(i16),
            Component::U16 => read!(u16),
            Component::I32 => read!(i32),
            Component::U32 => read!(u32),
            Component::F32 => read!(f32),
            Component::F64 => read!(f64),
        }
    }
}

impl std::fmt::Display for Datatype {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "c{}", self.component.name())?;
        if self.component.bytes() > 1 {
            f.write_str(if self.little_endian { "_le" } else { "_be" })?;
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn datatypes_parse_and_print_back() {
        for t in [
            "ci8", "cu8", "ci16_le", "ci16_be", "cu16_le", "ci32_be", "cu32_le", "cf32_le",
            "cf32_be", "cf64_le",
        ] {
            assert_eq!(Datatype::parse(t).unwrap().to_string(), t);
        }
        assert!(Datatype::parse("rf32_le").unwrap_err().contains("real"));
        assert!(Datatype::parse("ci16").unwrap_err().contains("_le or _be"));
        assert!(Datatype::parse("cf16_le").is_err());
        assert!(Datatype::parse("ci16_xx").is_err());
        assert!(Datatype::parse("").is_err());
    }
}
