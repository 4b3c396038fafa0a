//! `radbench bench`.

#[derive(Debug, clap::Args)]
pub struct Args {}

pub fn run(_args: Args, _global: &super::Global) -> anyhow::Result<()> {
    anyhow::bail!("bench: under construction")
}
