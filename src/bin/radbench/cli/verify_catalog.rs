//! `radbench doctor --verify-catalog [--write-overrides FILE]`: prints, per catalog value, what the
//! instrument said (`measure::verify_catalog` asks). Exit 0 unless a value differs (exit 3, as a
//! failed doctor check).

use super::capture::{bench_source, journal, open_bench};
use radbench::exit::{Classified, ExitClass};
use radbench::measure::{self, AwgLink, CatalogCheck, ScopeLink, Verdict};

/// What `doctor --verify-catalog` was given (the doctor's own arguments, without importing
/// the doctor: it calls this).
pub(crate) struct Request<'a> {
    pub bench: Option<&'a std::path::Path>,
    pub scope_model: &'a super::scope_model::ScopeModelArgs,
    pub json: bool,
    pub write_overrides: Option<&'a std::path::Path>,
}

pub(crate) fn run(args: Request<'_>, global: &super::global::Global) -> anyhow::Result<()> {
    super::global::runtime()?.block_on(async {
        let source = args.scope_model.apply(bench_source(
            args.bench,
            None,
            AwgLink::Hislip,
            ScopeLink::Vicp,
        )?)?;
        let bench = open_bench(source, args.json).await?;
        let check = measure::verify_catalog(&bench, journal(global)?).await?;
        if args.json {
            super::terminal::out(&serde_json::to_string(&check)?)?;
        } else {
            super::terminal::out(&text(&check))?;
        }
        if let Some(path) = args.write_overrides {
            match measure::write_overrides(&check, path)? {
                Some(written) => {
                    eprintln!("wrote {}", written.display());
                    eprintln!(
                        "to use it, write catalog_overrides = \"{}\" in the bench file (relative to \
                         its folder)",
                        relative_to(&written, bench.file.path.parent()).display()
                    );
                }
                None => eprintln!(
                    "--write-overrides: no value to write (none differs, or only identities)"
                ),
            }
        }
        let differ = check.count("differs");
        if differ == 0 {
            return Ok(());
        }
        Err(anyhow::Error::new(Classified {
            class: ExitClass::Instrument,
            message: format!(
                "{differ} catalog value(s) differ from the instruments' answers: correct the \
                 instrument files, or write the instruments' answers with --write-overrides FILE"
            ),
        }))
    })
}

/// `path` as the bench file names it: relative to the bench file's folder when inside it.
fn relative_to(path: &std::path::Path, base: Option<&std::path::Path>) -> std::path::PathBuf {
    let absolute = |p: &std::path::Path| std::path::absolute(p).unwrap_or_else(|_| p.to_path_buf());
    let full = absolute(path);
    base.map(|b| {
        absolute(if b.as_os_str().is_empty() {
            std::path::Path::new(".")
        } else {
            b
        })
    })
    .and_then(|b| full.strip_prefix(b).ok().map(std::path::Path::to_path_buf))
    .unwrap_or(full)
}

/// One line per value; the answer or the reason indented under it.
fn text(check: &CatalogCheck) -> String {
    let mut out = format!("catalog check: {}\n", check.bench);
    for v in &check.values {
        out += &format!(
            "{:<5} {:<24} {:<36} {}\n",
            v.instrument,
            v.model,
            v.field,
            v.verdict.word()
        );
        out += &format!("      catalog: {}\n", v.catalog);
        match &v.verdict {
            Verdict::Confirmed { answer } => out += &format!("      answer:  {answer}\n"),
            Verdict::Differs { answer } => out += &format!("      answer:  {answer}\n"),
            Verdict::CannotBeQueried { why } => out += &format!("      why:     {why}\n"),
        }
    }
    out += &format!(
        "{} confirmed, {} differ, {} cannot be queried; nothing was switched on",
        check.count("confirmed"),
        check.count("differs"),
        check.count("cannot be queried")
    );
    out
}
