//! The fixed-period loop: sleep to an absolute deadline, send this cycle's frame, wait for
//! its reply, let the task evaluate it, move the next deadline by the task's servo
//! correction, and once a second hand a stats line to the caller.
//!
//! WHY the task is a trait: the loop owns timing and I/O (wake lateness, round trip, lost
//! frames); what is in the frame and what the reply means belongs to the DC state machine
//! (`ecdc run`) or to a fixed probe (`ecdc rtt`). The loop itself does not allocate: buffers
//! and histograms are created before the first cycle (a test counts allocations).
//!
//! Master follows reference: the task returns a signed deadline adjustment each cycle
//! (its servo output); the loop clamps it to ±[`CycleConfig::max_adjust_ns`] so a bad sample
//! can never stall or race the loop.

use std::io;
use std::sync::atomic::{AtomicBool, Ordering};

use super::clock;
use super::socket::Link;
use super::stats::{Histogram, Summary, Window};
use super::transport::{Counters, Reply, SendError, Transport};

/// Receive buffer size: the largest Ethernet frame plus a VLAN tag, rounded up.
pub const RX_BUF: usize = 1536;

/// Loop parameters.
#[derive(Debug, Clone, Copy)]
pub struct CycleConfig {
    /// Period in ns.
    pub cycle_ns: u64,
    /// Sleep until `deadline - spin_ns`, then busy-wait (0 = pure sleep).
    pub spin_ns: u64,
    /// How long after the wake-up a reply may still arrive (must be < cycle).
    pub reply_timeout_ns: u64,
    /// Largest |deadline correction| per cycle accepted from the task.
    pub max_adjust_ns: u64,
    /// Stop after this many cycles (`None` = until Ctrl-C).
    pub max_cycles: Option<u64>,
}

impl CycleConfig {
    /// Defaults for a period: reply timeout 80 % of the cycle, adjustment clamp 10 % (IgH
    /// clamps to 0.1 % per cycle; the servo itself is expected to be far gentler).
    pub fn new(cycle_ns: u64) -> Self {
        CycleConfig {
            cycle_ns,
            spin_ns: 0,
            reply_timeout_ns: cycle_ns / 10 * 8,
            max_adjust_ns: cycle_ns / 10,
            max_cycles: None,
        }
    }
}

/// What the task reports after each cycle (all optional; `None` prints as `-`).
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct CycleReport {
    /// Signed correction to the next deadline, ns (servo output).
    pub adjust_ns: i64,
    /// The reply's working counter was not what was expected.
    pub wkc_error: bool,
    /// Largest |System Time Difference 0x092C| seen this cycle, ns.
    pub max_092c_ns: Option<u64>,
    /// Servo error this cycle (phase of our wake-up against the reference), ns.
    pub servo_error_ns: Option<i64>,
    /// DC lock state (slaves' |0x092C| within bounds).
    pub locked: Option<bool>,
    /// Master-follows-reference servo lock state.
    pub servo_locked: Option<bool>,
    /// End the loop after this cycle (e.g. the DC machine left cyclic operation).
    pub stop: bool,
}

/// One cycle's work.
pub trait CycleTask {
    /// Writes this cycle's frame into `buf` and returns its length; `None` sends nothing.
    /// `period` counts periods since the loop started, including periods skipped after an
    /// overrun (so `start + period × cycle` is the nominal time of this wake-up); `deadline`
    /// is the scheduled wake-up, `now` the actual one (monotonic ns).
    fn build(&mut self, period: u64, deadline: u64, now: u64, buf: &mut [u8]) -> Option<usize>;
    /// Evaluates the reply (`None`: it did not arrive in time) and returns the report.
    fn complete(&mut self, period: u64, reply: Option<(&[u8], &Reply)>) -> CycleReport;
}

/// Per-second accounting, printed as one line.
#[derive(Debug, Clone, Copy, Default)]
pub struct SecondStats {
    /// Seconds since the loop started (end of this window).
    pub second: u64,
    /// Cycles in this window.
    pub cycles: u64,
    /// Wake-up lateness, ns.
    pub wake: Window,
    /// Round trip, ns.
    pub rtt: Window,
    /// Frames without a reply.
    pub lost: u64,
    /// Cycles with a working-counter error.
    pub wkc_errors: u64,
    /// Cycles that started more than one period late (deadline skipped ahead).
    pub overruns: u64,
    /// Largest |0x092C|, ns.
    pub max_092c_ns: Option<u64>,
    /// Servo error.
    pub servo: Window,
    /// Servo correction applied to the deadlines.
    pub adjust: Window,
    /// Last DC lock state.
    pub locked: Option<bool>,
    /// Last servo lock state.
    pub servo_locked: Option<bool>,
}

impl std::fmt::Display for SecondStats {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let us = |x: f64| x / 1000.0;
        write!(
            f,
            "{:>5} s  cycles {:>5}  wake rms {:>6.1} max {:>6.1} us  rtt rms {:>6.1} max {:>6.1} us  lost {:>3}  wkc-err {:>3}",
            self.second,
            self.cycles,
            us(self.wake.rms()),
            us(self.wake.max_abs() as f64),
            us(self.rtt.rms()),
            us(self.rtt.max_abs() as f64),
            self.lost,
            self.wkc_errors,
        )?;
        if self.overruns > 0 {
            write!(f, "  overruns {}", self.overruns)?;
        }
        match self.max_092c_ns {
            Some(v) => write!(f, "  |092C| max {v:>6} ns")?,
            None => write!(f, "  |092C| max      - ns")?,
        }
        if self.servo.count() > 0 {
            write!(
                f,
                "  servo rms {:>8.0} max {:>8} ns",
                self.servo.rms(),
                self.servo.max_abs()
            )?;
        }
        match self.locked {
            Some(true) => write!(f, "  dc locked")?,
            Some(false) => write!(f, "  dc unlocked")?,
            None => {}
        }
        match self.servo_locked {
            Some(true) => write!(f, ", servo locked"),
            Some(false) => write!(f, ", servo unlocked"),
            None => Ok(()),
        }
    }
}

/// Whole-run results.
#[derive(Debug, Clone, serde::Serialize)]
pub struct LoopSummary {
    /// Cycles run.
    pub cycles: u64,
    /// Wall time of the loop, ns.
    pub elapsed_ns: u64,
    /// Wake-up lateness distribution.
    pub wake: Summary,
    /// Round-trip distribution.
    pub rtt: Summary,
    /// Cycles with a WKC error.
    pub wkc_errors: u64,
    /// Cycles that started over a period late.
    pub overruns: u64,
    /// Largest |0x092C| over the run.
    pub max_092c_ns: Option<u64>,
    /// Servo error rms over the run.
    pub servo_rms_ns: Option<f64>,
    /// Largest |servo error| over the run.
    pub servo_max_ns: Option<u64>,
    /// DC lock state at the end.
    pub locked_at_end: Option<bool>,
    /// Servo lock state at the end.
    pub servo_locked_at_end: Option<bool>,
    /// Cycles with the servo locked.
    pub servo_locked_cycles: u64,
    /// The task asked to stop (e.g. the DC machine re-initialises).
    pub stopped_by_task: bool,
    /// Cycles spent locked.
    pub locked_cycles: u64,
    /// Frame accounting.
    pub frames: Counters,
    /// Stopped by a signal (Ctrl-C) rather than by the cycle limit.
    pub interrupted: bool,
}

/// Runs the loop until `cfg.max_cycles`, `stop`, or an I/O error. `on_second` receives each
/// per-second line (it runs on the loop thread: keep it short).
pub fn run<L: Link, T: CycleTask>(
    transport: &mut Transport<L>,
    task: &mut T,
    cfg: &CycleConfig,
    stop: &AtomicBool,
    mut on_second: impl FnMut(&SecondStats),
) -> io::Result<LoopSummary> {
    // Everything the loop touches is allocated here.
    let mut tx = vec![0u8; RX_BUF];
    let mut rx = vec![0u8; RX_BUF];
    let mut wake_hist = Histogram::new();
    let mut rtt_hist = Histogram::new();
    let mut servo_all = Window::default();
    let mut sec = SecondStats::default();
    let mut totals = SecondStats::default();
    let mut locked_cycles = 0u64;
    let mut servo_locked_cycles = 0u64;
    let mut stopped_by_task = false;
    let max_adjust = i64::try_from(cfg.max_adjust_ns).unwrap_or(i64::MAX);

    let start = clock::now_ns().saturating_add(cfg.cycle_ns);
    let mut deadline = start;
    let mut next_line = start.saturating_add(clock::NS_PER_S);
    let mut cycle = 0u64;
    // Period number since start, skipped periods included (what a nominal clock advances by).
    let mut period = 0u64;
    let mut interrupted = false;

    loop {
        if cfg.max_cycles.is_some_and(|m| cycle >= m) || stopped_by_task {
            break;
        }
        if stop.load(Ordering::Relaxed) {
            interrupted = true;
            break;
        }
        let Some(woke) = clock::sleep_until(deadline, cfg.spin_ns, stop) else {
            interrupted = true;
            break;
        };
        let late = woke.saturating_sub(deadline);
        wake_hist.record(late);
        sec.wake.record(i64::try_from(late).unwrap_or(i64::MAX));
        sec.cycles += 1;

        let reply_deadline = woke.saturating_add(cfg.reply_timeout_ns);
        let mut got: Option<Reply> = None;
        if let Some(len) = task.build(period, deadline, woke, &mut tx) {
            let frame = tx.get(..len).unwrap_or_default();
            match transport.send(frame, reply_deadline) {
                Ok(_) => {}
                Err(SendError::Io(e)) => return Err(e),
                Err(e) => return Err(io::Error::other(e.to_string())),
            }
            got = transport.recv(&mut rx, reply_deadline)?;
            if got.is_none() {
                // Do not let an unanswered frame occupy its index into the next cycle.
                transport.abandon_all();
            }
        }
        let report = match &got {
            Some(r) => {
                rtt_hist.record(r.rtt_ns());
                sec.rtt
                    .record(i64::try_from(r.rtt_ns()).unwrap_or(i64::MAX));
                task.complete(period, Some((rx.get(..r.len).unwrap_or_default(), r)))
            }
            None => {
                sec.lost += 1;
                task.complete(period, None)
            }
        };
        if report.wkc_error {
            sec.wkc_errors += 1;
        }
        if let Some(v) = report.max_092c_ns {
            sec.max_092c_ns = Some(sec.max_092c_ns.unwrap_or(0).max(v));
        }
        if let Some(e) = report.servo_error_ns {
            sec.servo.record(e);
            servo_all.record(e);
        }
        if report.locked.is_some() {
            sec.locked = report.locked;
        }
        if report.locked == Some(true) {
            locked_cycles += 1;
        }
        if report.servo_locked.is_some() {
            sec.servo_locked = report.servo_locked;
        }
        if report.servo_locked == Some(true) {
            servo_locked_cycles += 1;
        }
        let adjust = report.adjust_ns.clamp(-max_adjust, max_adjust);
        sec.adjust.record(adjust);

        // Next deadline: one period plus the servo's correction. If we are already past it
        // (a stall longer than a period), skip whole periods instead of bursting to catch up.
        deadline = deadline
            .saturating_add(cfg.cycle_ns)
            .saturating_add_signed(adjust);
        let now = clock::now_ns();
        if now > deadline {
            let behind = (now - deadline) / cfg.cycle_ns.max(1) + 1;
            deadline = deadline.saturating_add(behind.saturating_mul(cfg.cycle_ns));
            period += behind;
            sec.overruns += behind;
        }
        cycle += 1;
        period += 1;
        if report.stop {
            stopped_by_task = true;
        }

        if now >= next_line {
            sec.second = (now - start) / clock::NS_PER_S;
            on_second(&sec);
            totals.wkc_errors += sec.wkc_errors;
            totals.overruns += sec.overruns;
            if let Some(v) = sec.max_092c_ns {
                totals.max_092c_ns = Some(totals.max_092c_ns.unwrap_or(0).max(v));
            }
            totals.locked = sec.locked.or(totals.locked);
            totals.servo_locked = sec.servo_locked.or(totals.servo_locked);
            let (locked, servo_locked) = (sec.locked, sec.servo_locked);
            sec = SecondStats {
                locked,
                servo_locked,
                ..SecondStats::default()
            };
            next_line = next_line.saturating_add(clock::NS_PER_S);
        }
    }
    // Fold the partial last window into the totals.
    totals.wkc_errors += sec.wkc_errors;
    totals.overruns += sec.overruns;
    if let Some(v) = sec.max_092c_ns {
        totals.max_092c_ns = Some(totals.max_092c_ns.unwrap_or(0).max(v));
    }
    let locked_at_end = sec.locked.or(totals.locked);
    let servo_locked_at_end = sec.servo_locked.or(totals.servo_locked);
    transport.abandon_all();
    Ok(LoopSummary {
        cycles: cycle,
        elapsed_ns: clock::now_ns().saturating_sub(start),
        wake: wake_hist.summary(),
        rtt: rtt_hist.summary(),
        wkc_errors: totals.wkc_errors,
        overruns: totals.overruns,
        max_092c_ns: totals.max_092c_ns,
        servo_rms_ns: (servo_all.count() > 0).then(|| servo_all.rms()),
        servo_max_ns: (servo_all.count() > 0).then(|| servo_all.max_abs()),
        locked_at_end,
        locked_cycles,
        servo_locked_at_end,
        servo_locked_cycles,
        stopped_by_task,
        frames: *transport.counters(),
        interrupted,
    })
}
