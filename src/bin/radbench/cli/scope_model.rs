//! `--scope-model`: the scope the built-in mock lab serves, one option shared by every command
//! that can start the lab (capture, align, doctor, calibrate and calibrate response). Its values
//! and their help come from the lab's table of scopes.

use radbench::exit::bad_input;
use radbench::measure::{BenchSource, ScopeModel};

#[derive(Debug, Clone, Copy, Default, clap::Args)]
pub struct ScopeModelArgs {
    /// Built-in mock lab only: the scope it serves (default: lecroy). With --bench, the bench
    /// file's [scope] model names the scope.
    #[arg(long, value_parser = super::args::scope_models(), value_name = "MODEL")]
    pub scope_model: Option<ScopeModel>,
}

impl ScopeModelArgs {
    /// Applies the option to the built-in lab; refused beside a bench file (the file names the
    /// scope).
    pub(crate) fn apply(self, mut source: BenchSource) -> anyhow::Result<BenchSource> {
        match (&mut source, self.scope_model) {
            (_, None) => {}
            (BenchSource::BuiltIn(b), Some(m)) => b.scope_model = m,
            (BenchSource::File(_), Some(_)) => {
                return Err(bad_input(
                    "--scope-model applies to the built-in mock lab only: with --bench, the bench \
                     file's [scope] model names the scope",
                ))
            }
        }
        Ok(source)
    }
}
