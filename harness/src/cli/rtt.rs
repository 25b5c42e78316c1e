//! `ecdc rtt --iface IF`: round-trip benchmark, back to back and inside a fixed cycle, with
//! the same probe frame as the C probe in docs/background/linux-runtime.md §6 (BRD 0x0130 len 2 + FRMW
//! 0x1001:0x0910 len 8, 60 bytes), so the numbers compare directly.
//!
//! The peer must answer EtherCAT frames: real slaves, or `ecdc emulate --engine reflect`
//! (pure socket path) / `ecdc emulate` (emulated ESCs) on the other end of a veth pair.

use std::sync::atomic::AtomicBool;

use anyhow::Context;
use ecdc_core::wire::{Address, Command, FrameBuilder};

use super::link_args::RtLinkArgs;
use super::validate::{self, CYCLE_US};
use crate::runtime::clock;
use crate::runtime::cyclic::{self, CycleConfig, CycleReport, CycleTask, LoopSummary};
use crate::runtime::errors::RuntimeError;
use crate::runtime::stats::{Histogram, Summary};
use crate::runtime::sys;
use crate::runtime::transport::{Counters, Reply, Transport};

/// Arguments of `ecdc rtt`.
#[derive(Debug, clap::Args)]
pub struct Args {
    #[command(flatten)]
    pub io: RtLinkArgs,
    /// Back-to-back round trips, 0..=100000000 (0 to skip).
    #[arg(long, default_value_t = 10_000, allow_negative_numbers = true,
          value_parser = validate::u64_in(0, MAX_PROBES))]
    pub count: u64,
    /// Cycles of the in-cycle measurement, 0..=100000000 (0 to skip).
    #[arg(long, default_value_t = 5_000, allow_negative_numbers = true,
          value_parser = validate::u64_in(0, MAX_PROBES))]
    pub cycles: u64,
    /// Cycle time of the in-cycle measurement, us, 100..=100000.
    #[arg(long, default_value_t = 1000, allow_negative_numbers = true,
          value_parser = validate::u64_in(CYCLE_US.0, CYCLE_US.1))]
    pub cycle_us: u64,
    /// Reply timeout for back-to-back frames, us, 1..=10000000.
    #[arg(long, default_value_t = 100_000, allow_negative_numbers = true,
          value_parser = validate::u64_in(1, MAX_TIMEOUT_US))]
    pub timeout_us: u64,
    /// Source MAC of the probe frames (bit 0x02 of the first octet must be clear); e.g.
    /// to play a second master and check that `ecdc run` refuses to share the segment.
    #[arg(long, value_parser = parse_mac, default_value = "10:10:10:10:10:10")]
    pub source_mac: [u8; 6],
    /// Print a JSON summary on stdout instead of text.
    #[arg(long)]
    pub json: bool,
}

/// Parses `aa:bb:cc:dd:ee:ff` into a unicast MAC whose "processed" bit is clear.
fn parse_mac(s: &str) -> Result<[u8; 6], String> {
    let parts: Vec<&str> = s.split(':').collect();
    let mut mac = [0u8; 6];
    if parts.len() != 6 {
        return Err("expected six hex octets separated by ':'".into());
    }
    for (m, p) in mac.iter_mut().zip(parts) {
        *m = u8::from_str_radix(p, 16).map_err(|e| format!("{p:?}: {e}"))?;
    }
    if mac[0] & 0x02 != 0 {
        return Err(
            "bit 0x02 of the first octet must be clear (slaves set it on processed frames)".into(),
        );
    }
    Ok(mac)
}

/// Writes the probe frame from `mac` with first datagram index `idx`; returns its length.
fn probe(buf: &mut [u8], mac: [u8; 6], idx: u8) -> ecdc_core::wire::Result<usize> {
    let mut b = FrameBuilder::new(buf)?;
    b.set_source(mac);
    b.push(Command::Brd, idx, Address::broadcast(0x0130), &[0, 0])?;
    b.push(
        Command::Frmw,
        idx.wrapping_add(1),
        Address::configured(0x1001, 0x0910),
        &[0; 8],
    )?;
    b.finish()
}

/// Result of the back-to-back phase.
#[derive(Debug, serde::Serialize)]
struct BackToBack {
    rtt: Summary,
    /// Kernel receive stamp to user space (the wake-up and read cost), when stamped.
    kernel_to_user: Summary,
    frames: Counters,
}

/// The in-cycle probe task: one probe per cycle, WKC of the BRD must be non-zero.
struct ProbeTask([u8; 6]);

impl CycleTask for ProbeTask {
    fn build(&mut self, cycle: u64, _deadline: u64, _now: u64, buf: &mut [u8]) -> Option<usize> {
        probe(buf, self.0, ((cycle % 128) * 2) as u8).ok()
    }
    fn complete(&mut self, _cycle: u64, reply: Option<(&[u8], &Reply)>) -> CycleReport {
        // Lost frames are counted by the loop; a WKC error is a reply nobody processed.
        let wkc_error = reply.is_some_and(|(bytes, _)| brd_wkc(bytes).is_none_or(|w| w == 0));
        CycleReport {
            wkc_error,
            ..CycleReport::default()
        }
    }
}

/// WKC of the first datagram (the BRD) of a reply.
fn brd_wkc(frame: &[u8]) -> Option<u16> {
    let eth = ecdc_core::wire::EthernetFrame::new_checked(frame).ok()?;
    let ecat = eth.ecat_frame().ok()?;
    let first = ecat.iter().next()?.ok()?;
    Some(first.wkc())
}

#[derive(Debug, serde::Serialize)]
struct Report {
    iface: String,
    rt: String,
    wait: crate::runtime::socket::WaitMode,
    qdisc_bypass: bool,
    back_to_back: Option<BackToBack>,
    cyclic: Option<LoopSummary>,
    cycle_us: u64,
}

/// Most probes of either phase. ecdc choice: 10^8 frames is over a day at 1 kHz; more is a
/// typo, not a measurement.
const MAX_PROBES: u64 = 100_000_000;

/// Longest reply timeout, us (10 s). ecdc choice: a peer that needs longer is not there.
const MAX_TIMEOUT_US: u64 = 10_000_000;

/// Runs `ecdc rtt`.
pub fn run(args: &Args) -> anyhow::Result<()> {
    if args.count == 0 && args.cycles == 0 {
        return Err(validate::usage(
            "--count 0 and --cycles 0: nothing to measure; give at least one of them > 0",
        ));
    }
    validate::cpu("--cpu", args.io.rt.cpu)?;
    let stop = sys::install_stop_handler().context("installing the Ctrl-C handler")?;
    let sock = args.io.link.open(60, true).map_err(anyhow::Error::new)?;
    let info = sock.info().clone();
    let rt = args.io.rt.apply();
    let mut transport = Transport::new(sock, args.source_mac);

    let back_to_back = if args.count > 0 {
        Some(back_to_back(&mut transport, args, stop)?)
    } else {
        None
    };
    if let Some(b) = &back_to_back {
        if b.frames.matched == 0 {
            return Err(RuntimeError::NoSlaves {
                name: info.name.clone(),
                sent: b.frames.sent,
                ignored: b.frames.ignored(),
            }
            .into());
        }
    }
    let cyclic = if args.cycles > 0 {
        transport.reset_counters();
        let mut cfg = CycleConfig::new(args.cycle_us * 1000);
        cfg.max_cycles = Some(args.cycles);
        let summary = cyclic::run(
            &mut transport,
            &mut ProbeTask(args.source_mac),
            &cfg,
            stop,
            |line| {
                if !args.json {
                    eprintln!("{line}");
                }
            },
        )?;
        Some(summary)
    } else {
        None
    };
    let report = Report {
        iface: info.name.clone(),
        rt: rt.describe(),
        wait: args.io.link.wait,
        qdisc_bypass: info.qdisc_bypass,
        back_to_back,
        cyclic,
        cycle_us: args.cycle_us,
    };
    if args.json {
        println!("{}", serde_json::to_string_pretty(&report)?);
    } else {
        println!(
            "interface {} ({}; wait {:?}; qdisc bypass {})",
            report.iface, report.rt, report.wait, report.qdisc_bypass
        );
        if let Some(b) = &report.back_to_back {
            println!(
                "back-to-back RTT: {}  (lost {}, stale {})",
                b.rtt, b.frames.lost, b.frames.stale
            );
            if b.kernel_to_user.count > 0 {
                println!("back-to-back kernel RX stamp -> user: {}", b.kernel_to_user);
            }
        }
        if let Some(c) = &report.cyclic {
            println!(
                "in {} us cycle: RTT {}  (lost {}, wkc errors {})",
                report.cycle_us, c.rtt, c.frames.lost, c.wkc_errors
            );
            println!(
                "in {} us cycle: wake lateness {}  (overruns {})",
                report.cycle_us, c.wake, c.overruns
            );
        }
    }
    Ok(())
}

fn back_to_back(
    transport: &mut Transport<crate::runtime::socket::RawSocket>,
    args: &Args,
    stop: &AtomicBool,
) -> anyhow::Result<BackToBack> {
    let mut tx = [0u8; 128];
    let mut rx = vec![0u8; cyclic::RX_BUF];
    let mut hist = Histogram::new();
    let mut k2u = Histogram::new();
    for i in 0..args.count {
        if stop.load(std::sync::atomic::Ordering::Relaxed) {
            break;
        }
        let len = probe(&mut tx, args.source_mac, ((i % 128) * 2) as u8)
            .map_err(|e| anyhow::anyhow!("building probe: {e}"))?;
        let deadline = clock::now_ns().saturating_add(args.timeout_us * 1000);
        transport
            .send(tx.get(..len).unwrap_or_default(), deadline)
            .map_err(|e| anyhow::anyhow!("{e}"))?;
        match transport.recv(&mut rx, deadline)? {
            Some(r) => {
                hist.record(r.rtt_ns());
                if let Some(k) = r.rx_stamp {
                    k2u.record(r.received_at.saturating_sub(k));
                }
            }
            None => {
                transport.abandon_all();
                // Nobody there: give up early instead of waiting count * timeout.
                if transport.counters().matched == 0 && i >= 9 {
                    break;
                }
            }
        }
    }
    Ok(BackToBack {
        rtt: hist.summary(),
        kernel_to_user: k2u.summary(),
        frames: *transport.counters(),
    })
}
