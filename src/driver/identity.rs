//! Is this the instrument the bench file names? `*IDN?` against the catalog model's patterns
//! (or its mock_lab emulator's identity).

use super::error::DriverError;
use crate::catalog::InstrumentModel;
use crate::session::{parse_idn, Identity};

/// Whether an identity is the model (vendor patterns) or its mock_lab emulator.
pub(crate) fn matches(model: &InstrumentModel, idn: &Identity) -> bool {
    model
        .identity
        .matches(&idn.manufacturer, &idn.model)
        .is_some()
}

/// Parses an `*IDN?` reply (a `*IDN ` response header, LeCroy's default, is skipped) and checks
/// it is `model`. `resource` names the address in the error; `command` the request that was sent.
pub(crate) fn check(
    model: &InstrumentModel,
    instrument: &str,
    resource: &str,
    command: &str,
    reply: &str,
) -> Result<Identity, DriverError> {
    let body = match reply.get(..5) {
        Some(head) if head.eq_ignore_ascii_case("*IDN ") => &reply[5..],
        _ => reply,
    };
    let idn = parse_idn(body).ok_or_else(|| DriverError::Reply {
        instrument: instrument.to_string(),
        command: command.to_string(),
        expected: "manufacturer,model,serial,firmware",
        reply: reply.to_string(),
    })?;
    if !matches(model, &idn) {
        return Err(DriverError::WrongInstrument {
            resource: resource.to_string(),
            expected: format!(
                "{} {} (catalog key `{}`)",
                model.instrument.manufacturer, model.instrument.model, model.instrument.key
            ),
            idn: reply.to_string(),
        });
    }
    Ok(idn)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::catalog::Catalog;

    #[test]
    fn vendor_emulator_and_strangers() {
        let catalog = Catalog::embedded().unwrap();
        let scope = catalog.get("lecroy-labmaster10zi-a").unwrap();
        let ok = check(
            scope,
            "scope",
            "r",
            "*IDN?",
            "*IDN LECROY,LABMASTER10ZI-A,1,9.1",
        );
        assert_eq!(ok.unwrap().manufacturer, "LECROY");
        let emu = "MOCK_LAB,LABMASTER10ZI-A-EMU,EMU0002,mock_lab-1";
        assert!(check(scope, "scope", "r", "*IDN?", emu).is_ok());
        let e = check(scope, "scope", "r", "*IDN?", "Rigol,DG1022,1,1").unwrap_err();
        assert!(matches!(e, DriverError::WrongInstrument { .. }), "{e}");
        let e = check(scope, "scope", "r", "*IDN?", "nonsense").unwrap_err();
        assert!(matches!(e, DriverError::Reply { .. }), "{e}");
    }
}
