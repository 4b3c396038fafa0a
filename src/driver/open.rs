//! Instruments opened from data: a catalog entry names its driver family (`[instrument] driver`),
//! and this is the one place that turns an entry and a resource into a boxed capability, one
//! `match` per kind. Nothing above `driver` names a vendor.
//!
//! Adding a driver family: its folder under `src/driver/`, one `mod` line in `driver/mod.rs`,
//! one variant and its table row in `family.rs` ([`DriverFamily`]), and one arm in the `match`
//! of its kind here (the compiler points at the matches that must learn it).

use super::capability::{Awg, AwgSettings, Digitizer, IqWaveform, RfFrontEnd};
use super::error::DriverError;
use super::family::DriverFamily;
pub(crate) use super::family::RemoteSetting;
use super::gotmic::{Framing, Gotmic};
use super::keysight_uxr::KeysightUxr;
use super::lecroy::Lecroy;
use super::m8195a::M8195a;
use crate::address::Resource;
use crate::catalog::InstrumentModel;
use crate::transport::Journal;

/// The driver family text of a catalog entry: its `driver` key, or for a file written before the
/// key existed the family that drove its kind then. Unchecked: [`family`] parses it.
pub(crate) fn spelling(model: &InstrumentModel) -> &str {
    match &model.instrument.driver {
        Some(name) => name,
        None => DriverFamily::first_for(model.instrument.kind).name(),
    }
}

/// The driver family of a catalog entry.
///
/// # Errors
/// [`DriverError::Catalog`] naming `instrument.driver` and every family when the text is none.
pub(crate) fn family(model: &InstrumentModel) -> Result<DriverFamily, DriverError> {
    let name = spelling(model);
    DriverFamily::from_name(name).ok_or_else(|| {
        let known: Vec<&str> = DriverFamily::all().iter().map(|f| f.name()).collect();
        unknown(
            model,
            format!(
                "instrument.driver = {name:?} is no driver family; allowed: {}",
                known.join(", ")
            ),
        )
    })
}

fn unknown(model: &InstrumentModel, reason: String) -> DriverError {
    DriverError::Catalog {
        key: model.instrument.key.clone(),
        reason,
    }
}

/// Checks that the entry's driver family exists, drives its kind, and accepts its `[vendor]`
/// table; touches no instrument. Returns the family.
///
/// # Errors
/// [`DriverError::Catalog`] naming the `driver` key or the `[vendor]` field and what is allowed.
pub(crate) fn check(model: &InstrumentModel) -> Result<DriverFamily, DriverError> {
    let family = family(model)?;
    let name = family.name();
    let kind = model.instrument.kind;
    let row = family.row();
    if !row.kinds.contains(&kind) {
        return Err(unknown(
            model,
            format!(
                "instrument.driver = {name:?} does not drive kind {:?}",
                kind.as_str()
            ),
        ));
    }
    match row.check_vendor {
        Some(check_vendor) => check_vendor(model)?,
        None if model.vendor.is_empty() => {}
        None => {
            let keys: Vec<String> = model.vendor.keys().cloned().collect();
            return Err(unknown(
                model,
                format!(
                    "the driver family {name:?} reads no [vendor] table; remove it (found \
                     keys: {})",
                    keys.join(", ")
                ),
            ));
        }
    }
    Ok(family)
}

fn wrong_kind(model: &InstrumentModel, wanted: &str) -> DriverError {
    unknown(
        model,
        format!(
            "instrument.driver = {:?} (kind {:?}) is not {wanted}",
            spelling(model),
            model.instrument.kind.as_str()
        ),
    )
}

/// Opens an AWG with its family's driver.
///
/// # Errors
/// The catalog entry is not an AWG family, or the driver's open failed.
pub(crate) async fn open_awg(
    resource: Resource,
    model: &InstrumentModel,
    journal: Option<Journal>,
    name: &str,
) -> Result<Box<dyn Awg>, DriverError> {
    match check(model)? {
        DriverFamily::KeysightM8195a => Ok(Box::new(
            M8195a::open(resource, model, journal, name).await?,
        )),
        _ => Err(wrong_kind(model, "an AWG")),
    }
}

/// Opens a digitizer with its family's driver.
///
/// # Errors
/// The catalog entry is not a digitizer family, or the driver's open failed.
pub(crate) async fn open_digitizer(
    resource: Resource,
    model: &InstrumentModel,
    journal: Option<Journal>,
    name: &str,
) -> Result<Box<dyn Digitizer>, DriverError> {
    match check(model)? {
        DriverFamily::LecroyMaui => Ok(Box::new(
            Lecroy::open(resource, model, journal, name).await?,
        )),
        DriverFamily::KeysightInfiniium => Ok(Box::new(
            KeysightUxr::open(resource, model, journal, name).await?,
        )),
        _ => Err(wrong_kind(model, "a digitizer")),
    }
}

/// Opens an RF front end with its family's driver.
///
/// # Errors
/// The catalog entry is not an RF family, or the driver's open failed.
pub(crate) async fn open_rf(
    resource: Resource,
    model: &InstrumentModel,
    journal: Option<Journal>,
    name: &str,
) -> Result<Box<dyn RfFrontEnd>, DriverError> {
    match check(model)? {
        DriverFamily::GotmicLine => Ok(Box::new(
            Gotmic::open(resource, model, journal, name).await?,
        )),
        _ => Err(wrong_kind(model, "an RF front end")),
    }
}

/// The line mode the catalog gives a front end, in words (for the bench doctor); `None` when the
/// family has no choice of line mode.
pub(crate) fn rf_line_mode(model: &InstrumentModel) -> Option<&'static str> {
    match family(model) {
        Ok(DriverFamily::GotmicLine) => Some(match Framing::from_catalog(model) {
            Framing::Plain => "plain lines",
            Framing::Crc8(_) => "CRC-8 framed lines (`CRC ON`)",
        }),
        _ => None,
    }
}

/// The remote-interface setting of a scope's family, in its own menus' words.
pub(crate) fn scope_remote_setting(model: &InstrumentModel) -> RemoteSetting {
    family(model)
        .ok()
        .and_then(|f| f.row().remote)
        .unwrap_or(RemoteSetting::SideBySide {
            look_at: "its remote-control settings",
        })
}

/// How a scope's timebase is locked to an external 10 MHz reference, in its family's words and
/// with the command its driver sends (the bench doctor's `timebases` fix).
pub(crate) fn scope_external_reference(model: &InstrumentModel) -> String {
    match family(model).ok().and_then(|f| f.row().reference) {
        Some((brand, command)) => format!("{brand} {command}"),
        None => "its reference input's setting".to_string(),
    }
}

/// Opens a front end in the line mode the catalog does not give it: a module that answers so is
/// set to the wrong mode, not dead (the bench doctor's question).
///
/// # Errors
/// The family has no other line mode, or the module did not answer in it either.
pub(crate) async fn open_rf_other_mode(
    resource: Resource,
    model: &InstrumentModel,
    journal: Option<Journal>,
    name: &str,
) -> Result<Box<dyn RfFrontEnd>, DriverError> {
    match family(model) {
        Ok(DriverFamily::GotmicLine) => {
            let other = Framing::other_than_catalog(model);
            Ok(Box::new(
                Gotmic::open_with(resource, model, journal, name, other).await?,
            ))
        }
        _ => Err(wrong_kind(model, "a front end with line modes")),
    }
}

/// What an AWG will do with a waveform, planned from the catalog alone (no instrument touched).
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct AwgPlan {
    /// Samples of one repetition after padding (the repetition period in samples).
    pub(crate) padded_samples: u64,
    /// The marker is high on the first this-many samples of every repetition.
    pub(crate) marker_high_samples: u64,
    /// The DAC sample clock, Sa/s.
    pub(crate) dac_rate_hz: f64,
    /// DAC clock over playback rate.
    pub(crate) divider: u32,
}

/// Plans the AWG's clock and segment for `waveform` at `settings`, with its family's rules.
///
/// # Errors
/// [`DriverError::OutOfLimits`] / [`DriverError::BadSettings`] when the waveform or a level does
/// not fit the model, [`DriverError::Catalog`] when the entry is no AWG family.
pub(crate) fn plan_awg(
    model: &InstrumentModel,
    settings: &AwgSettings,
    waveform: &IqWaveform,
) -> Result<AwgPlan, DriverError> {
    let limits = model
        .awg
        .as_ref()
        .ok_or_else(|| wrong_kind(model, "an AWG"))?;
    match family(model) {
        Ok(DriverFamily::KeysightM8195a) => {
            use super::m8195a::plan::{plan_clock, plan_download};
            let name = &model.instrument.model;
            let clock = plan_clock(limits, &model.instrument.key, name, settings)?;
            let download = plan_download(limits, &clock, name, waveform)?;
            Ok(AwgPlan {
                padded_samples: download.padded,
                marker_high_samples: download.marker_high,
                dac_rate_hz: clock.dac_rate_hz,
                divider: clock.divider.divider,
            })
        }
        _ => Err(wrong_kind(model, "an AWG")),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::catalog::{parse_model, Catalog, InstrumentKind, EMBEDDED_FILES};

    fn file(name: &str) -> &'static str {
        EMBEDDED_FILES
            .iter()
            .find(|(n, _)| *n == name)
            .map(|(_, t)| *t)
            .unwrap()
    }

    #[test]
    fn every_built_in_model_names_a_family_that_drives_its_kind() {
        for (model, _) in Catalog::embedded().unwrap().models() {
            let family = check(model).unwrap_or_else(|e| panic!("{}: {e}", model.instrument.key));
            assert_eq!(model.instrument.driver.as_deref(), Some(family.name()));
            assert!(
                model.instrument.driver.is_some(),
                "{}",
                model.instrument.key
            );
        }
    }

    #[test]
    fn a_file_without_the_key_gets_its_kind_s_first_family() {
        let text = file("lecroy_labmaster10zi_a.toml").replace("driver = \"lecroy-maui\"\n", "");
        let model = parse_model("old.toml", &text).unwrap();
        assert_eq!(model.instrument.driver, None);
        assert_eq!(family(&model).unwrap(), DriverFamily::LecroyMaui);
        check(&model).unwrap();
    }

    #[test]
    fn unknown_families_wrong_kinds_and_stray_vendor_tables_are_refused() {
        let lecroy = file("lecroy_labmaster10zi_a.toml");
        let unknown = parse_model(
            "x.toml",
            &lecroy.replace("driver = \"lecroy-maui\"", "driver = \"tek-dpo\""),
        )
        .unwrap();
        let e = check(&unknown).unwrap_err().to_string();
        assert!(
            e.contains("\"tek-dpo\"") && e.contains("keysight-infiniium"),
            "{e}"
        );
        let wrong = parse_model(
            "x.toml",
            &lecroy.replace("driver = \"lecroy-maui\"", "driver = \"gotmic-line\""),
        )
        .unwrap();
        let e = check(&wrong).unwrap_err().to_string();
        assert!(e.contains("does not drive kind \"digitizer\""), "{e}");
        let awg = file("keysight_m8195a.toml");
        let stray = parse_model("x.toml", &format!("{awg}\n[vendor]\nx = 1\n")).unwrap();
        let e = check(&stray).unwrap_err().to_string();
        assert!(
            e.contains("reads no [vendor] table") && e.contains('x'),
            "{e}"
        );
        let uxr = file("keysight_uxr0334a.toml");
        let bad = parse_model(
            "x.toml",
            &uxr.replace("acquisition_poll_ms = 2", "acquisition_poll_ms = \"fast\""),
        )
        .unwrap();
        let e = check(&bad).unwrap_err().to_string();
        assert!(
            e.contains("[vendor]") && e.contains("acquisition_poll_ms"),
            "{e}"
        );
    }

    #[test]
    fn each_scope_family_names_its_own_remote_setting_and_reference() {
        let catalog = Catalog::embedded().unwrap();
        let lecroy = catalog.get("lecroy-labmaster10zi-a").unwrap();
        let uxr = catalog.get("keysight-uxr0334a").unwrap();
        assert_eq!(
            scope_remote_setting(lecroy),
            RemoteSetting::OneAtATime {
                menu: "Utilities > Utilities Setup > Remote"
            }
        );
        let RemoteSetting::SideBySide { look_at } = scope_remote_setting(uxr) else {
            panic!("the Infiniium serves HiSLIP and VXI-11 side by side");
        };
        assert!(look_at.contains("Infiniium") && !look_at.contains("Utilities"));
        assert_eq!(scope_external_reference(lecroy), "LeCroy RCLK EXTERNAL");
        assert_eq!(
            scope_external_reference(uxr),
            "Infiniium :TIMebase:REFClock ON"
        );
        // Every built-in scope: its family's own words, one interface at a time exactly when
        // its catalog file says the interfaces are exclusive.
        for (model, _) in catalog.models() {
            if model.instrument.kind != InstrumentKind::Digitizer {
                continue;
            }
            let key = &model.instrument.key;
            assert!(
                !scope_external_reference(model).starts_with("its "),
                "{key}"
            );
            let one_at_a_time = matches!(
                scope_remote_setting(model),
                RemoteSetting::OneAtATime { .. }
            );
            assert_eq!(
                one_at_a_time, model.quirks.remote_interfaces_exclusive,
                "{key}"
            );
        }
    }

    #[test]
    fn awg_planning_goes_through_the_family() {
        let catalog = Catalog::embedded().unwrap();
        let awg = catalog.get("keysight-m8195a").unwrap();
        let waveform = IqWaveform {
            i: vec![0; 1000],
            q: vec![0; 1000],
            marker_high_samples: 64,
        };
        let plan = plan_awg(awg, &AwgSettings::default(), &waveform).unwrap();
        assert_eq!(plan.padded_samples % 64, 0);
        assert!(plan.padded_samples >= 1000);
        assert_eq!(plan.dac_rate_hz / f64::from(plan.divider), 16e9);
        let scope = catalog.get("keysight-uxr0334a").unwrap();
        assert!(plan_awg(scope, &AwgSettings::default(), &waveform).is_err());
    }
}
