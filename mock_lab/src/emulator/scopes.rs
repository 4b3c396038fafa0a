//! The scopes the lab can serve as `scope`: [`SCOPES`], one row per family (name, catalog key,
//! transports, emulator), public as [`ScopeModel::ALL`].

use super::keysight_uxr;
use super::lecroy::trigger::TriggerSource;
use crate::catalog::CatalogError;
use crate::server::launch::Transport;
use crate::server::Handler;
use std::sync::Arc;

/// Every scope the lab can serve, the default first. The first transport of each is the one
/// radbench's `--scope-transport vicp` (the default) reaches it on.
pub(crate) const SCOPES: [ScopeModel; 2] = [
    ScopeModel {
        name: "lecroy",
        catalog_key: "lecroy-labmaster10zi-a",
        about: "Teledyne LeCroy LabMaster 10 Zi-A (VICP or VXI-11), saves `.trc` files beside the \
                SigMF",
        transports: &[Transport::Vicp, Transport::Vxi11],
        emulator: ScopeEmulator::BenchLecroy,
    },
    ScopeModel {
        name: "keysight-uxr",
        catalog_key: "keysight-uxr0334a",
        about: "Keysight Infiniium UXR0334A (HiSLIP or VXI-11), saves the SigMF recording only",
        transports: &[Transport::Hislip, Transport::Vxi11],
        emulator: ScopeEmulator::Build(|source| {
            Ok(Arc::new(keysight_uxr::KeysightUxr::embedded_with(source)?))
        }),
    },
];

/// A scope the lab can serve as `scope` (a row of `SCOPES`, listed in [`ScopeModel::ALL`]): every one sees
/// the same bench (AWG marker on its external trigger, the scene on channels 1 and 2).
#[derive(Clone, Copy)]
pub struct ScopeModel {
    /// The name the command line and spec files use.
    pub(crate) name: &'static str,
    /// The catalog key radbench's bench file names.
    pub(crate) catalog_key: &'static str,
    /// One line of help.
    pub(crate) about: &'static str,
    /// The transports it is served on; the first is the default.
    pub(crate) transports: &'static [Transport],
    pub(crate) emulator: ScopeEmulator,
}

/// Builds a scope's emulator on the bench's inputs.
pub(crate) type BuildScope = fn(Arc<dyn TriggerSource>) -> Result<Arc<dyn Handler>, CatalogError>;

/// How the lab gets a scope's emulator.
#[derive(Clone, Copy)]
pub(crate) enum ScopeEmulator {
    /// The bench's own LeCroy ([`Bench::scope`](crate::bench::Bench::scope)), served on VICP and VXI-11, only the one its
    /// remote interface selects answering.
    BenchLecroy,
    /// Built for the lab on the bench's inputs, served on all its transports.
    Build(BuildScope),
}

impl ScopeModel {
    /// Every scope the lab can serve, the default first.
    pub const ALL: [ScopeModel; SCOPES.len()] = SCOPES;

    /// The catalog key radbench's bench file names.
    pub fn catalog_key(self) -> &'static str {
        self.catalog_key
    }

    /// The name the command line and spec files use.
    pub fn name(self) -> &'static str {
        self.name
    }

    pub fn about(self) -> &'static str {
        self.about
    }

    /// The transport to reach it on when `asked` for one: `asked` when it is served on it,
    /// otherwise its default (the first it is served on).
    pub fn transport(self, asked: Transport) -> Transport {
        if self.transports.contains(&asked) {
            asked
        } else {
            self.transports[0]
        }
    }
}

impl Default for ScopeModel {
    fn default() -> Self {
        ScopeModel::ALL[0]
    }
}

impl PartialEq for ScopeModel {
    fn eq(&self, other: &Self) -> bool {
        self.name == other.name
    }
}

impl Eq for ScopeModel {}

impl std::fmt::Debug for ScopeModel {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "ScopeModel({})", self.name)
    }
}

impl std::str::FromStr for ScopeModel {
    type Err = String;

    /// As `name` spells it; the error lists what is allowed.
    fn from_str(s: &str) -> Result<Self, String> {
        Self::ALL
            .into_iter()
            .find(|v| v.name() == s)
            .ok_or_else(|| {
                let names: Vec<&str> = Self::ALL.iter().map(|v| v.name()).collect();
                format!("unknown scope model `{s}`: allowed: {}", names.join(", "))
            })
    }
}

impl std::fmt::Display for ScopeModel {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

impl serde::Serialize for ScopeModel {
    fn serialize<S: serde::Serializer>(&self, serializer: S) -> Result<S::Ok, S::Error> {
        serializer.serialize_str(self.name)
    }
}

impl<'de> serde::Deserialize<'de> for ScopeModel {
    fn deserialize<D: serde::Deserializer<'de>>(deserializer: D) -> Result<Self, D::Error> {
        let name = String::deserialize(deserializer)?;
        name.parse().map_err(serde::de::Error::custom)
    }
}
