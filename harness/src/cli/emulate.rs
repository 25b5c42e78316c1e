//! `ecdc emulate`.

/// Arguments of `ecdc emulate`.
#[derive(Debug, clap::Args)]
pub struct Args {}

/// Runs `ecdc emulate`.
pub fn run(_args: &Args) -> anyhow::Result<()> {
    anyhow::bail!("emulate: not implemented yet")
}
