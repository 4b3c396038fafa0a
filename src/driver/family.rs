//! The driver families, closed: one variant per family and one table row ([`DriverFamily::row`])
//! with everything that depends on it outside its own folder: the kinds it drives, its
//! `[vendor]` check, and the words the bench doctor uses for its remote interface and its
//! reference input. A typo in a family is a compile error; the catalog's text (`[instrument]
//! driver`) is parsed into it once ([`super::open::family`]).

use super::error::DriverError;
use crate::catalog::{InstrumentKind, InstrumentModel};

/// A driver family, spelled in the catalog as its strum name (one spelling each).
#[derive(Debug, Clone, Copy, PartialEq, Eq, strum::VariantArray, strum::IntoStaticStr)]
pub(crate) enum DriverFamily {
    #[strum(serialize = "keysight-m8195a")]
    KeysightM8195a,
    #[strum(serialize = "lecroy-maui")]
    LecroyMaui,
    #[strum(serialize = "keysight-infiniium")]
    KeysightInfiniium,
    #[strum(serialize = "gotmic-line")]
    GotmicLine,
}

/// Where a scope family chooses its remote-control interface, for the bench doctor's fix when
/// the scope does not answer as the bench file says (`open::scope_remote_setting`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum RemoteSetting {
    /// One interface at a time (VICP or VXI-11), chosen in `menu`: a scope set to the other one
    /// answers only there.
    OneAtATime { menu: &'static str },
    /// Its protocols served side by side, nothing to choose: `look_at` is what to check when it
    /// answers on none (it ends "check that the scope is on, its host, and ...").
    SideBySide { look_at: &'static str },
}

/// Checks a family's `[vendor]` table of a catalog entry.
pub(crate) type VendorCheck = fn(&InstrumentModel) -> Result<(), DriverError>;

/// Everything that depends on a family (see the module docs).
pub(crate) struct Family {
    /// The kinds of instrument it drives; a catalog file without a `driver` key gets the first
    /// family (in `VARIANTS` order) that drives its kind.
    pub kinds: &'static [InstrumentKind],
    /// Checks its `[vendor]` table; `None`: it reads none, and a table there is refused.
    pub check_vendor: Option<VendorCheck>,
    /// A scope family's remote-interface setting, in its own menus' words.
    pub remote: Option<RemoteSetting>,
    /// A scope family's external 10 MHz reference: its brand and the command its driver sends.
    pub reference: Option<(&'static str, &'static str)>,
}

impl DriverFamily {
    /// The family's table entry: the one place that names what depends on it.
    pub(crate) fn row(self) -> Family {
        match self {
            DriverFamily::KeysightM8195a => Family {
                kinds: &[InstrumentKind::Awg],
                check_vendor: None,
                remote: None,
                reference: None,
            },
            DriverFamily::LecroyMaui => Family {
                kinds: &[InstrumentKind::Digitizer],
                check_vendor: Some(super::lecroy::check_vendor),
                remote: Some(RemoteSetting::OneAtATime {
                    menu: "Utilities > Utilities Setup > Remote",
                }),
                reference: Some(("LeCroy", super::lecroy::commands::EXTERNAL_REFERENCE)),
            },
            DriverFamily::KeysightInfiniium => Family {
                kinds: &[InstrumentKind::Digitizer],
                check_vendor: Some(super::keysight_uxr::check_vendor),
                remote: Some(RemoteSetting::SideBySide {
                    look_at: "that the Infiniium application is running (it serves HiSLIP and \
                              VXI-11 side by side: there is no interface to choose)",
                }),
                reference: Some((
                    "Infiniium",
                    super::keysight_uxr::commands::EXTERNAL_REFERENCE,
                )),
            },
            DriverFamily::GotmicLine => Family {
                kinds: &[InstrumentKind::RfTx, InstrumentKind::RfRx],
                check_vendor: None,
                remote: None,
                reference: None,
            },
        }
    }

    /// Every family, in the order a kind's default is looked for.
    pub(crate) fn all() -> &'static [DriverFamily] {
        <Self as strum::VariantArray>::VARIANTS
    }

    /// As the catalog spells it.
    pub(crate) fn name(self) -> &'static str {
        self.into()
    }

    /// The family spelled `text`, if any.
    pub(crate) fn from_name(text: &str) -> Option<DriverFamily> {
        Self::all().iter().copied().find(|f| f.name() == text)
    }

    /// The family a catalog file written before the `driver` key means: the first that drives
    /// `kind`.
    pub(crate) fn first_for(kind: InstrumentKind) -> DriverFamily {
        Self::all()
            .iter()
            .copied()
            .find(|f| f.row().kinds.contains(&kind))
            .expect("every kind has a driver family")
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_catalog_spellings_are_unchanged_and_parse_back() {
        let names: Vec<&str> = DriverFamily::all().iter().map(|f| f.name()).collect();
        assert_eq!(
            names,
            [
                "keysight-m8195a",
                "lecroy-maui",
                "keysight-infiniium",
                "gotmic-line"
            ]
        );
        for f in DriverFamily::all() {
            assert_eq!(DriverFamily::from_name(f.name()), Some(*f));
        }
        assert_eq!(DriverFamily::from_name("lecroy_maui"), None);
    }

    #[test]
    fn every_kind_has_a_first_family_and_scopes_have_their_doctor_words() {
        use DriverFamily as F;
        use InstrumentKind as K;
        assert_eq!(F::first_for(K::Awg), F::KeysightM8195a);
        assert_eq!(F::first_for(K::Digitizer), F::LecroyMaui);
        assert_eq!(F::first_for(K::RfTx), F::GotmicLine);
        assert_eq!(F::first_for(K::RfRx), F::GotmicLine);
        for f in DriverFamily::all() {
            let row = f.row();
            let scope = row.kinds.contains(&K::Digitizer);
            assert_eq!(row.remote.is_some(), scope, "{}", f.name());
            assert_eq!(row.reference.is_some(), scope, "{}", f.name());
        }
    }
}
