//! `ecdc scan --iface IF`: slaves, station addresses, DC capability (none / delay-only /
//! 32 / 64 bit), the topology tree and the measured propagation delays.
//!
//! It runs the core DC machine up to the delay measurement and stops there: the only writes
//! are the station addresses (0x0010), the receive-time latch trigger (BWR 0x0900) and, during
//! the t_Diff measurement, DL control 0x0100 (ports closed one slave at a time and restored to
//! the value read; skipped when a slave is in SAFE-OP/OP), never an offset, a delay register or
//! a SYNC unit. Each slave's t_Diff and its source are listed (REQ-DC-126).

use anyhow::Context;
use ecdc_core::dc::port::{Port, PortSet};
use ecdc_core::dc::topology::{Latches, SlaveSample, Topology};
use ecdc_core::dc::{Config, DcKind, Machine, SlaveInfo};
use ecdc_core::wire::MASTER_MAC;

use super::link_args::LinkArgs;
use crate::runtime::bringup::{self, Limits, Outcome, Until};
use crate::runtime::clock::DcClock;
use crate::runtime::sys;
use crate::runtime::transport::{Counters, Transport};

/// Largest network `scan` and `run` handle (slave capacity of the DC machine).
pub const MAX_SLAVES: usize = 256;

/// Arguments of `ecdc scan`.
#[derive(Debug, clap::Args)]
pub struct Args {
    #[command(flatten)]
    pub link: LinkArgs,
    /// Print JSON on stdout instead of tables.
    #[arg(long)]
    pub json: bool,
}

/// One slave as `scan` reports it.
#[derive(Debug, Clone, serde::Serialize)]
pub struct ScannedSlave {
    /// Auto-increment position.
    pub position: u16,
    /// Station address assigned.
    pub station: u16,
    /// "none", "delay-only", "32-bit" or "64-bit".
    pub dc: &'static str,
    /// ESC features 0x0008.
    pub features: u16,
    /// DL status 0x0110.
    pub dl_status: u16,
    /// Open ports.
    pub open_ports: Vec<u8>,
    /// Entry port (towards the master), from the topology.
    pub entry_port: Option<u8>,
    /// Upstream slave position and its port, `None` = wired to the master.
    pub parent: Option<(u16, u8)>,
    /// Propagation delay from the reference clock, ns (DC slaves).
    pub delay_ns: Option<u32>,
    /// t_Diff the delay measurement used, ns, and where it came from (REQ-DC-126).
    pub t_diff_ns: Option<i32>,
    /// Source of `t_diff_ns`: "measured", "same type as N", "configured", "fallback: …",
    /// "default".
    pub t_diff_source: Option<String>,
    /// Port receive times of the last latch (local time, ns; open ports only).
    pub receive_times: Vec<(u8, u32)>,
}

/// The scan result.
#[derive(Debug, Clone, serde::Serialize)]
pub struct ScanReport {
    /// Interface.
    pub iface: String,
    /// Slaves in position order.
    pub slaves: Vec<ScannedSlave>,
    /// Position of the DC reference clock.
    pub reference: Option<u16>,
    /// Why the topology could not be built, if it could not.
    pub topology_error: Option<String>,
    /// Frame accounting.
    pub frames: Counters,
}

/// Human-readable DC kind.
pub fn dc_name(k: DcKind) -> &'static str {
    match k {
        DcKind::None => "none",
        DcKind::DelayOnly => "delay-only",
        DcKind::Bits32 => "32-bit",
        DcKind::Bits64 => "64-bit",
    }
}

fn open_ports(p: PortSet) -> Vec<u8> {
    (0..4u8)
        .filter_map(Port::from_number)
        .filter(|q| p.contains(*q))
        .map(|q| q.number())
        .collect()
}

/// Builds the report from the machine's slave table (shared with `run`).
pub fn report_slaves<const N: usize>(
    slaves: &[SlaveInfo],
    measured: bool,
) -> (Vec<ScannedSlave>, Option<String>) {
    let samples: Vec<SlaveSample> = slaves
        .iter()
        .map(|s| SlaveSample {
            ports: PortSet::from_dl_status(s.dl_status),
            latches: (measured && s.dc.has_latches())
                .then(|| Latches::from_raw(s.times_after, s.epu_time)),
            t_diff: 0,
        })
        .collect();
    let topo = Topology::<N>::build(&samples);
    let topo_err = topo.as_ref().err().map(|e| format!("{e:?}"));
    let out = slaves
        .iter()
        .enumerate()
        .map(|(i, s)| {
            let ports = PortSet::from_dl_status(s.dl_status);
            let node = topo.as_ref().ok().and_then(|t| t.node(i).copied());
            ScannedSlave {
                position: u16::try_from(i).unwrap_or(u16::MAX),
                station: s.station,
                dc: dc_name(s.dc),
                features: s.features,
                dl_status: s.dl_status,
                open_ports: open_ports(ports),
                entry_port: node.map(|n| n.entry.number()),
                parent: node
                    .and_then(|n| n.parent)
                    .map(|l| (l.slave, l.port.number())),
                delay_ns: (measured && s.dc.has_latches()).then_some(s.delay_ns),
                t_diff_ns: measured.then_some(s.t_diff_ns),
                t_diff_source: measured.then(|| s.t_diff_source.to_string()),
                receive_times: if measured && s.dc.has_latches() {
                    open_ports(ports)
                        .into_iter()
                        .map(|p| (p, s.times_after[usize::from(p)]))
                        .collect()
                } else {
                    Vec::new()
                },
            }
        })
        .collect();
    (out, topo_err)
}

/// Prints the slave table and the tree.
pub fn print_slaves(slaves: &[ScannedSlave], reference: Option<u16>, topology_error: Option<&str>) {
    println!(
        "{:>4}  {:>7}  {:<10}  {:<8}  {:>5}  {:<12}  {:>9}  {:>8}  t_Diff source",
        "pos", "station", "DC", "ports", "entry", "parent", "delay ns", "t_Diff"
    );
    for s in slaves {
        let ports = s
            .open_ports
            .iter()
            .map(u8::to_string)
            .collect::<Vec<_>>()
            .join(",");
        let parent = match s.parent {
            None => "master".to_owned(),
            Some((p, port)) => format!(
                "{:#06x}:{port}",
                slaves.get(usize::from(p)).map_or(0, |x| x.station)
            ),
        };
        let delay = s.delay_ns.map_or("-".to_owned(), |d| d.to_string());
        let t_diff = s.t_diff_ns.map_or("-".to_owned(), |d| d.to_string());
        let source = s.t_diff_source.as_deref().unwrap_or("-");
        let refmark = if reference == Some(s.position) {
            "  (reference clock)"
        } else {
            ""
        };
        println!(
            "{:>4}  {:>7}  {:<10}  {:<8}  {:>5}  {:<12}  {:>9}  {:>8}  {source}{refmark}",
            s.position,
            format!("{:#06x}", s.station),
            s.dc,
            ports,
            s.entry_port.map_or("-".to_owned(), |e| e.to_string()),
            parent,
            delay,
            t_diff
        );
    }
    match topology_error {
        Some(e) => println!("topology: could not be reconstructed ({e})"),
        None => {
            println!("topology:");
            println!("master");
            print_children(slaves, None, "");
        }
    }
}

fn print_children(slaves: &[ScannedSlave], parent: Option<u16>, indent: &str) {
    let kids: Vec<&ScannedSlave> = slaves
        .iter()
        .filter(|s| s.parent.map(|p| p.0) == parent)
        .collect();
    for (k, s) in kids.iter().enumerate() {
        let last = k + 1 == kids.len();
        let port = s
            .parent
            .map_or(String::new(), |(_, p)| format!("[port {p}] "));
        println!(
            "{indent}{} {port}{:#06x} (pos {}, DC {})",
            if last { "└─" } else { "├─" },
            s.station,
            s.position,
            s.dc
        );
        let next = format!("{indent}{}", if last { "   " } else { "│  " });
        print_children(slaves, Some(s.position), &next);
    }
}

/// Runs `ecdc scan`.
pub fn run(args: &Args) -> anyhow::Result<()> {
    let stop = sys::install_stop_handler().context("installing the Ctrl-C handler")?;
    let sock = args
        .link
        .open(crate::runtime::socket::FULL_PAYLOAD, true)
        .map_err(anyhow::Error::new)?;
    let mut t = Transport::new(sock, MASTER_MAC);
    let cfg = Config {
        auto_restart: true,
        ..Config::default()
    };
    // Built in place on the heap: no machine-sized value passes over the stack.
    let mut m: Box<Machine<MAX_SLAVES>> = Box::new(Machine::idle());
    m.configure(cfg)
        .map_err(|e| anyhow::anyhow!("DC machine configuration: {e:?}"))?;
    let dc = DcClock::from_realtime();
    let outcome = bringup::bring_up(
        &mut m,
        &mut t,
        &dc,
        &args.link.iface,
        Until::DelaysMeasured,
        &Limits {
            timeout_ns: 10 * crate::runtime::clock::NS_PER_S,
            ..Limits::default()
        },
        stop,
        |_| {},
        |_| {},
    )
    .map_err(anyhow::Error::new)?;
    if outcome == Outcome::Interrupted {
        anyhow::bail!("interrupted");
    }
    let measured = outcome == Outcome::Reached;
    let (slaves, topology_error) = report_slaves::<MAX_SLAVES>(m.slaves(), measured);
    let report = ScanReport {
        iface: args.link.iface.clone(),
        slaves,
        reference: if measured { m.reference() } else { None },
        topology_error,
        frames: *t.counters(),
    };
    if args.json {
        println!("{}", serde_json::to_string_pretty(&report)?);
        return Ok(());
    }
    let dc_count = report
        .slaves
        .iter()
        .filter(|s| s.dc == "32-bit" || s.dc == "64-bit")
        .count();
    println!(
        "{}: {} slaves, {} with a DC system time",
        report.iface,
        report.slaves.len(),
        dc_count
    );
    if !measured {
        println!("no DC reference clock: delays not measured");
    }
    print_slaves(
        &report.slaves,
        report.reference,
        report.topology_error.as_deref(),
    );
    let f = &report.frames;
    println!(
        "frames: sent {} matched {} lost {} ignored {}",
        f.sent,
        f.matched,
        f.lost,
        f.ignored()
    );
    Ok(())
}
