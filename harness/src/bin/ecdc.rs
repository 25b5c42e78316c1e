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
    /// Bring up DC on emulated slaves and report precision (the main job).
    Simulate(cli::simulate::Args),
    /// Serve emulated slaves on a network interface in real time.
    Emulate(cli::emulate::Args),
    /// List slaves, DC capability, topology and delays on a network interface.
    Scan(cli::scan::Args),
    /// Bring up DC and run the cyclic loop on a network interface.
    Run(cli::run::Args),
    /// Measure round trips on a network interface (back to back and inside a cycle).
    Rtt(cli::rtt::Args),
    /// Soak: simulated hours of DC under a seeded random fault schedule.
    Soak(cli::soak::Args),
    /// Benchmarks: `ecdc bench dc` compares DC precision with other masters' schemes.
    Bench(cli::bench::Args),
}

fn main() -> std::process::ExitCode {
    // Writing into a closed pipe (`ecdc decode big.pcap | head`) ends the process quietly.
    let _ = ecdc_harness::runtime::sys::default_sigpipe();
    let mut cli = Cli::parse();
    // `--duration 10s` and the older `--duration-ms 10000` fill one field.
    if let Command::Simulate(a) = &mut cli.command {
        a.duration_ms = a.duration.take().unwrap_or(a.duration_ms);
    }
    let result = match &cli.command {
        Command::Decode(args) => cli::decode::run(args),
        Command::Simulate(args) => cli::simulate::run(args),
        Command::Emulate(args) => cli::emulate::run(args),
        Command::Scan(args) => cli::scan::run(args),
        Command::Run(args) => cli::run::run(args),
        Command::Rtt(args) => cli::rtt::run(args),
        Command::Bench(args) => cli::bench::run(args),
        Command::Soak(args) => cli::soak::run(args),
    };
    // 0 ok, 1 runtime error, 2 usage error (as clap's), 3 `--check` target missed: README.
    match result {
        Ok(()) => std::process::ExitCode::from(cli::validate::EXIT_OK),
        Err(e) => {
            eprintln!("error: {e:#}");
            std::process::ExitCode::from(cli::validate::exit_code(&e))
        }
    }
}
