//! `ecdc decode FILE.pcap|HEX`: print each frame's datagrams as a table.

/// Arguments of `ecdc decode`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// A classic pcap file, or a frame as a hex string.
    pub input: String,
}

/// Runs `ecdc decode`.
pub fn run(_args: &Args) -> anyhow::Result<()> {
    anyhow::bail!("decode: not implemented yet")
}
