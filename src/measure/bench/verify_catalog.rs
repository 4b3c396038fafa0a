//! `radbench doctor --verify-catalog`: asks each instrument of the bench for what the catalog
//! only infers (instruments/README.md, tags [I] and [P]) and says, per value, whether the
//! instrument confirms it, answers differently (with its answer), or cannot be asked (with why:
//! radbench knows no query for it on that family, or the instrument did not answer). Nothing
//! radiating is sent: identities, `*OPT?`, the limit queries of `driver::instrument_limits`.
//! Every exchange is bounded, and the whole check by one deadline. `write_overrides` writes the differences into one overrides file for the bench's
//! `catalog_overrides`.

use crate::address::Resource;
use crate::catalog::{Catalog, InstrumentKind, InstrumentModel};
use crate::driver::family::DriverFamily;
use crate::driver::{instrument_limits, open, DriverError, Journal};
use crate::measure::bench::in_use::Bench;
use crate::measure::error::MeasureError;
use serde::Serialize;
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

/// Longest wait for one exchange (connecting included).
const EXCHANGE_LIMIT: Duration = Duration::from_secs(5);
/// Longest the whole check may take.
const DEADLINE: Duration = Duration::from_secs(40);

/// How one catalog value came out.
#[derive(Debug, Clone, PartialEq, Serialize)]
#[serde(tag = "verdict", rename_all = "snake_case")]
pub enum Verdict {
    Confirmed { answer: String },
    Differs { answer: String },
    CannotBeQueried { why: String },
}

impl Verdict {
    pub fn word(&self) -> &'static str {
        match self {
            Verdict::Confirmed { .. } => "confirmed",
            Verdict::Differs { .. } => "differs",
            Verdict::CannotBeQueried { .. } => "cannot be queried",
        }
    }
}

/// One catalog value and what the instrument said about it.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct CatalogValue {
    /// `awg`, `scope`, `tx` or `rx`.
    pub instrument: &'static str,
    /// The catalog key of its model.
    pub model: String,
    /// The field, as in the instrument file (`awg.options`, `identity`).
    pub field: String,
    /// The catalog's value.
    pub catalog: String,
    #[serde(flatten)]
    pub verdict: Verdict,
}

/// Every value checked.
#[derive(Debug, Clone, Serialize)]
pub struct CatalogCheck {
    pub bench: String,
    pub values: Vec<CatalogValue>,
}

impl CatalogCheck {
    /// How many values have this verdict's word.
    pub fn count(&self, word: &str) -> usize {
        self.values
            .iter()
            .filter(|v| v.verdict.word() == word)
            .count()
    }
}

fn no_query(family: &str) -> Verdict {
    Verdict::CannotBeQueried {
        why: format!(
            "radbench knows no remote query for it on {family}: check the datasheet, the \
             instrument's front panel or its option list, and correct the instrument file"
        ),
    }
}

fn past_deadline() -> Verdict {
    Verdict::CannotBeQueried {
        why: format!(
            "not asked: the check's deadline of {} s passed",
            DEADLINE.as_secs()
        ),
    }
}

/// How a catalog number is shown: rates in Sa/s as `6.4e10 Sa/s`, whole numbers as integers.
fn show(v: f64, unit: &str) -> String {
    match unit {
        "Sa/s" => format!("{v:e} Sa/s"),
        _ if v.fract() == 0.0 && v.abs() < 1e18 => format!("{}{unit}", v as i64),
        _ => format!("{v}{unit}"),
    }
}

/// The inferred limits of a model: field, the catalog's number, its unit (for [`show`]).
fn inferred_limits(model: &InstrumentModel) -> Vec<(&'static str, f64, &'static str)> {
    let mut out = Vec::new();
    if let Some(a) = &model.awg {
        out.extend([
            ("awg.dac_rate_min", a.dac_rate_min, "Sa/s"),
            ("awg.dac_rate_max", a.dac_rate_max, "Sa/s"),
            ("awg.dac_rate_default", a.dac_rate_default, "Sa/s"),
            (
                "awg.internal_memory_samples",
                a.internal_memory_samples as f64,
                "",
            ),
            (
                "awg.extended_memory_samples",
                a.extended_memory_samples as f64,
                "",
            ),
        ]);
    }
    if let Some(d) = &model.digitizer {
        let highest = d.sample_rates.iter().copied().fold(0.0, f64::max);
        out.extend([
            ("digitizer.sample_rates", highest, "Sa/s"),
            (
                "digitizer.max_points_per_channel",
                d.max_points_per_channel as f64,
                "",
            ),
            ("digitizer.volts_per_div_min", d.volts_per_div_min, " V"),
            ("digitizer.volts_per_div_max", d.volts_per_div_max, " V"),
            (
                "digitizer.max_sequence_segments",
                f64::from(d.max_sequence_segments),
                "",
            ),
        ]);
    }
    out
}

/// Equal within the printing precision of the instruments' replies.
fn same(a: f64, b: f64) -> bool {
    (a - b).abs() <= 1e-6 * a.abs().max(b.abs())
}

/// `awg.max_segment_id` from the installed options: without `SEQ` the M8195A keeps one segment;
/// with it, more than one, and no query says how many.
fn segment_verdict(catalog_max: u32, options: &str) -> Verdict {
    let seq = option_set(options).iter().any(|o| o == "SEQ");
    match (seq, catalog_max) {
        (false, 1) => Verdict::Confirmed {
            answer: "1 (no SEQ in *OPT?: one segment)".into(),
        },
        (false, _) => Verdict::Differs {
            answer: "1 (no SEQ in *OPT?: one segment)".into(),
        },
        (true, 1) => Verdict::Differs {
            answer: "more than 1 (SEQ in *OPT?)".into(),
        },
        (true, _) => Verdict::CannotBeQueried {
            why: "SEQ is installed, so more than one segment; the M8195A has no query for \
                  how many: check its datasheet"
                .into(),
        },
    }
}

/// What the driver's identity check made of an open (`Ok`: the identity it read).
fn identity_verdict(opened: Result<String, String>) -> Verdict {
    match opened {
        Ok(idn) => Verdict::Confirmed { answer: idn },
        Err(e) if e.contains("which is not") || e.contains("ID register") => {
            Verdict::Differs { answer: e }
        }
        Err(e) => Verdict::CannotBeQueried { why: e },
    }
}

async fn bounded<T>(
    work: impl std::future::Future<Output = Result<T, DriverError>>,
) -> Result<T, String> {
    match tokio::time::timeout(EXCHANGE_LIMIT, work).await {
        Ok(r) => r.map_err(|e| e.to_string()),
        Err(_) => Err(format!("no identity within {} s", EXCHANGE_LIMIT.as_secs())),
    }
}

/// The installed options `*OPT?` lists (blank and `0` entries dropped), sorted.
fn option_set(text: &str) -> Vec<String> {
    let mut set: Vec<String> = text
        .trim_matches('"')
        .split(',')
        .map(|o| o.trim().trim_matches('"').to_ascii_uppercase())
        .filter(|o| !o.is_empty() && o != "0")
        .collect();
    set.sort();
    set.dedup();
    set
}

/// Asks every instrument of `bench` for what its catalog entry infers. `journal`: `--trace-io`.
pub async fn verify_catalog(
    bench: &Bench,
    journal: Option<Journal>,
) -> Result<CatalogCheck, MeasureError> {
    let started = Instant::now();
    let file = &bench.file;
    let catalog: Catalog = file.catalog()?;
    let parse = |text: &str, section: &'static str| -> Result<Resource, MeasureError> {
        text.parse().map_err(|source| MeasureError::Resource {
            section,
            text: text.to_string(),
            source,
        })
    };
    let mut instruments: Vec<(&'static str, Resource, InstrumentModel)> = vec![
        (
            "awg",
            parse(&file.awg.resource, "awg")?,
            catalog.get(&file.awg.model)?.clone(),
        ),
        (
            "scope",
            parse(&file.scope.resource, "scope")?,
            catalog.get(&file.scope.model)?.clone(),
        ),
    ];
    for (name, entry) in [("tx", &file.tx), ("rx", &file.rx)] {
        if let Some(e) = entry {
            instruments.push((
                name,
                parse(&e.resource, name)?,
                catalog.get(&e.model)?.clone(),
            ));
        }
    }
    let mut values = Vec::new();
    for (name, resource, model) in &instruments {
        let late = started.elapsed() >= DEADLINE;
        let key = model.instrument.key.clone();
        // The text names the family in verdicts; the parsed family (none: unknown) picks queries.
        let family = open::spelling(model).to_string();
        let driver = open::family(model).ok();
        let value = |field: &str, catalog: String, verdict: Verdict| CatalogValue {
            instrument: name,
            model: key.clone(),
            field: field.to_string(),
            catalog,
            verdict,
        };
        let expected = format!(
            "manufacturer {}, model {}",
            model.identity.manufacturer.join(" | "),
            model.identity.model.join(" | ")
        );
        let identity = if late {
            past_deadline()
        } else {
            let j = journal.clone();
            let r = resource.clone();
            identity_verdict(match model.instrument.kind {
                InstrumentKind::Awg => bounded(open::open_awg(r, model, j, name))
                    .await
                    .map(|d| d.identity().to_string()),
                InstrumentKind::Digitizer => bounded(open::open_digitizer(r, model, j, name))
                    .await
                    .map(|d| d.identity().to_string()),
                InstrumentKind::RfTx | InstrumentKind::RfRx => {
                    bounded(open::open_rf(r, model, j, name))
                        .await
                        .map(|d| d.identity().to_string())
                }
            })
        };
        let reached = !matches!(identity, Verdict::CannotBeQueried { .. });
        values.push(value("identity", expected, identity));
        let mut options_reply: Option<Result<String, String>> = None;
        if let Some(awg) = &model.awg {
            let mut listed = awg.options.clone();
            listed.sort();
            let verdict = if started.elapsed() >= DEADLINE {
                past_deadline()
            } else if !reached {
                Verdict::CannotBeQueried {
                    why: "not asked: the instrument was not identified".into(),
                }
            } else {
                let reply = crate::driver::ask::ask_once(
                    resource.clone(),
                    model,
                    "*OPT?",
                    EXCHANGE_LIMIT,
                    journal.clone(),
                    name,
                )
                .await;
                options_reply = Some(reply.clone());
                match reply {
                    Ok(reply) if option_set(&reply) == option_set(&listed.join(",")) => {
                        Verdict::Confirmed { answer: reply }
                    }
                    Ok(reply) => Verdict::Differs { answer: reply },
                    Err(why) => Verdict::CannotBeQueried { why },
                }
            };
            values.push(value("awg.options", listed.join(","), verdict));
        }
        let read = if !reached || started.elapsed() >= DEADLINE {
            Vec::new()
        } else {
            let reach = instrument_limits::Reach {
                resource: resource.clone(),
                model,
                limit: EXCHANGE_LIMIT,
                journal: journal.clone(),
                name,
            };
            match driver {
                Some(driver) => instrument_limits::read_limits(driver, &reach).await,
                None => Vec::new(),
            }
        };
        for (field, expected, unit) in inferred_limits(model) {
            let verdict = match read.iter().find(|(f, _)| *f == field) {
                Some((_, Ok(v))) if same(*v, expected) => Verdict::Confirmed {
                    answer: show(*v, unit),
                },
                Some((_, Ok(v))) => Verdict::Differs {
                    answer: show(*v, unit),
                },
                Some((_, Err(why))) => Verdict::CannotBeQueried { why: why.clone() },
                None if !reached => Verdict::CannotBeQueried {
                    why: "not asked: the instrument was not identified".into(),
                },
                None if started.elapsed() >= DEADLINE => past_deadline(),
                None => no_query(&family),
            };
            let shown = match (field, &model.digitizer) {
                ("digitizer.sample_rates", Some(d)) => {
                    let rates: Vec<String> =
                        d.sample_rates.iter().map(|r| format!("{r:e}")).collect();
                    format!("{} Sa/s (the highest is asked)", rates.join(", "))
                }
                _ => show(expected, unit),
            };
            values.push(value(field, shown, verdict));
        }
        if let Some(awg) = &model.awg {
            let verdict = match options_reply.as_ref() {
                Some(Ok(reply)) if driver == Some(DriverFamily::KeysightM8195a) => {
                    segment_verdict(awg.max_segment_id, reply)
                }
                Some(Err(why)) => Verdict::CannotBeQueried { why: why.clone() },
                _ => no_query(&family),
            };
            values.push(value(
                "awg.max_segment_id",
                awg.max_segment_id.to_string(),
                verdict,
            ));
        }
        if model.protocol.is_some() {
            values.push(value(
                "protocol, register map",
                "project-defined".into(),
                Verdict::CannotBeQueried {
                    why: "radbench's own description, not the vendor's: the identity above is \
                          what the module answered in it; describe the module's real protocol \
                          in its instrument file (instruments/README.md)"
                        .into(),
                },
            ));
        }
    }
    Ok(CatalogCheck {
        bench: bench.describe(),
        values,
    })
}

/// The value to write for a field that differs, as the instrument file spells it (`None`: not
/// one to write down, e.g. an identity or a segment count known only as "more than 1").
fn override_value(
    v: &CatalogValue,
    answer: &str,
) -> Option<(&'static str, String, toml_edit::Value)> {
    let number = || crate::driver::ask::reply_number(answer);
    let (table, key) = v.field.split_once('.')?;
    let table: &'static str = match table {
        "awg" => "awg",
        "digitizer" => "digitizer",
        _ => return None,
    };
    let value: toml_edit::Value = match v.field.as_str() {
        "awg.options" => {
            let mut array = toml_edit::Array::new();
            for o in option_set(answer) {
                array.push(o);
            }
            array.into()
        }
        "awg.max_segment_id" if answer.starts_with("1 ") => 1i64.into(),
        "awg.max_segment_id" => return None,
        "awg.internal_memory_samples"
        | "awg.extended_memory_samples"
        | "digitizer.max_points_per_channel"
        | "digitizer.max_sequence_segments" => (number()? as i64).into(),
        "digitizer.sample_rates" => {
            // The highest rate was asked: it replaces the catalog's highest, the others stay.
            let mut rates: Vec<f64> = v
                .catalog
                .split(|c: char| c == ',' || c.is_whitespace())
                .filter_map(|t| t.parse::<f64>().ok())
                .collect();
            let top = rates.iter().copied().fold(f64::MIN, f64::max);
            rates.retain(|r| *r != top);
            rates.push(number()?);
            rates.sort_by(f64::total_cmp);
            rates.into_iter().collect::<toml_edit::Array>().into()
        }
        _ => number()?.into(),
    };
    Some((table, key.to_string(), value))
}

/// Writes the values that differ, as the instruments answered them, into the overrides file
/// `path` (one TOML file, `[<model key>.<table>]` tables; values already in it are kept unless
/// answered anew). The bench file's `catalog_overrides = "<path>"` applies it. An existing folder
/// gets `overrides.toml` inside it. Returns the file written, or `None` when nothing differs.
///
/// # Errors
/// [`MeasureError::Storage`] when the file cannot be read or written; [`MeasureError::Option`]
/// when an existing file is not an overrides file.
pub fn write_overrides(check: &CatalogCheck, path: &Path) -> Result<Option<PathBuf>, MeasureError> {
    let path = if path.is_dir() {
        path.join("overrides.toml")
    } else {
        path.to_path_buf()
    };
    let mut doc = match std::fs::read_to_string(&path) {
        Ok(text) => text.parse::<toml_edit::DocumentMut>().map_err(|e| {
            MeasureError::option(
                "write-overrides",
                path.display(),
                format!("a new file or an overrides file (this one is not TOML: {e})"),
            )
        })?,
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => {
            let mut doc = toml_edit::DocumentMut::new();
            doc.decor_mut().set_prefix(
                "# Written by `radbench doctor --verify-catalog --write-overrides`: the values this \
                 bench's\n# instruments answered differently from the catalog. Apply it with\n# \
                 catalog_overrides = \"<this file>\" in the bench file.\n",
            );
            doc
        }
        Err(e) => return Err(storage(&path, e)),
    };
    let mut wrote = false;
    for v in &check.values {
        let Verdict::Differs { answer } = &v.verdict else {
            continue;
        };
        let Some((table, key, value)) = override_value(v, answer) else {
            continue;
        };
        let model = doc
            .entry(&v.model)
            .or_insert(toml_edit::table())
            .as_table_mut()
            .ok_or_else(|| not_a_table(&path, &v.model))?;
        model.set_implicit(true);
        let section = model
            .entry(table)
            .or_insert(toml_edit::table())
            .as_table_mut()
            .ok_or_else(|| not_a_table(&path, &format!("{}.{table}", v.model)))?;
        section.insert(&key, toml_edit::value(value));
        wrote = true;
    }
    if !wrote {
        return Ok(None);
    }
    if let Some(parent) = path.parent().filter(|p| !p.as_os_str().is_empty()) {
        std::fs::create_dir_all(parent).map_err(|e| storage(parent, e))?;
    }
    crate::storage::write_atomic(&path, doc.to_string().as_bytes())?;
    Ok(Some(path))
}

fn not_a_table(path: &Path, name: &str) -> MeasureError {
    MeasureError::option(
        "write-overrides",
        path.display(),
        format!("a new file or an overrides file (`{name}` is not a table in this one)"),
    )
}

fn storage(path: &Path, e: std::io::Error) -> MeasureError {
    MeasureError::Storage(crate::storage::StorageError::Io {
        path: path.to_path_buf(),
        source: e,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn options_compare_as_sets() {
        assert_eq!(
            option_set("\"004,001, 16G,002\""),
            option_set("001,002,004,16G")
        );
        assert_ne!(option_set("001,002"), option_set("001,002,004,16G"));
        assert!(option_set("0").is_empty());
    }
}
