//! `ecdc emulate --iface IF`: serve emulated slaves on a network interface in real time
//! (host monotonic clock as true time), so any master (ours or another) can talk to them
//! over a veth pair.

use anyhow::Context;

use super::link_args::{LinkArgs, RtArgs};
use crate::runtime::clock;
use crate::runtime::serve::{self, Reflector, ServeSummary};
use crate::runtime::sys;

/// Which slave model answers.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum Engine {
    /// The ESC emulator (DC registers, drifting clocks, topology).
    Esc,
    /// One bare slave without DC: WKC + 1, ADP + 1, processed bit. Measures the socket path only.
    Reflect,
}

/// Arguments of `ecdc emulate`.
#[derive(Debug, clap::Args)]
pub struct Args {
    #[command(flatten)]
    pub link: LinkArgs,
    #[command(flatten)]
    pub rt: RtArgs,
    /// Slave model.
    #[arg(long, value_enum, default_value_t = Engine::Esc)]
    pub engine: Engine,
    /// Stop after this many seconds (default: until Ctrl-C / SIGTERM).
    #[arg(long)]
    pub duration: Option<f64>,
    /// Print a line per second with frame counters.
    #[arg(long)]
    pub stats: bool,
    /// Print the summary as JSON on stdout.
    #[arg(long)]
    pub json: bool,
}

/// Runs `ecdc emulate`.
pub fn run(args: &Args) -> anyhow::Result<()> {
    let stop = sys::install_stop_handler().context("installing the signal handler")?;
    let mut sock = args
        .link
        .open(crate::runtime::socket::FULL_PAYLOAD, false)
        .map_err(anyhow::Error::new)?;
    let rt = args.rt.apply();
    let until = args
        .duration
        .map(|s| clock::now_ns().saturating_add((s.max(0.0) * 1e9) as u64));
    let spin = if args.rt.rt { 20_000 } else { 0 };
    let print = |c: &serve::ServeCounters| {
        if args.stats {
            eprintln!(
                "emulate: received {} answered {} already-processed {} dropped {} send-errors {}",
                c.received, c.answered, c.already_processed, c.dropped, c.send_errors
            );
        }
    };
    let summary: ServeSummary = match args.engine {
        Engine::Reflect => {
            eprintln!(
                "ecdc emulate: serving 1 reflecting slave on {} ({}); Ctrl-C to stop",
                args.link.iface,
                rt.describe()
            );
            serve::serve(&mut sock, &mut Reflector, stop, until, spin, print)?
        }
        Engine::Esc => {
            anyhow::bail!(
                "emulate --engine esc: the ESC emulator (harness/src/emu) does not offer its network API yet; \
                 use --engine reflect"
            )
        }
    };
    if args.json {
        println!("{}", serde_json::to_string_pretty(&summary)?);
    } else {
        let f = &summary.frames;
        println!(
            "emulate: received {} answered {} already-processed {} dropped {} truncated {} send-errors {}; turnaround {}",
            f.received, f.answered, f.already_processed, f.dropped, f.truncated, f.send_errors, summary.turnaround
        );
    }
    Ok(())
}
