//! `ecdc scan`.

/// Arguments of `ecdc scan`.
#[derive(Debug, clap::Args)]
pub struct Args {}

/// Runs `ecdc scan`.
pub fn run(_args: &Args) -> anyhow::Result<()> {
    anyhow::bail!("scan: not implemented yet")
}
