//! Library enums the command line and the files take by name ([`Listed`]), and clap's parser
//! of them ([`listed`]): one spelling per value, its `FromStr` and a line of help.
//!
//! An enum's tables are derived from the enum itself, so a new variant is in all of them:
//!
//! ```text
//! #[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
//! #[serde(rename_all = "kebab-case")]
//! #[derive(strum::VariantArray, strum::IntoStaticStr, strum::EnumMessage)]
//! #[strum(serialize_all = "kebab-case")]
//! pub enum DetectorName {
//!     /// Cell-averaging CFAR.
//!     CaCfar,
//!     /// Greatest-of CFAR (robust at clutter edges, masks close targets).
//!     #[strum(message = "Greatest-of CFAR")]
//!     GoCfar,
//! }
//! named_enum!(DetectorName, "detector");
//! ```
//!
//! - every value: `VariantArray`'s `VARIANTS`, in declaration order (the order `--help` lists);
//! - its spelling: `IntoStaticStr`, by `#[strum(serialize_all = ...)]` (the same case as serde's
//!   `rename_all`: a test here holds the two together) or a variant's `#[strum(serialize = ...)]`;
//! - its line of help: `EnumMessage`, the variant's `#[strum(message = "...")]`, or else its
//!   one-line `///` doc comment without the final period (as clap takes an argument's), or
//!   nothing;
//! - `named_enum!` (src/lib.rs) adds `name()`, `FromStr` (its error names the kind and lists the
//!   allowed values) and `Display`.
//!
//! The enum is then [`Listed`] (a blanket impl here), and `listed::<T>()` is clap's parser of it.
//! The built-in lab's scope model is not an enum but a row of the lab's table of scopes (`mock_lab`'s
//! `SCOPES`, which [`ScopeModel::ALL`] is): [`scope_models`] is its parser.

use crate::measure::bench::in_use::ScopeModel;
use strum::{EnumMessage, VariantArray};

/// A library enum the command line takes by name: its values (with a line of help each) and its
/// `FromStr`, so clap parses the library's own type (no mirror enum here). Every enum with the
/// derives and `named_enum!` above is one.
pub trait Listed: std::str::FromStr + Copy + Send + Sync + 'static {
    fn all() -> &'static [Self];
    fn name(self) -> &'static str;
    fn about(self) -> &'static str;
}

impl<T> Listed for T
where
    T: VariantArray
        + EnumMessage
        + Into<&'static str>
        + std::str::FromStr
        + Copy
        + Send
        + Sync
        + 'static,
{
    fn all() -> &'static [Self] {
        T::VARIANTS
    }

    fn name(self) -> &'static str {
        self.into()
    }

    fn about(self) -> &'static str {
        match self.get_message() {
            Some(message) => message,
            None => match self.get_documentation() {
                Some(doc) => doc.strip_suffix('.').unwrap_or(doc),
                None => "",
            },
        }
    }
}

/// clap's parser of a [`Listed`] enum: `--help` lists its values, a wrong one is refused naming
/// the option and every allowed value (as for a clap `ValueEnum`).
pub fn listed<T: Listed>() -> impl clap::builder::TypedValueParser<Value = T> {
    parser(T::all().iter().map(|v| (v.name(), v.about())))
}

/// clap's parser of `--scope-model`: the names of the lab's table of scopes, each with its line of
/// help, as [`listed`] parses an enum.
pub fn scope_models() -> impl clap::builder::TypedValueParser<Value = ScopeModel> {
    parser(ScopeModel::ALL.iter().map(|m| (m.name(), m.about())))
}

/// The values (name and line of help) clap lists and passes to `T`'s `FromStr`.
fn parser<T: std::str::FromStr + Clone + Send + Sync + 'static>(
    values: impl Iterator<Item = (&'static str, &'static str)>,
) -> impl clap::builder::TypedValueParser<Value = T> {
    use clap::builder::{PossibleValue, PossibleValuesParser, TypedValueParser};
    PossibleValuesParser::new(values.map(|(name, about)| match about {
        "" => PossibleValue::new(name),
        about => PossibleValue::new(name).help(about),
    }))
    .map(|s| match s.parse::<T>() {
        Ok(v) => v,
        Err(_) => unreachable!("clap passes only the listed values"),
    })
}

/// A test of a [`Listed`] enum: every value's spelling is serde's (files and the command line
/// spell it alike) and parses back, its line of help is one line; a wrong value's error names the
/// kind (`what`) and lists every allowed value.
#[cfg(test)]
pub(crate) fn check_listed<T>(what: &str)
where
    T: Listed + serde::Serialize + PartialEq + std::fmt::Debug,
    T::Err: std::fmt::Display,
{
    assert!(!T::all().is_empty());
    for &v in T::all() {
        let serde_name = serde_json::to_value(v).unwrap();
        assert_eq!(serde_name.as_str(), Some(v.name()), "{what}: {v:?}");
        assert_eq!(v.name().parse::<T>().ok(), Some(v), "{what}: {v:?}");
        let about = v.about();
        assert!(
            !about.contains('\n') && !about.ends_with('.'),
            "{what} {v:?}: help {about:?} is not one line without a final period: give it a \
             #[strum(message = \"...\")]"
        );
    }
    let err = match "no-such-value".parse::<T>() {
        Ok(v) => panic!("{what}: `no-such-value` parsed as {v:?}"),
        Err(e) => e.to_string(),
    };
    assert!(
        err.starts_with(&format!("unknown {what} `no-such-value`: allowed: ")),
        "{err}"
    );
    for &v in T::all() {
        assert!(err.contains(v.name()), "{err}");
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::measure::{
        Algorithm, AwgLink, CorrectionMode, DetectorName, FftPrecisionName, Ranging, ScopeLink,
        WindowName,
    };
    use crate::waveform::WaveformKind;

    /// (`CarrierPhase`, of a layer above, is checked in `simulate::scene`.)
    #[test]
    fn spellings_are_serde_s_and_helps_are_one_line() {
        check_listed::<WaveformKind>("waveform");
        check_listed::<Algorithm>("algorithm");
        check_listed::<WindowName>("window");
        check_listed::<FftPrecisionName>("FFT precision");
        check_listed::<DetectorName>("detector");
        check_listed::<Ranging>("ranging");
        check_listed::<AwgLink>("AWG transport");
        check_listed::<ScopeLink>("scope transport");
        check_listed::<CorrectionMode>("correction");
    }
}
