//! `ecdc simulate`.

/// Arguments of `ecdc simulate`.
#[derive(Debug, clap::Args)]
pub struct Args {}

/// Runs `ecdc simulate`.
pub fn run(_args: &Args) -> anyhow::Result<()> {
    anyhow::bail!("simulate: not implemented yet")
}
