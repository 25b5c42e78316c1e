//! `ecdc run`.

/// Arguments of `ecdc run`.
#[derive(Debug, clap::Args)]
pub struct Args {}

/// Runs `ecdc run`.
pub fn run(_args: &Args) -> anyhow::Result<()> {
    anyhow::bail!("run: not implemented yet")
}
