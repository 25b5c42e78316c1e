//! `ecdc emulate --iface IF`: serve emulated slaves on a network interface in real time
//! (host monotonic clock as true time), so any master (ours or another) can talk to them
//! over a veth pair.

use anyhow::Context;

use super::link_args::RtLinkArgs;
use super::validate;
use crate::emu::scenario::MAX_SLAVES;
use crate::emu::yardstick::{SlaveReport, SyncReport, Yardstick, YardstickOpts};
use crate::emu::{Delivery, Network, Scenario};
use crate::runtime::clock;
use crate::runtime::serve::{self, Reflector, Responder, ServeSummary};
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
    pub io: RtLinkArgs,
    /// Slave model.
    #[arg(long, value_enum, default_value_t = Engine::Esc)]
    pub engine: Engine,
    /// Number of default slaves in a line, 1..=65535 (not with --scenario).
    #[arg(long, default_value_t = 3, allow_negative_numbers = true,
          value_parser = validate::usize_in(1, MAX_SLAVES), conflicts_with = "scenario")]
    pub slaves: usize,
    /// Scenario file (TOML or JSON, see docs/emulator.md): topology, delays, crystals, faults.
    #[arg(long)]
    pub scenario: Option<std::path::PathBuf>,
    /// Override the scenario's random seed (0..=2^64-1).
    #[arg(long, allow_negative_numbers = true, value_parser = validate::u64_in(0, u64::MAX))]
    pub seed: Option<u64>,
    /// Override the scenario's frame loss probability (0..=1).
    #[arg(long, allow_negative_numbers = true, value_parser = validate::f64_in(0.0, 1.0))]
    pub loss_rate: Option<f64>,
    /// Stop after this long: `10s`, `500ms`, `2min` (a bare number is seconds) [default: until
    /// Ctrl-C / SIGTERM].
    #[arg(long, allow_negative_numbers = true, value_parser = validate::seconds)]
    pub duration: Option<f64>,
    /// Print a line per second with frame counters and the DC yardstick so far.
    #[arg(long)]
    pub stats: bool,
    /// Print the summary as JSON on stdout.
    #[arg(long)]
    pub json: bool,
}

/// Runs `ecdc emulate`.
pub fn run(args: &Args) -> anyhow::Result<()> {
    // Every input is checked before the interface is touched.
    validate::cpu("--cpu", args.io.rt.cpu)?;
    let scenario = match args.engine {
        Engine::Esc => Some(load_scenario(args)?),
        Engine::Reflect => {
            let esc_only = [
                ("--scenario", args.scenario.is_some()),
                ("--seed", args.seed.is_some()),
                ("--loss-rate", args.loss_rate.is_some()),
            ];
            if let Some((flag, _)) = esc_only.iter().find(|(_, given)| *given) {
                return Err(validate::usage(format!(
                    "{flag} configures the ESC emulator and has no effect with --engine reflect"
                )));
            }
            None
        }
    };
    let stop = sys::install_stop_handler().context("installing the signal handler")?;
    let mut sock = args
        .io
        .link
        .open(crate::runtime::socket::FULL_PAYLOAD, false)
        .map_err(anyhow::Error::new)?;
    let rt = args.io.rt.apply();
    let until = args
        .duration
        .map(|s| clock::now_ns().saturating_add((s.max(0.0) * 1e9) as u64));
    // The emulated wire time is a few us: a sleep that short costs a whole wake-up (tens of
    // us on a VM), so spin for it instead.
    let spin = 200_000;
    let print = |c: &serve::ServeCounters, sync: Option<&SyncReport>| {
        if args.stats {
            eprintln!(
                "emulate: received {} answered {} already-processed {} dropped {} send-errors {}{}",
                c.received,
                c.answered,
                c.already_processed,
                c.dropped,
                c.send_errors,
                sync.map(sync_line).unwrap_or_default()
            );
        }
    };
    let report: Report = match args.engine {
        Engine::Reflect => {
            eprintln!(
                "ecdc emulate: serving 1 reflecting slave on {} ({}); Ctrl-C to stop",
                args.io.link.iface,
                rt.describe()
            );
            let s = serve::serve(&mut sock, &mut Reflector, stop, until, spin, |c, _| {
                print(c, None)
            })?;
            Report {
                serve: s,
                sync: None,
                slaves: None,
            }
        }
        Engine::Esc => {
            let scenario =
                scenario.ok_or_else(|| anyhow::anyhow!("no scenario for the esc engine"))?;
            let net =
                Network::new(&scenario).map_err(|e| anyhow::anyhow!("emulator scenario: {e}"))?;
            let n = net.slave_count();
            let yardstick = Yardstick::new(&net, YardstickOpts::default());
            let mut esc = EscResponder {
                net,
                mono_start: clock::now_ns(),
                sync_edges: 0,
                yardstick,
                error: None,
            };
            eprintln!(
                "ecdc emulate: serving {n} emulated ESCs on {} ({}); Ctrl-C to stop",
                args.io.link.iface,
                rt.describe()
            );
            let s = serve::serve(&mut sock, &mut esc, stop, until, spin, |c, r| {
                print(c, Some(&r.yardstick.report()))
            })?;
            if let Some(e) = &esc.error {
                eprintln!("emulate: yardstick stopped sampling: {e}");
            }
            let st = esc.net.stats();
            eprintln!(
                "emulate: emulator frames {} returned {} lost {}; SYNC edges {}",
                st.frames, st.returned, st.lost, esc.sync_edges
            );
            Report {
                serve: s,
                sync: Some(esc.yardstick.report()),
                slaves: Some(esc.yardstick.slaves(&esc.net)),
            }
        }
    };
    let summary = &report.serve;
    if args.json {
        println!("{}", serde_json::to_string_pretty(&report)?);
    } else {
        let f = &summary.frames;
        println!(
            "emulate: received {} answered {} (kernel-stamped {}) already-processed {} dropped {} truncated {} \
             send-errors {}; turnaround from arrival {}",
            f.received,
            f.answered,
            f.stamped,
            f.already_processed,
            f.dropped,
            f.truncated,
            f.send_errors,
            summary.turnaround
        );
        if let Some(sync) = &report.sync {
            println!("emulate: {}", sync_line(sync).trim_start_matches("; "));
        }
    }
    Ok(())
}

/// What `ecdc emulate` reports: the frame accounting, and with the ESC engine the yardstick
/// (docs/emulator.md "DC yardstick").
#[derive(Debug, serde::Serialize)]
struct Report {
    #[serde(flatten)]
    serve: ServeSummary,
    #[serde(skip_serializing_if = "Option::is_none")]
    sync: Option<SyncReport>,
    #[serde(skip_serializing_if = "Option::is_none")]
    slaves: Option<Vec<SlaveReport>>,
}

/// The yardstick's figures for a `--stats` or summary line.
fn sync_line(s: &SyncReport) -> String {
    let ns = |v: Option<f64>| v.map_or("-".to_string(), |v| format!("{v:.1}"));
    let int = |v: Option<u64>| v.map_or("-".to_string(), |v| v.to_string());
    let lock = match s.lock_ms {
        Some(ms) => format!("locked {ms:.1} ms after the first SYNC0"),
        None => "not locked".to_string(),
    };
    format!(
        "; SYNC0 firing {} pairs {} skew mean {} p99 {} max {} ns; {lock}",
        s.slaves_firing,
        s.pairs,
        ns(s.skew.mean_ns),
        int(s.skew.p99_ns),
        int(s.skew.max_ns)
    )
}

fn load_scenario(args: &Args) -> anyhow::Result<Scenario> {
    if args.scenario.is_none() && !(1..=MAX_SLAVES).contains(&args.slaves) {
        return Err(validate::usage(format!(
            "--slaves {}: valid: 1..={MAX_SLAVES}",
            args.slaves
        )));
    }
    let mut sc = match &args.scenario {
        Some(path) => validate::load_scenario("--scenario", path)?,
        None => Scenario::line(args.slaves),
    };
    if let Some(seed) = args.seed {
        sc.seed = seed;
    }
    if let Some(p) = args.loss_rate {
        if !(0.0..=1.0).contains(&p) {
            return Err(validate::usage(format!("--loss-rate {p}: valid: 0..=1")));
        }
        sc.frame_loss_rate = p;
    }
    let run_ns = args.duration.map(|s| (s * 1e9) as u64);
    validate::scenario(&sc, args.scenario.as_deref(), run_ns)?;
    Ok(sc)
}

/// The ESC emulator as a [`Responder`]: true time = host monotonic time since start; the
/// yardstick watches every frame's effects.
struct EscResponder {
    net: Network,
    mono_start: u64,
    sync_edges: u64,
    yardstick: Yardstick,
    /// The first error of the yardstick's clock sampling (it then stops sampling).
    error: Option<String>,
}

impl Responder for EscResponder {
    fn respond(&mut self, now_ns: u64, buf: &mut [u8], len: usize) -> Option<(usize, u64)> {
        let t = now_ns.saturating_sub(self.mono_start).max(self.net.now());
        let frame = buf.get(..len)?;
        let delivery = self.net.transact(frame, t).ok()?;
        // SYNC edges are logged by the emulator; drain them so a long run does not grow memory.
        let edges = self.net.take_sync_edges();
        self.sync_edges += edges.len() as u64;
        if self.error.is_none() {
            if let Err(e) = self.yardstick.observe(&mut self.net, &edges) {
                self.error = Some(e.to_string());
            }
        }
        match delivery {
            Delivery::Returned(r) => {
                let out = buf.get_mut(..r.frame.len())?;
                out.copy_from_slice(&r.frame);
                Some((r.frame.len(), self.mono_start.saturating_add(r.arrival)))
            }
            Delivery::Lost(_) => None,
        }
    }
}
