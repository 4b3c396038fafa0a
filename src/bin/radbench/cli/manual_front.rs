//! Manual front ends (`driver = "manual"`) at the command line: before the first RF of a run the
//! operator is told what to set and confirms on standard input; every exit then says what
//! radbench switched off and what it did not.

use radbench::driver::RfPermit;
use radbench::measure::{self, BenchFile, ManualFrontEnd};
use std::io::BufRead;
use std::path::Path;

/// Prints what radbench did and did not switch off when dropped: on a normal end, an error, a stop
/// signal (the command returns) and a panic (unwinding drops it). Empty for a bench without
/// manual front ends.
#[must_use = "the note is printed when this is dropped, at the end of the run"]
pub(crate) struct ExitNote {
    manual: Vec<ManualFrontEnd>,
}

impl ExitNote {
    /// The user's permit (the caller checked `--allow-rf`), carrying the operator's
    /// confirmation of the manual front ends when there are any: the library refuses a bench
    /// with manual front ends without it.
    pub(crate) fn permit(&self) -> RfPermit {
        let permit = RfPermit::granted_by_user();
        if self.manual.is_empty() {
            permit
        } else {
            permit.with_manual_front_ends_confirmed()
        }
    }
}

impl Drop for ExitNote {
    fn drop(&mut self) {
        if !self.manual.is_empty() {
            eprintln!("{}", measure::manual_exit_note(&self.manual));
        }
    }
}

/// [`confirm`] for the bench file at `path` (none: the built-in mock lab, nothing manual).
pub(crate) fn confirm_file(path: Option<&Path>, run: &str) -> anyhow::Result<ExitNote> {
    match path {
        Some(p) => confirm(Some(&BenchFile::load(p)?), run),
        None => confirm(None, run),
    }
}

/// When `bench` has manual front ends: prints what to set and reads one line of standard input;
/// anything but the confirmation refuses the run (exit 2, as without --allow-rf) with nothing
/// switched on. Call after the permit check and before the stop signals are taken over, so a
/// Ctrl-C at the prompt ends radbench at once (nothing is on yet).
pub(crate) fn confirm(bench: Option<&BenchFile>, run: &str) -> anyhow::Result<ExitNote> {
    let Some(bench) = bench.filter(|b| !b.manual.is_empty()) else {
        return Ok(ExitNote { manual: Vec::new() });
    };
    let catalog = bench.catalog().ok();
    eprint!(
        "{}",
        measure::manual_instructions(bench, catalog.as_ref(), run)
    );
    let mut answer = String::new();
    // End of input or an unreadable one is no confirmation.
    let _ = std::io::stdin().lock().read_line(&mut answer);
    eprintln!();
    if !measure::confirms(&answer) {
        return Err(radbench::exit::bad_input(format!(
            "{}. {}",
            measure::manual_refused(&bench.manual, run),
            measure::manual_exit_note(&bench.manual)
        )));
    }
    eprintln!(
        "confirmed: the {} settings are the operator's",
        bench
            .manual
            .iter()
            .map(ManualFrontEnd::name)
            .collect::<Vec<_>>()
            .join(" and ")
    );
    Ok(ExitNote {
        manual: bench.manual.clone(),
    })
}
