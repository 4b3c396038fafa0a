//! Front ends with `driver = "manual"`: radbench never talks to them. It tells the operator what
//! to set before the first RF of a run, takes the operator's confirmation, and on every exit says
//! what it switched off (the AWG's outputs, the only RF source it controls then) and what it did
//! not (the manual modules).

use super::bench_file::{BenchFile, ManualFrontEnd};
use crate::catalog::Catalog;

/// The bench's RF frequency, told to the operator when the bench file gives none.
const DEFAULT_RF_HZ: f64 = 80e9;

/// The answer that confirms the manual front ends are set (case-insensitive, trimmed).
pub(crate) const MANUAL_CONFIRMATION: &str = "yes";

/// Whether `answer` (one line of standard input) confirms.
pub fn confirms(answer: &str) -> bool {
    answer.trim().eq_ignore_ascii_case(MANUAL_CONFIRMATION)
}

/// `Tx`, `Rx` or `Tx and Rx`.
pub(crate) fn names(manual: &[ManualFrontEnd]) -> String {
    manual
        .iter()
        .map(ManualFrontEnd::name)
        .collect::<Vec<_>>()
        .join(" and ")
}

/// What the operator must set on each manual front end before `run` (`capture`, `campaign run`,
/// ...), and how to confirm. `catalog`: the bench's, for the LO multiplier of a named model.
pub fn manual_instructions(bench: &BenchFile, catalog: Option<&Catalog>, run: &str) -> String {
    let mut out = format!(
        "{} {} manual (driver = \"manual\"): radbench does not talk to {}. Before this {run} \
         radiates, set by hand:\n",
        names(&bench.manual),
        if bench.manual.len() > 1 { "are" } else { "is" },
        if bench.manual.len() > 1 { "them" } else { "it" },
    );
    for m in &bench.manual {
        let rf = m.rf_frequency_hz.unwrap_or(DEFAULT_RF_HZ);
        let multiplier = m
            .model
            .as_ref()
            .and_then(|k| catalog?.get(k).ok())
            .and_then(|model| model.rf.as_ref())
            .map(|rf| rf.lo_multiplier);
        let lo = match multiplier {
            Some(k) if k > 0 => format!(" (LO {:.4} GHz, x{k})", rf / f64::from(k) / 1e9),
            _ => String::new(),
        };
        let att = match m.attenuation_db {
            Some(a) => format!("{a:.1} dB"),
            None => "as for your link budget (the bench file gives no attenuation_db)".into(),
        };
        let enable = if m.section == "tx" {
            "transmitter enabled (RF on)"
        } else {
            "receiver enabled"
        };
        out += &format!(
            "  {}: RF {:.3} GHz{lo}, attenuation {att}, {enable}\n",
            m.name(),
            rf / 1e9
        );
    }
    out += &format!(
        "radbench switches only the AWG's outputs on and off; it cannot switch the {} off. \
         Type {MANUAL_CONFIRMATION} and Enter once set (anything else stops with nothing \
         switched on): ",
        names(&bench.manual)
    );
    out
}

/// The doctor's advice for a manual front end.
pub(crate) fn manual_doctor_fix(m: &ManualFrontEnd) -> String {
    format!(
        "set the {0} module by hand before each run and switch it off by hand after it (radbench \
         switches only the AWG's outputs off); give the bench file's [{1}] a model and resource \
         instead of driver = \"manual\" once its protocol is described in the catalog",
        m.name(),
        m.section
    )
}

/// The refusal when the operator did not confirm: nothing was switched on.
pub fn manual_refused(manual: &[ManualFrontEnd], run: &str) -> String {
    format!(
        "the {} front end settings were not confirmed (answer {MANUAL_CONFIRMATION:?} on \
         standard input, e.g. `echo {MANUAL_CONFIRMATION} | radbench ...`): the {run} did not \
         start and nothing was switched on",
        names(manual)
    )
}

/// What radbench did and did not switch off, for every exit of a run with manual front ends
/// (from what the drivers recorded in this process).
pub fn manual_exit_note(manual: &[ManualFrontEnd]) -> String {
    let awg = crate::driver::snapshot()
        .into_iter()
        .find(|(name, _)| name == "awg")
        .map(|(_, on)| on);
    let awg = match awg {
        None => "radbench did not connect to the AWG and switched nothing on",
        Some(false) => "radbench switched the AWG outputs off and stopped the AWG",
        Some(true) => {
            "radbench could NOT confirm the AWG outputs off: switch them off by hand at the AWG"
        }
    };
    let manual_names = names(manual);
    let verb = if manual.len() > 1 { "are" } else { "is" };
    let module = if manual.len() > 1 {
        "modules"
    } else {
        "module"
    };
    format!(
        "{manual_names} {verb} manual: {awg}; it did not switch the {manual_names} {module} \
         off: switch {} off by hand",
        if manual.len() > 1 { "them" } else { "it" }
    )
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::path::Path;

    const MANUAL: &str = r#"
[awg]
model = "keysight-m8195a"
resource = "TCPIP::127.0.0.1::hislip0::INSTR"

[scope]
model = "lecroy-labmaster10zi-a"
resource = "VICP::127.0.0.1"

[tx]
driver = "manual"
model = "gotmic-eband-tx"
attenuation_db = 10.0

[rx]
driver = "manual"
"#;

    #[test]
    fn manual_front_ends_are_taken_out_and_described() {
        let bench = BenchFile::parse(MANUAL, Path::new("b.toml")).unwrap();
        assert!(bench.tx.is_none() && bench.rx.is_none());
        assert_eq!(bench.manual.len(), 2);
        let catalog = Catalog::embedded().unwrap();
        bench.check_models(&catalog).unwrap();
        let text = manual_instructions(&bench, Some(&catalog), "capture");
        assert!(text.contains("Tx and Rx are manual"), "{text}");
        assert!(
            text.contains("Tx: RF 80.000 GHz (LO 13.3333 GHz, x6), attenuation 10.0 dB"),
            "{text}"
        );
        assert!(
            text.contains("Rx: RF 80.000 GHz, attenuation as for"),
            "{text}"
        );
        assert!(confirms(" YES\n") && !confirms("y") && !confirms(""));
    }

    #[test]
    fn a_manual_front_end_with_a_resource_or_a_wrong_model_is_refused() {
        let with_resource = MANUAL.replace(
            "[rx]\ndriver = \"manual\"\n",
            "[rx]\ndriver = \"manual\"\nresource = \"ASRL/dev/ttyUSB1::INSTR\"\n",
        );
        let e = BenchFile::parse(&with_resource, Path::new("b.toml")).unwrap_err();
        assert!(
            e.to_string().contains("[rx] resource") && e.to_string().contains("not connected"),
            "{e}"
        );
        let wrong = MANUAL.replace("model = \"gotmic-eband-tx\"", "model = \"gotmic-eband-rx\"");
        let b = BenchFile::parse(&wrong, Path::new("b.toml")).unwrap();
        let e = b
            .check_models(&Catalog::embedded().unwrap())
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("[tx] model") && e.contains("gotmic-eband-tx"),
            "{e}"
        );
        let driven_without_resource = MANUAL.replace(
            "[rx]\ndriver = \"manual\"\n",
            "[rx]\nmodel = \"gotmic-eband-rx\"\n",
        );
        let e = BenchFile::parse(&driven_without_resource, Path::new("b.toml")).unwrap_err();
        assert!(
            e.to_string().contains("[rx] resource: missing")
                && e.to_string().contains("driver = \"manual\""),
            "{e}"
        );
    }
}
