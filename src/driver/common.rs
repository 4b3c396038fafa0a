//! Pieces every driver uses: identifying the instrument against its catalog model, checking the
//! error queue after a batch, and turning session errors into driver errors.

use super::error::DriverError;
use super::io::InstrumentIo;
use crate::catalog::InstrumentModel;
use crate::session::reply::parse_idn;
use crate::session::{Identity, SessionError};

/// Wraps a session error with the instrument's name.
pub fn session(instrument: &str) -> impl Fn(SessionError) -> DriverError + '_ {
    move |source| DriverError::Session {
        instrument: instrument.to_string(),
        source: Box::new(source),
    }
}

/// Whether an identity is the model (vendor patterns) or its mock_lab emulator.
pub fn identity_matches(model: &InstrumentModel, idn: &Identity) -> bool {
    model
        .identity
        .matches(&idn.manufacturer, &idn.model)
        .is_some()
}

/// Asks `*IDN?` and checks the answer is the catalog model.
pub async fn identify(
    io: &mut dyn InstrumentIo,
    model: &InstrumentModel,
    instrument: &str,
) -> Result<Identity, DriverError> {
    let reply = io.query("*IDN?").await.map_err(session(instrument))?;
    // Instruments with response headers on (LeCroy's default) prefix the reply with `*IDN `.
    let body = match reply.get(..5) {
        Some(head) if head.eq_ignore_ascii_case("*IDN ") => &reply[5..],
        _ => reply.as_str(),
    };
    let idn = parse_idn(body).ok_or_else(|| DriverError::Reply {
        instrument: instrument.to_string(),
        command: "*IDN?".into(),
        expected: "manufacturer,model,serial,firmware",
        reply: reply.clone(),
    })?;
    if !identity_matches(model, &idn) {
        return Err(DriverError::WrongInstrument {
            resource: io.resource_text(),
            expected: format!(
                "{} {} (catalog key `{}`)",
                model.instrument.manufacturer, model.instrument.model, model.instrument.key
            ),
            idn: reply,
        });
    }
    Ok(idn)
}

/// Drains the error queue after a batch and fails with [`DriverError::Refused`] if it held entries.
pub async fn check_batch(
    io: &mut dyn InstrumentIo,
    instrument: &str,
    batch: &str,
) -> Result<(), DriverError> {
    let errors = io.errors().await.map_err(session(instrument))?;
    if errors.is_empty() {
        Ok(())
    } else {
        Err(DriverError::Refused {
            instrument: instrument.to_string(),
            batch: batch.to_string(),
            errors,
        })
    }
}

/// Checks `value` against `min..=max`; the error names the field and the allowed range.
pub fn within(
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

/// A number as SCPI text: a plain decimal rounded to 12 significant digits, so arithmetic noise
/// (`1.0239999999999999e-7`) never reaches the instrument (`64000000000`, `0.5`, `0.0000001024`).
pub fn number(value: f64) -> String {
    let rounded: f64 = format!("{value:.11e}").parse().unwrap_or(value);
    if rounded == 0.0 {
        "0".to_string()
    } else {
        format!("{rounded}")
    }
}

/// Relative closeness used to compare a read-back with what was asked.
pub fn close(a: f64, b: f64, relative: f64) -> bool {
    (a - b).abs() <= relative * a.abs().max(b.abs()).max(f64::MIN_POSITIVE)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn numbers_are_plain_decimals() {
        assert_eq!(number(64e9), "64000000000");
        assert_eq!(number(0.5), "0.5");
        assert_eq!(number(-0.0), "0");
        assert_eq!(number(1.024e-7), "0.0000001024");
        assert_eq!(number(1.024e-6 / 10.0 - 1e-22), "0.0000001024");
        assert_eq!(number(-5.12e-7), "-0.000000512");
        assert!(close(6.4e10, 6.4000000000e10, 1e-9));
        assert!(!close(6.4e10, 6.5e10, 1e-9));
    }

    #[test]
    fn limits_name_the_field_and_the_range() {
        let e = within("awg", "i_amplitude_vpp", 2.0, 0.075, 1.0, "Vpp").unwrap_err();
        let text = e.to_string();
        assert!(
            text.contains("i_amplitude_vpp") && text.contains("0.075 ..= 1 Vpp"),
            "{text}"
        );
        assert!(within("awg", "x", f64::NAN, 0.0, 1.0, "V").is_err());
    }
}
