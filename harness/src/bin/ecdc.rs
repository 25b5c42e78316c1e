//! The `ecdc` command line: parses arguments and dispatches to `ecdc_harness::cli`.

use clap::{Parser, Subcommand};
use ecdc_harness::cli;

/// ecdc: EtherCAT Distributed Clocks, formally specified.
#[derive(Debug, Parser)]
#[command(name = "ecdc", version, about)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Debug, Subcommand)]
enum Command {
    /// Decode EtherCAT frames from a pcap file or a hex string.
    Decode(cli::decode::Args),
}

fn main() -> std::process::ExitCode {
    let cli = Cli::parse();
    let result = match &cli.command {
        Command::Decode(args) => cli::decode::run(args),
    };
    match result {
        Ok(()) => std::process::ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {e:#}");
            std::process::ExitCode::FAILURE
        }
    }
}
