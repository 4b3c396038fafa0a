//! Library enums the command line and the files take by name ([`Listed`]), and clap's parser
//! of them ([`listed`]): one spelling per value, its `FromStr` and a line of help.

use super::bench::{AwgLink, ScopeLink, ScopeModel};
use super::options::{Algorithm, DetectorName, FftPrecisionName, Ranging, WindowName};
use super::response::CorrectionMode;
use crate::waveform::WaveformKind;

/// A library enum the command line takes by name: its values (with a line of help each) and its
/// `FromStr`, so clap parses the library's own type (no mirror enum here).
pub trait Listed: std::str::FromStr + Copy + Send + Sync + 'static {
    fn all() -> &'static [Self];
    fn name(self) -> &'static str;
    fn about(self) -> &'static str;
}

impl Listed for WaveformKind {
    fn all() -> &'static [Self] {
        &WaveformKind::ALL
    }
    fn name(self) -> &'static str {
        WaveformKind::name(self)
    }
    fn about(self) -> &'static str {
        WaveformKind::about(self)
    }
}

impl Listed for Algorithm {
    fn all() -> &'static [Self] {
        &Algorithm::ALL
    }
    fn name(self) -> &'static str {
        Algorithm::name(self)
    }
    fn about(self) -> &'static str {
        Algorithm::about(self)
    }
}

impl Listed for WindowName {
    fn all() -> &'static [Self] {
        &WindowName::ALL
    }
    fn name(self) -> &'static str {
        WindowName::name(self)
    }
    fn about(self) -> &'static str {
        WindowName::about(self)
    }
}

impl Listed for FftPrecisionName {
    fn all() -> &'static [Self] {
        &FftPrecisionName::ALL
    }
    fn name(self) -> &'static str {
        FftPrecisionName::name(self)
    }
    fn about(self) -> &'static str {
        FftPrecisionName::about(self)
    }
}

impl Listed for DetectorName {
    fn all() -> &'static [Self] {
        &DetectorName::ALL
    }
    fn name(self) -> &'static str {
        DetectorName::name(self)
    }
    fn about(self) -> &'static str {
        DetectorName::about(self)
    }
}

impl Listed for AwgLink {
    fn all() -> &'static [Self] {
        &AwgLink::ALL
    }
    fn name(self) -> &'static str {
        AwgLink::name(self)
    }
    fn about(self) -> &'static str {
        AwgLink::about(self)
    }
}

impl Listed for ScopeLink {
    fn all() -> &'static [Self] {
        &ScopeLink::ALL
    }
    fn name(self) -> &'static str {
        ScopeLink::name(self)
    }
    fn about(self) -> &'static str {
        ScopeLink::about(self)
    }
}

impl Listed for ScopeModel {
    fn all() -> &'static [Self] {
        &ScopeModel::ALL
    }
    fn name(self) -> &'static str {
        ScopeModel::name(self)
    }
    fn about(self) -> &'static str {
        ScopeModel::about(self)
    }
}

impl Listed for CorrectionMode {
    fn all() -> &'static [Self] {
        &CorrectionMode::ALL
    }
    fn name(self) -> &'static str {
        CorrectionMode::name(self)
    }
    fn about(self) -> &'static str {
        CorrectionMode::about(self)
    }
}

impl Listed for Ranging {
    fn all() -> &'static [Self] {
        &Ranging::ALL
    }
    fn name(self) -> &'static str {
        Ranging::name(self)
    }
    fn about(self) -> &'static str {
        Ranging::about(self)
    }
}

/// clap's parser of a [`Listed`] enum: `--help` lists its values, a wrong one is refused naming
/// the option and every allowed value (as for a clap `ValueEnum`).
pub fn listed<T: Listed>() -> impl clap::builder::TypedValueParser<Value = T> {
    use clap::builder::{PossibleValue, PossibleValuesParser, TypedValueParser};
    PossibleValuesParser::new(T::all().iter().map(|v| match v.about() {
        "" => PossibleValue::new(v.name()),
        about => PossibleValue::new(v.name()).help(about),
    }))
    .map(|s| match s.parse::<T>() {
        Ok(v) => v,
        Err(_) => unreachable!("clap passes only the listed values"),
    })
}
