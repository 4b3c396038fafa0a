//! SCPI numeric, boolean and character parameters, with unit suffixes and MIN/MAX/DEF.

use super::error_queue::ScpiError;

/// The unit a numeric parameter may carry as a suffix.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Unit {
    None,
    Hertz,
    Volt,
    Second,
}

/// Range and keyword values of a numeric parameter.
#[derive(Debug, Clone, Copy)]
pub(crate) struct NumericSpec {
    pub unit: Unit,
    pub min: f64,
    pub max: f64,
    pub default: f64,
}

/// Parses a number such as `64E9`, `64 GHz`, `500mV`, `MAX`; checks it against the range (`-222`).
pub(crate) fn numeric(text: &str, spec: NumericSpec) -> Result<f64, ScpiError> {
    let upper = text.trim().to_ascii_uppercase();
    let value = match upper.as_str() {
        "MIN" | "MINIMUM" => return Ok(spec.min),
        "MAX" | "MAXIMUM" => return Ok(spec.max),
        "DEF" | "DEFAULT" => return Ok(spec.default),
        _ => parse_with_unit(&upper, spec.unit)?,
    };
    if !(value >= spec.min && value <= spec.max) {
        return Err(ScpiError::new(
            -222,
            format!("{} is outside {} ..= {}", text.trim(), spec.min, spec.max),
        ));
    }
    Ok(value)
}

/// Parses a number with an optional unit suffix, without a range check.
pub(crate) fn parse_with_unit(upper: &str, unit: Unit) -> Result<f64, ScpiError> {
    let split = upper
        .find(|c: char| c.is_ascii_alphabetic() && c != 'E')
        .unwrap_or(upper.len());
    let (number, suffix) = upper.split_at(split);
    let number = number.trim();
    let value: f64 = number
        .parse()
        .map_err(|_| ScpiError::new(-104, format!("expected a number, got {upper:?}")))?;
    if !value.is_finite() {
        return Err(ScpiError::new(-222, "the number is not finite"));
    }
    let suffix = suffix.trim();
    if suffix.is_empty() {
        return Ok(value);
    }
    let multiplier = unit_multiplier(suffix, unit)
        .ok_or_else(|| ScpiError::new(-131, format!("invalid suffix {suffix:?}")))?;
    Ok(value * multiplier)
}

fn unit_multiplier(suffix: &str, unit: Unit) -> Option<f64> {
    let (base, table): (&str, &[(&str, f64)]) = match unit {
        Unit::None => return None,
        // SCPI: "M" is milli except in MHZ (mega); "MA" is mega.
        Unit::Hertz => (
            "HZ",
            &[("G", 1e9), ("M", 1e6), ("MA", 1e6), ("K", 1e3), ("", 1.0)],
        ),
        Unit::Volt => ("V", &[("M", 1e-3), ("U", 1e-6), ("K", 1e3), ("", 1.0)]),
        Unit::Second => (
            "S",
            &[
                ("P", 1e-12),
                ("N", 1e-9),
                ("U", 1e-6),
                ("M", 1e-3),
                ("", 1.0),
            ],
        ),
    };
    let prefix = suffix.strip_suffix(base)?;
    table.iter().find(|(p, _)| *p == prefix).map(|(_, m)| *m)
}

/// `ON|OFF|1|0` (any non-zero number is true, per SCPI).
pub(crate) fn boolean(text: &str) -> Result<bool, ScpiError> {
    match text.trim().to_ascii_uppercase().as_str() {
        "ON" => Ok(true),
        "OFF" => Ok(false),
        other => other
            .parse::<f64>()
            .map(|v| v.round() != 0.0)
            .map_err(|_| ScpiError::new(-224, format!("expected ON, OFF, 1 or 0, got {text:?}"))),
    }
}

/// A non-negative integer (`-104` if not a number, `-222` if negative or fractional).
pub(crate) fn unsigned(text: &str) -> Result<u64, ScpiError> {
    let value = parse_with_unit(&text.trim().to_ascii_uppercase(), Unit::None)?;
    if value < 0.0 || value.fract() != 0.0 || value > u64::MAX as f64 {
        return Err(ScpiError::new(
            -222,
            format!("expected a non-negative integer, got {text}"),
        ));
    }
    Ok(value as u64)
}

/// Matches character data against `(short, long)` keyword forms, case-insensitively (`-224` otherwise).
pub(crate) fn keyword<'a>(
    text: &str,
    choices: &[(&'a str, &'a str)],
) -> Result<&'a str, ScpiError> {
    let t = text.trim();
    choices
        .iter()
        .find(|(short, long)| t.eq_ignore_ascii_case(short) || t.eq_ignore_ascii_case(long))
        .map(|(short, _)| *short)
        .ok_or_else(|| {
            let allowed: Vec<_> = choices.iter().map(|(s, _)| *s).collect();
            ScpiError::new(-224, format!("{t:?} is not one of {}", allowed.join("|")))
        })
}

/// The SCPI NR3 form of a float, e.g. `6.4000000000E+10`.
pub(crate) fn nr3(value: f64) -> String {
    let s = format!("{value:.10E}");
    match s.split_once('E') {
        Some((mantissa, exp)) => {
            let exp: i32 = exp.parse().unwrap_or(0);
            format!(
                "{mantissa}E{}{:02}",
                if exp < 0 { '-' } else { '+' },
                exp.abs()
            )
        }
        None => s,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const RATE: NumericSpec = NumericSpec {
        unit: Unit::Hertz,
        min: 53.76e9,
        max: 65e9,
        default: 64e9,
    };

    #[test]
    fn numbers_units_and_keywords() {
        assert_eq!(numeric("64E9", RATE).unwrap(), 64e9);
        assert_eq!(numeric("64 GHz", RATE).unwrap(), 64e9);
        assert_eq!(numeric("max", RATE).unwrap(), 65e9);
        assert_eq!(numeric("70e9", RATE).unwrap_err().code, -222);
        assert_eq!(numeric("fast", RATE).unwrap_err().code, -104);
        assert_eq!(parse_with_unit("500MV", Unit::Volt).unwrap(), 0.5);
        assert_eq!(parse_with_unit("5E-1", Unit::Volt).unwrap(), 0.5);
        assert_eq!(parse_with_unit("1.5E+3", Unit::None).unwrap(), 1500.0);
        assert!(boolean("ON").unwrap());
        assert!(!boolean("0").unwrap());
        assert_eq!(keyword("dcmarker", &[("DCM", "DCMARKER")]).unwrap(), "DCM");
        assert_eq!(nr3(64e9), "6.4000000000E+10");
        assert_eq!(nr3(0.5), "5.0000000000E-01");
    }
}
