//! Checks of settings against the catalog's limits, done before anything is sent.

use super::error::DriverError;

/// Checks `value` against `min..=max`; the error names the field and the allowed range.
pub(crate) fn within(
    instrument: &str,
    field: &'static str,
    value: f64,
    min: f64,
    max: f64,
    unit: &str,
) -> Result<(), DriverError> {
    if value.is_finite() && value >= min && value <= max {
        Ok(())
    } else {
        Err(DriverError::OutOfLimits {
            instrument: instrument.to_string(),
            field,
            value: format!("{value} {unit}"),
            allowed: format!("{min} ..= {max} {unit}"),
        })
    }
}

/// Relative closeness used to compare a read-back with what was asked.
pub(crate) fn close(a: f64, b: f64, relative: f64) -> bool {
    (a - b).abs() <= relative * a.abs().max(b.abs()).max(f64::MIN_POSITIVE)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn limits_name_the_field_and_the_range() {
        let e = within("awg", "i_amplitude_vpp", 2.0, 0.075, 1.0, "Vpp").unwrap_err();
        let text = e.to_string();
        assert!(
            text.contains("i_amplitude_vpp") && text.contains("0.075 ..= 1 Vpp"),
            "{text}"
        );
        assert!(within("awg", "x", f64::NAN, 0.0, 1.0, "V").is_err());
        assert!(within("awg", "x", 1.0, 0.0, 1.0, "V").is_ok());
    }

    #[test]
    fn closeness_is_relative() {
        assert!(close(6.4e10, 6.4000000000e10, 1e-9));
        assert!(!close(6.4e10, 6.5e10, 1e-9));
        assert!(close(0.0, 0.0, 1e-9));
    }
}
