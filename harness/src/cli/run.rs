//! `ecdc run --iface IF`: scan, DC bring-up with the core state machine (with a progress bar
//! during static drift compensation), then cyclic DC with a per-second monitoring line and
//! the master following the reference clock; a summary on Ctrl-C or after `--duration`.

use std::io::IsTerminal;
use std::path::PathBuf;

use anyhow::Context;
use ecdc_core::dc::{Config, DcKind, Event, Machine, State};
use ecdc_core::servo::master::{MasterConfig, MasterServo};
use ecdc_core::wire::MASTER_MAC;

use super::link_args::RtLinkArgs;
use super::scan::{print_slaves, report_slaves, ScannedSlave, MAX_SLAVES};
use super::validate::{self, CYCLE_US};
use crate::runtime::bringup::{self, Limits, Outcome, Progress, Until};
use crate::runtime::capture_link::CaptureLink;
use crate::runtime::clock::{self, DcClock};
use crate::runtime::cyclic::{self, CycleConfig, LoopSummary};
use crate::runtime::dc_task::DcTask;
use crate::runtime::socket::{RawSocket, FULL_PAYLOAD};
use crate::runtime::sys;
use crate::runtime::transport::{Counters, Transport};

/// Arguments of `ecdc run`.
#[derive(Debug, clap::Args)]
pub struct Args {
    #[command(flatten)]
    pub io: RtLinkArgs,
    /// Cycle time, us (also the SYNC0 cycle), 100..=100000.
    #[arg(long, default_value_t = 1000, allow_negative_numbers = true,
          value_parser = validate::u64_in(CYCLE_US.0, CYCLE_US.1))]
    pub cycle_us: u64,
    /// Cyclic operation for this long, then stop with a summary: `10s`, `500ms`, `2min` (a bare
    /// number is seconds) [default: until Ctrl-C].
    #[arg(long, allow_negative_numbers = true, value_parser = validate::seconds)]
    pub duration: Option<f64>,
    /// Record every frame sent and received into this capture file (Wireshark-readable):
    /// pcapng when the name ends in `.pcapng`, classic pcap (ns timestamps) otherwise.
    #[arg(long)]
    pub pcap: Option<PathBuf>,
    /// Print the summary as JSON on stdout (progress and per-second lines stay on stderr).
    #[arg(long)]
    pub json: bool,
    /// Suppress the per-second lines and the progress bar.
    #[arg(long, short)]
    pub quiet: bool,
    /// Leave the SYNC units alone (no 0x0980/0x0990/0x09A0 writes).
    #[arg(long)]
    pub no_sync: bool,
    /// Servo target for (app time - reference time), ns: the reference should see the frame
    /// this long after the master's nominal cycle time (negative = before); within ± one cycle.
    #[arg(long, default_value_t = 0, allow_negative_numbers = true,
          value_parser = validate::i64_in(-MAX_TARGET_NS, MAX_TARGET_NS))]
    pub target_ns: i64,
    /// Consecutive lost cycles before the DC machine re-initialises, 1..=65535 (raise it on a
    /// machine without real-time scheduling, where the peer can stall for milliseconds).
    #[arg(long, default_value_t = 5, allow_negative_numbers = true,
          value_parser = validate::u16_in(1, u16::MAX))]
    pub max_lost_cycles: u16,
    /// Re-initialisations of DC before giving up (default: retry with backoff for as long as
    /// the interface has carrier).
    #[arg(long, allow_negative_numbers = true, value_parser = validate::u32_in(0, u32::MAX))]
    pub max_restarts: Option<u32>,
    /// Longest silence of the wire (or stall of this process) held over in cyclic operation
    /// without re-initialising DC, ms; 0 = re-initialise after --max-lost-cycles.
    #[arg(long, default_value_t = 1000, allow_negative_numbers = true,
          value_parser = validate::u64_in(0, 3_600_000))]
    pub holdover_ms: u64,
    /// Sleep until this long before each deadline, then spin (us; 0 = pure sleep; less than
    /// the cycle).
    #[arg(long, default_value_t = 0, allow_negative_numbers = true,
          value_parser = validate::u64_in(0, CYCLE_US.1 - 1))]
    pub spin_us: u64,
}

/// The run summary (`--json`).
#[derive(Debug, serde::Serialize)]
struct RunSummary {
    iface: String,
    rt: String,
    cycle_us: u64,
    slaves: usize,
    dc_slaves: usize,
    reference: Option<u16>,
    slave_table: Vec<ScannedSlave>,
    bringup_ms: f64,
    drift_frames: Option<u32>,
    drift_max_diff_ns: Option<u32>,
    /// DC re-initialisations (the machine's count: after faults in bring-up or cyclic phase).
    restarts: u64,
    /// Silences or stalls held over in cyclic operation that ended with a passed check.
    holdovers: u64,
    /// Cyclic cycles over all segments (a re-initialisation starts a new segment).
    cyclic_cycles_total: u64,
    /// Statistics of the last cyclic segment (since the last re-initialisation).
    cyclic: Option<LoopSummary>,
    servo_drift_ns_per_cycle: Option<i64>,
    machine_frames_sent: u64,
    machine_timeouts: u64,
    machine_lost_cycles: u64,
    frames: Counters,
    pcap_frames: Option<u64>,
    interrupted: bool,
}

/// Renders the bring-up progress: on a terminal an indicatif bar (a spinner with the state and
/// frame count, a bar of FRMW frames during static drift compensation), otherwise a line a
/// second. Events print above the bar.
struct ProgressBar {
    /// The terminal bar; `None` when stderr is not a terminal.
    tty: Option<indicatif::ProgressBar>,
    quiet: bool,
    last_line: u64,
    drifting: bool,
}

impl ProgressBar {
    fn new(quiet: bool) -> Self {
        let tty = (!quiet && std::io::stderr().is_terminal()).then(Self::spinner);
        ProgressBar {
            tty,
            quiet,
            last_line: 0,
            drifting: false,
        }
    }

    fn spinner() -> indicatif::ProgressBar {
        let bar = indicatif::ProgressBar::new_spinner();
        bar.set_style(Self::style(false));
        bar
    }

    fn style(drifting: bool) -> indicatif::ProgressStyle {
        let template = if drifting {
            "static drift compensation [{bar:30}] {pos} FRMW frames (give up at {len}), {msg}"
        } else {
            "{spinner} bring-up: {msg}"
        };
        indicatif::ProgressStyle::with_template(template)
            .unwrap_or_else(|_| indicatif::ProgressStyle::default_spinner())
            .progress_chars("#>.")
    }

    fn show(&mut self, p: &Progress) {
        if self.quiet {
            return;
        }
        let drifting = matches!(p.state, State::DriftBurst | State::DriftCheck);
        let diff = p.max_diff_ns.map_or("-".to_owned(), |d| format!("{d} ns"));
        if let Some(bar) = &self.tty {
            if drifting != self.drifting {
                bar.set_style(Self::style(drifting));
                self.drifting = drifting;
            }
            if drifting {
                bar.set_length(u64::from(p.drift_max));
                bar.set_position(p.drift_frames.min(u64::from(p.drift_max)));
                bar.set_message(format!("max |0x092C| {diff}"));
            } else {
                bar.set_message(format!("{:?}, {} frames", p.state, p.frames));
                bar.tick();
            }
            return;
        }
        let now = clock::now_ns();
        if now < self.last_line + clock::NS_PER_S {
            return;
        }
        self.last_line = now;
        if drifting {
            eprintln!(
                "static drift compensation: {} FRMW frames (give up at {}), max |0x092C| {diff}",
                p.drift_frames, p.drift_max
            );
        } else {
            eprintln!("bring-up: {:?}, {} frames", p.state, p.frames);
        }
    }

    fn line(&mut self, text: &str) {
        if self.quiet {
            return;
        }
        match &self.tty {
            Some(bar) => bar.println(text),
            None => eprintln!("{text}"),
        }
    }

    /// Removes the bar once DC is up (the cyclic phase prints its own lines); a fresh one,
    /// not drawn until used, waits for a re-initialisation.
    fn clear(&mut self) {
        if let Some(bar) = self.tty.as_mut() {
            std::mem::replace(bar, Self::spinner()).finish_and_clear();
        }
        self.drifting = false;
    }
}

fn describe(e: &Event) -> String {
    match e {
        Event::SlavesFound { count, dc } => {
            format!("found {count} slaves, {dc} with a DC system time")
        }
        Event::DelaysMeasured { max_delay_ns } => {
            format!("propagation delays measured (max {max_delay_ns} ns)")
        }
        Event::OffsetsWritten {
            written,
            skipped_running,
        } => {
            format!(
                "offsets written to {written} slaves ({skipped_running} running slaves left alone)"
            )
        }
        Event::DriftConverged {
            frames,
            max_diff_ns,
        } => {
            format!("static drift compensation converged after {frames} frames, max |0x092C| {max_diff_ns} ns")
        }
        Event::SyncStarted { start, slaves } => {
            format!("SYNC0 started on {slaves} slaves at system time {start}")
        }
        Event::Locked { frames, bound_ns } => {
            format!("DC locked after {frames} frames (|0x092C| bound {bound_ns} ns)")
        }
        Event::LockLost { bound_ns } => format!("DC lock lost (|0x092C| bound {bound_ns} ns)"),
        Event::DelaysUpdated { max_change_ns } => {
            format!("delays re-measured (max change {max_change_ns} ns)")
        }
        Event::Error(err) => format!("DC error: {err:?}"),
        Event::Restarting => "DC re-initialising".to_owned(),
        Event::HoldoverStarted { cause, .. } => {
            format!("DC holding over ({cause:?}): offsets and SYNC0 kept")
        }
        Event::HoldoverEnded { after_ns, check } => format!(
            "DC hold-over ended after {:.1} ms: {} slaves, |0x092C| bound {} ns; resumed",
            *after_ns as f64 / 1e6,
            check.slaves,
            check.bound_ns
        ),
        other => format!("{other:?}"),
    }
}

/// [`describe`], with the attempt number on a re-initialisation (its cause is the error
/// printed just before).
fn describe_attempt(e: &Event, attempts: &std::cell::Cell<u64>) -> String {
    if *e == Event::Restarting {
        attempts.set(attempts.get() + 1);
        format!(
            "DC re-initialising, attempt {} (the pause before it doubles per attempt without lock, up to 1 s)",
            attempts.get()
        )
    } else {
        describe(e)
    }
}

/// Largest |--target-ns|: the servo accepts a target within one period (`MasterConfig`), and
/// the longest period is 100 ms.
const MAX_TARGET_NS: i64 = 100_000_000;

/// The checks of the flags that depend on each other or on the machine, before the interface
/// is opened.
fn check_args(args: &Args) -> anyhow::Result<()> {
    if !(CYCLE_US.0..=CYCLE_US.1).contains(&args.cycle_us) {
        return Err(validate::usage(format!(
            "--cycle-us {}: valid: {}..={}",
            args.cycle_us, CYCLE_US.0, CYCLE_US.1
        )));
    }
    let cycle_ns = i64::try_from(args.cycle_us.saturating_mul(1000)).unwrap_or(i64::MAX);
    if args.target_ns.unsigned_abs() > cycle_ns.unsigned_abs() {
        return Err(validate::usage(format!(
            "--target-ns {}: must be within ± one cycle (--cycle-us {} = {cycle_ns} ns)",
            args.target_ns, args.cycle_us
        )));
    }
    if args.spin_us >= args.cycle_us {
        return Err(validate::usage(format!(
            "--spin-us {}: must be less than the cycle (--cycle-us {}); 0 = pure sleep",
            args.spin_us, args.cycle_us
        )));
    }
    if args.max_lost_cycles == 0 {
        return Err(validate::usage("--max-lost-cycles 0: valid: 1..=65535"));
    }
    if let Some(p) = &args.pcap {
        validate::out_file("--pcap", p)?;
    }
    validate::cpu("--cpu", args.io.rt.cpu)
}

/// Runs `ecdc run`.
pub fn run(args: &Args) -> anyhow::Result<()> {
    check_args(args)?;
    let cycle_ns = args.cycle_us * 1000;
    let stop = sys::install_stop_handler().context("installing the Ctrl-C handler")?;
    let sock: RawSocket = args
        .io
        .link
        .open(FULL_PAYLOAD, true)
        .map_err(anyhow::Error::new)?;
    let link = match &args.pcap {
        Some(path) => CaptureLink::create(sock, path)
            .with_context(|| format!("creating {}", path.display()))?,
        None => CaptureLink::passthrough(sock),
    };
    let rt = args.io.rt.apply();
    let mut t = Transport::new(link, MASTER_MAC);

    let mut cfg = Config::default();
    cfg.monitor.cycle_ns = cycle_ns;
    cfg.monitor.max_lost_cycles = args.max_lost_cycles;
    cfg.holdover_ns = args.holdover_ms.saturating_mul(1_000_000);
    cfg.sync = if args.no_sync {
        None
    } else {
        let mut s = cfg.sync.unwrap_or_default();
        s.sync0_cycle_ns = u32::try_from(cycle_ns).context("cycle too long")?;
        Some(s)
    };
    // Built in place on the heap: no machine-sized value passes over the stack.
    let mut m: Box<Machine<MAX_SLAVES>> = Box::new(Machine::idle());
    m.configure(cfg)
        .map_err(|e| anyhow::anyhow!("DC machine configuration: {e:?}"))?;
    let dc = DcClock::from_realtime();
    let bar = std::cell::RefCell::new(ProgressBar::new(args.quiet));
    let total_cycles = args
        .duration
        .map(|s| ((s.max(0.0) * 1e9) as u64) / cycle_ns);

    let started = clock::now_ns();
    let mut bringup_ms = 0.0;
    let mut drift: Option<(u32, u32)> = None;
    let mut reinits = 0u32;
    // Re-initialisations the machine announced, over bring-up and cyclic phases.
    let attempts = std::cell::Cell::new(0u64);
    let mut done_cycles = 0u64;
    let mut cyclic_summary: Option<LoopSummary> = None;
    let mut servo_drift = None;
    let mut interrupted;
    let mut slave_table = Vec::new();

    loop {
        let t0 = clock::now_ns();
        let outcome = bringup::bring_up(
            &mut m,
            &mut t,
            &dc,
            &args.io.link.iface,
            Until::Cyclic,
            &Limits {
                timeout_ns: if args.max_restarts.is_some() {
                    Limits::default().timeout_ns
                } else {
                    u64::MAX
                },
                max_restarts: args.max_restarts.map(|n| n.saturating_sub(reinits)),
                ..Limits::default()
            },
            stop,
            |e| {
                if let Event::DriftConverged {
                    frames,
                    max_diff_ns,
                } = e
                {
                    drift = Some((*frames, *max_diff_ns));
                }
                bar.borrow_mut().line(&describe_attempt(e, &attempts));
            },
            |p| bar.borrow_mut().show(p),
        );
        let outcome = outcome.map_err(anyhow::Error::new)?;
        bringup_ms += (clock::now_ns() - t0) as f64 / 1e6;
        bar.borrow_mut().clear();
        if outcome == Outcome::Interrupted {
            interrupted = true;
            break;
        }
        if slave_table.is_empty() {
            let (table, topo_err) = report_slaves::<MAX_SLAVES>(m.slaves(), true);
            if !args.json && !args.quiet {
                print_slaves(&table, m.reference(), topo_err.as_deref());
            }
            slave_table = table;
        }

        let ref_32bit = m
            .reference()
            .and_then(|r| m.slaves().get(usize::from(r)))
            .is_some_and(|s| s.dc == DcKind::Bits32);
        let mut mcfg = MasterConfig::for_period(u32::try_from(cycle_ns).context("cycle too long")?)
            .map_err(|e| anyhow::anyhow!("servo configuration: {e:?}"))?;
        mcfg.ref_32bit = ref_32bit;
        mcfg.target_ns = args.target_ns;
        let servo =
            MasterServo::new(mcfg).map_err(|e| anyhow::anyhow!("servo configuration: {e:?}"))?;

        let mut ccfg = CycleConfig::new(cycle_ns);
        ccfg.spin_ns = args.spin_us * 1000;
        ccfg.max_cycles = total_cycles.map(|n| n.saturating_sub(done_cycles));
        let quiet = args.quiet;
        let mut task = DcTask::new(&mut m, servo, dc, cycle_ns, |cycle, e| {
            if !quiet {
                eprintln!("cycle {cycle}: {}", describe_attempt(e, &attempts));
            }
        });
        let summary = cyclic::run(&mut t, &mut task, &ccfg, stop, |line| {
            if !quiet {
                eprintln!("{line}");
            }
        })?;
        servo_drift = Some(task.servo().drift_ns_per_cycle());
        done_cycles += summary.cycles;
        let stopped_by_task = summary.stopped_by_task;
        interrupted = summary.interrupted;
        cyclic_summary = Some(summary);
        if !stopped_by_task || interrupted {
            break;
        }
        reinits += 1;
        if args.max_restarts.is_some_and(|max| reinits > max) {
            anyhow::bail!(
                "DC re-initialised {reinits} times from cyclic operation (--max-restarts {}); giving up",
                args.max_restarts.unwrap_or(0)
            );
        }
        if !bringup::has_carrier(&args.io.link.iface) && args.max_restarts.is_none() {
            anyhow::bail!("interface {} lost carrier; giving up", args.io.link.iface);
        }
        bar.borrow_mut().line(&format!(
            "cyclic operation ended by the DC machine; bringing DC up again (re-initialisation {reinits})"
        ));
    }

    let pcap_frames = match &args.pcap {
        Some(path) => Some(
            t.link_mut()
                .finish()
                .with_context(|| format!("writing {}", path.display()))?,
        ),
        None => None,
    };
    let stats = *m.stats();
    let summary = RunSummary {
        iface: args.io.link.iface.clone(),
        rt: rt.describe(),
        cycle_us: args.cycle_us,
        slaves: m.slaves().len(),
        dc_slaves: m.slaves().iter().filter(|s| s.dc.has_system_time()).count(),
        reference: m.reference(),
        slave_table,
        bringup_ms,
        drift_frames: drift.map(|d| d.0),
        drift_max_diff_ns: drift.map(|d| d.1),
        restarts: stats.restarts,
        holdovers: stats.holdovers,
        cyclic_cycles_total: done_cycles,
        cyclic: cyclic_summary,
        servo_drift_ns_per_cycle: servo_drift,
        machine_frames_sent: stats.frames_sent,
        machine_timeouts: stats.timeouts,
        machine_lost_cycles: stats.lost_cycles,
        frames: *t.counters(),
        pcap_frames,
        interrupted,
    };
    if args.json {
        println!("{}", serde_json::to_string_pretty(&summary)?);
    } else {
        print_summary(&summary, clock::now_ns() - started);
    }
    Ok(())
}

fn print_summary(s: &RunSummary, elapsed_ns: u64) {
    println!();
    println!(
        "summary: {} on {} ({}), {} slaves ({} DC), cycle {} us, {:.1} s total{}",
        if s.interrupted {
            "interrupted"
        } else {
            "finished"
        },
        s.iface,
        s.rt,
        s.slaves,
        s.dc_slaves,
        s.cycle_us,
        elapsed_ns as f64 / 1e9,
        if s.restarts > 0 {
            format!(", {} re-initialisations", s.restarts)
        } else {
            String::new()
        }
    );
    if s.holdovers > 0 {
        println!(
            "  hold-overs (silence or stall bridged without re-initialising): {}",
            s.holdovers
        );
    }
    println!(
        "  bring-up {:.0} ms; static drift: {}",
        s.bringup_ms,
        match (s.drift_frames, s.drift_max_diff_ns) {
            (Some(f), Some(d)) => format!("{f} frames, max |0x092C| {d} ns at convergence"),
            _ => "-".to_owned(),
        }
    );
    if let Some(c) = &s.cyclic {
        if s.restarts > 0 {
            println!(
                "  {} cyclic cycles in total; the figures below cover the last segment",
                s.cyclic_cycles_total
            );
        }
        println!(
            "  cyclic: {} cycles, DC lock at end: {}, locked cycles {}; servo lock at end: {}, locked cycles {}",
            c.cycles,
            yes_no(c.locked_at_end),
            c.locked_cycles,
            yes_no(c.servo_locked_at_end),
            c.servo_locked_cycles
        );
        println!("  wake lateness: {}", c.wake);
        println!("  round trip:    {}", c.rtt);
        println!(
            "  max |0x092C| {} ns; servo error rms {} max {} ns; WKC errors {}; overruns {}",
            c.max_092c_ns.map_or("-".to_owned(), |v| v.to_string()),
            c.servo_rms_ns.map_or("-".to_owned(), |v| format!("{v:.0}")),
            c.servo_max_ns.map_or("-".to_owned(), |v| v.to_string()),
            c.wkc_errors,
            c.overruns
        );
    }
    let f = &s.frames;
    println!(
        "  frames: sent {} matched {} lost {} stale {} | ignored: foreign {} own-unprocessed {} other-master {} truncated {}",
        f.sent, f.matched, f.lost, f.stale, f.foreign, f.own_unprocessed, f.other_master, f.truncated
    );
    if let Some(n) = s.pcap_frames {
        println!("  pcap: {n} frames recorded");
    }
}

fn yes_no(v: Option<bool>) -> &'static str {
    match v {
        Some(true) => "yes",
        Some(false) => "no",
        None => "-",
    }
}
