//! The `[vendor]` table of a LeCroy (MAUI) catalog file: the WAVEDESC template and its size.
//!
//! Catalog files written before the `[vendor]` table give both fields under `[digitizer]` (their
//! old place); the catalog loader moves them here, so this reads one place.

use crate::catalog::InstrumentModel;
use crate::driver::DriverError;

/// The one WAVEDESC template the decoder reads, and its size in bytes.
const TEMPLATE: &str = "LECROY_2_3";
const TEMPLATE_BYTES: u32 = 346;
/// The largest descriptor a catalog may declare: the session's message headroom holds it
/// (`driver::io::MESSAGE_HEADROOM_BYTES`, 1 MiB).
const MOST_WAVEDESC_BYTES: u32 = 64 << 10;

/// The `[vendor]` table of a LeCroy catalog file; both fields optional.
#[derive(Debug, Clone, Default, PartialEq)]
struct Vendor {
    /// The WAVEDESC template name the firmware writes (`LECROY_2_3`).
    wavedesc_template: Option<String>,
    /// Size of that descriptor in bytes (346 for `LECROY_2_3`).
    wavedesc_bytes: Option<u32>,
}

fn bad(model: &InstrumentModel, reason: String) -> DriverError {
    DriverError::Catalog {
        key: model.instrument.key.clone(),
        reason,
    }
}

/// Reads the table, naming the `vendor.` field of any problem and what is allowed.
fn vendor(model: &InstrumentModel) -> Result<Vendor, DriverError> {
    const FIELDS: &str = "wavedesc_template, wavedesc_bytes";
    if let Some(key) = model
        .vendor
        .keys()
        .find(|k| !FIELDS.split(", ").any(|f| f == k.as_str()))
    {
        return Err(bad(
            model,
            format!("vendor.{key}: the lecroy-maui driver reads no such field; allowed: {FIELDS}"),
        ));
    }
    let wavedesc_template = match model.vendor.get("wavedesc_template") {
        None => None,
        Some(toml::Value::String(s)) => Some(s.clone()),
        Some(other) => {
            return Err(bad(
                model,
                format!(
                    "vendor.wavedesc_template: must be a template name such as \"{TEMPLATE}\" \
                     (got {other})"
                ),
            ))
        }
    };
    let wavedesc_bytes = match model.vendor.get("wavedesc_bytes") {
        None => None,
        Some(toml::Value::Integer(n)) if (0..=i64::from(MOST_WAVEDESC_BYTES)).contains(n) => {
            u32::try_from(*n).ok()
        }
        Some(other) => {
            return Err(bad(
                model,
                format!(
                    "vendor.wavedesc_bytes: must be a size in bytes, 0 ..= \
                     {MOST_WAVEDESC_BYTES} (such as {TEMPLATE_BYTES}) (got {other})"
                ),
            ))
        }
    };
    Ok(Vendor {
        wavedesc_template,
        wavedesc_bytes,
    })
}

/// Checks the `[vendor]` table of a LeCroy catalog entry.
///
/// # Errors
/// [`DriverError::Catalog`] naming the `vendor.` field: an unknown field, a wrong type, or a
/// `LECROY_2_3` descriptor size other than 346 bytes.
pub(crate) fn check_vendor(model: &InstrumentModel) -> Result<(), DriverError> {
    let v = vendor(model)?;
    if let (Some(TEMPLATE), Some(bytes)) = (v.wavedesc_template.as_deref(), v.wavedesc_bytes) {
        if bytes != TEMPLATE_BYTES {
            return Err(bad(
                model,
                format!(
                    "vendor.wavedesc_bytes: the {TEMPLATE} descriptor is {TEMPLATE_BYTES} bytes \
                     (got {bytes})"
                ),
            ));
        }
    }
    Ok(())
}

/// The WAVEDESC size the catalog gives (0 when it gives none or the table does not read).
#[cfg(test)]
fn wavedesc_bytes(model: &InstrumentModel) -> u32 {
    vendor(model)
        .ok()
        .and_then(|v| v.wavedesc_bytes)
        .unwrap_or(0)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::catalog::{parse_model, EMBEDDED_FILES};

    fn lecroy() -> &'static str {
        EMBEDDED_FILES
            .iter()
            .find(|(n, _)| *n == "lecroy_labmaster10zi_a.toml")
            .map(|(_, t)| *t)
            .unwrap()
    }

    /// The shipped file with its two `[vendor]` lines moved under `[digitizer]`.
    fn old_place(bytes: &str) -> String {
        let text = lecroy()
            .replace("wavedesc_template = \"LECROY_2_3\"\n", "")
            .replace("wavedesc_bytes = 346\n", "");
        text.replacen(
            "[digitizer]\n",
            &format!("[digitizer]\nwavedesc_template = \"LECROY_2_3\"\nwavedesc_bytes = {bytes}\n"),
            1,
        )
    }

    #[test]
    fn the_shipped_file_has_them_in_its_vendor_table() {
        let model = parse_model("x.toml", lecroy()).unwrap();
        assert_eq!(model.digitizer.as_ref().unwrap().wavedesc_bytes, None);
        check_vendor(&model).unwrap();
        assert_eq!(wavedesc_bytes(&model), 346);
    }

    #[test]
    fn a_file_with_them_in_the_old_place_loads_the_same() {
        let old = parse_model("old.toml", &old_place("346")).unwrap();
        check_vendor(&old).unwrap();
        assert_eq!(wavedesc_bytes(&old), 346);
        let new = parse_model("new.toml", lecroy()).unwrap();
        assert_eq!(old.vendor, new.vendor);
    }

    #[test]
    fn a_wrong_size_is_refused_naming_the_vendor_field() {
        for text in [
            lecroy().replace("wavedesc_bytes = 346", "wavedesc_bytes = 320"),
            old_place("320"),
        ] {
            let model = parse_model("x.toml", &text).unwrap();
            let e = check_vendor(&model).unwrap_err().to_string();
            assert!(
                e.contains("vendor.wavedesc_bytes") && e.contains("320"),
                "{e}"
            );
        }
        let stray = lecroy().replace("wavedesc_bytes = 346", "wavedesc_bytes = 346\nx = 1");
        let e = check_vendor(&parse_model("x.toml", &stray).unwrap())
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("vendor.x") && e.contains("wavedesc_bytes"),
            "{e}"
        );
        let typed = lecroy().replace("wavedesc_bytes = 346", "wavedesc_bytes = \"346\"");
        let e = check_vendor(&parse_model("x.toml", &typed).unwrap())
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("vendor.wavedesc_bytes") && e.contains("\"346\""),
            "{e}"
        );
    }
}
