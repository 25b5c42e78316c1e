//! t_Diff measurement (REQ-DC-120..126): ecdc measures each ESC's `t_Diff = t_P − t_F` itself
//! instead of relying on a value from the ESI.
//!
//! Method (docs/background/t-diff.md): with every port open, one latch gives the excursion
//! `X = t_a(p) − t_a(q)` the nearest upstream DC slave `a` sees through the port `p` towards
//! slave `b`, and `b`'s own round trip `rtt_b = t_b(last) − t_b(entry)`. Then `b`'s downstream
//! ports are forced closed through the loop bits of DL control 0x0101, so `b` turns the frame
//! round as a line end does, and a second latch gives the excursion `X'`. Everything outside
//! `b` is the same in both latches (symmetric cables), so
//!
//! ```text
//!   X' − X + rtt_b = t_P(b) − t_F(b) = t_Diff(b)
//! ```
//!
//! (`X` contains `b`'s round trip `rtt_b` plus its forwarding return hop `t_F(b)`; `X'` contains
//! `b`'s processing turn-round `t_P(b)`). The all-open latch is repeated
//! [`TdiffConfig::base_rounds`] times (shared by every target), the closed one
//! [`TdiffConfig::rounds`] times per target, and the sums are divided once. `rtt_b` is read on
//! `b`'s clock and `X` on `a`'s, both over `b`'s whole subtree, so `rtt_b` is first converted
//! to `a`'s clock (their crystals may differ by ~100 ppm).
//!
//! Slaves that cannot be measured this way (the first DC slave, line ends, non-DC slaves: their
//! t_Diff still enters the delays) take a user value, else the value measured on a slave of the
//! same ESC type and revision, else `Config::t_diff_ns`.
//!
//! Safety rules: the step never runs while any slave reports SAFE-OP or OP (closing a port cuts
//! the slaves behind it off the frame); DL control is read first and written back exactly;
//! the triggers' working counters are checked against the slaves that are still reachable; a
//! restore interrupted by a restart is sent first in the next `CountSlaves`.
//!
//! The phase owns its working data (`Tdiff`); the machine only keeps one `Tdiff` field and
//! receives the result per slave in [`SlaveInfo::t_diff_ns`] and [`SlaveInfo::t_diff_source`].

use crate::dc::config::{TdiffConfig, TdiffMode};
use crate::dc::error::Error;
use crate::dc::event::Event;
use crate::dc::machine::{Item, Machine};
use crate::dc::measure::LATCH_TRIGGER;
use crate::dc::offset::offset_write_permitted;
use crate::dc::phase::{Phase, TdiffStep};
use crate::dc::port::{Port, PortSet};
use crate::dc::request::{le, Op, Reply};
use crate::dc::shared::expect_wkc;
use crate::dc::slave::SlaveInfo;
use crate::dc::state::State;
use crate::dc::topology::{Latches, SlaveSample};
use crate::dc::work::PerSlave;
use crate::time::PortTime;
use crate::wire::register::{reg, ReceiveTimes};

/// ESC type (0x0000) and revision (0x0001), read as one little-endian word.
const ESC_TYPE: u16 = 0x0000;
/// ESC DL control 0x0100..0x0103; bits 8..15 (byte 0x0101) are the loop control of ports 0..3,
/// two bits per port, 0b11 = "closed" (Beckhoff ESC datasheet section II, DL control).
const DL_CONTROL: u16 = 0x0100;
/// Loop-control value "closed" of one port (two bits).
const LOOP_CLOSED: u16 = 0b11;

/// Where the `t_Diff` used for a slave came from.
///
/// # Examples
///
/// ```
/// use ecdc_core::dc::{SlaveInfo, TdiffFallback, TdiffSource};
///
/// // Reporting where each slave's t_Diff came from, as `Machine::slaves` gives it.
/// let mut s = SlaveInfo::EMPTY;
/// s.t_diff_source = TdiffSource::SameType { from: 3 };
/// assert_eq!(s.t_diff_source.to_string(), "same type as 3");
/// let f = TdiffSource::Fallback(TdiffFallback::Running);
/// assert_eq!(f.to_string(), "fallback: running");
/// ```
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default)]
pub enum TdiffSource {
    /// [`crate::dc::Config::t_diff_ns`]: nothing was measured or configured for this slave
    /// (with the default 0: no t_Diff at all). Also the value before the step ran.
    #[default]
    Default,
    /// Given by the user: [`Machine::set_slave_t_diff`] or an entry of
    /// [`TdiffConfig::types`]. Configured slaves are not measured.
    Configured,
    /// Measured on this slave (REQ-DC-121), the mean over [`TdiffConfig::rounds`] latch pairs.
    Measured,
    /// Measured on the slave at auto-increment position `from`, which has the same ESC type
    /// and revision (0x0000..0x0001). Used for slaves that cannot be measured themselves (the
    /// first DC slave, line ends) and in [`TdiffMode::PerEscType`].
    SameType {
        /// Position of the measured slave.
        from: u16,
    },
    /// Measured on this slave in an earlier bring-up of this machine: this one found a slave
    /// in SAFE-OP or OP, so no port was closed (REQ-DC-123), and the slave at this position
    /// still has the ESC type and revision it had then (REQ-DC-126).
    Earlier,
    /// A measurement was wanted but could not be used; the value is `Config::t_diff_ns`.
    Fallback(TdiffFallback),
}

impl core::fmt::Display for TdiffSource {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match *self {
            TdiffSource::Default => f.write_str("default"),
            TdiffSource::Configured => f.write_str("configured"),
            TdiffSource::Measured => f.write_str("measured"),
            TdiffSource::SameType { from } => write!(f, "same type as {from}"),
            TdiffSource::Earlier => f.write_str("measured in an earlier bring-up"),
            TdiffSource::Fallback(TdiffFallback::Running) => f.write_str("fallback: running"),
            TdiffSource::Fallback(TdiffFallback::Implausible { measured_ns }) => {
                write!(f, "fallback: measured {measured_ns} ns implausible")
            }
        }
    }
}

/// Why a wanted measurement was not used.
///
/// # Examples
///
/// ```
/// use ecdc_core::dc::{TdiffFallback, TdiffSource};
///
/// let rejected = TdiffSource::Fallback(TdiffFallback::Implausible { measured_ns: 900 });
/// assert_eq!(
///     rejected.to_string(),
///     "fallback: measured 900 ns implausible"
/// );
/// ```
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum TdiffFallback {
    /// A slave reported SAFE-OP, OP or an unknown AL state, so no port was closed (REQ-DC-123).
    Running,
    /// The measured value was outside [`TdiffConfig::min_ns`]..=[`TdiffConfig::max_ns`]
    /// (REQ-DC-124).
    Implausible {
        /// The rejected mean, ns.
        measured_ns: i32,
    },
}

/// How one slave takes part in the measurement, decided from the first all-open latch.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default)]
pub(crate) enum Plan {
    /// Not measured.
    #[default]
    Skip,
    /// Measured through its nearest upstream DC slave `parent`, whose ports `q` (the open port
    /// before `p`) and `p` (towards this slave) bracket its subtree; `close` holds the ports to
    /// force closed; `end` is one past the last position of its subtree (cut off while closed).
    Measure {
        parent: u16,
        q: Port,
        p: Port,
        entry: Port,
        last: Port,
        close: PortSet,
        end: u16,
    },
    /// Measured: the mean before the plausibility check (`None` if it did not fit).
    Done { mean: Option<i32> },
}

/// Which latch the step is in.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default)]
pub(crate) enum Latch {
    /// The read before the first trigger (stale-latch reference).
    #[default]
    Pre,
    /// All ports open, round `round`.
    Base { round: u8 },
    /// `target`'s downstream ports closed, round `round`.
    Closed { target: u16, round: u8 },
}

/// The reads of `TdiffRead`, per slave.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum TdiffRead {
    /// 0x0000: ESC type and revision.
    Ident,
    /// 0x0130.
    AlStatus,
    /// 0x0100, only of a slave with latches and two or more open ports (a possible target).
    DlControl,
}

impl PerSlave for TdiffRead {
    const ALL: &'static [Self] = &[TdiffRead::Ident, TdiffRead::AlStatus, TdiffRead::DlControl];
}

/// One typed work item of a t_Diff request step.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub(crate) enum Work {
    /// FPRD 0x0000 (type, revision) of a slave.
    Ident(u16),
    /// FPRD 0x0130 of any slave (the running check).
    AlStatus(u16),
    /// FPRD 0x0100 (2 bytes) of a possible target: the value to restore.
    ReadDlControl(u16),
    /// BWR 0x0900.
    Trigger,
    /// FPRD 0x0900..0x090F of a DC slave.
    ReadPorts(u16),
    /// FPWR 0x0100 of the target with its downstream loop bits closed.
    Close(u16),
    /// FPWR 0x0100 of the target with the value read before.
    Restore(u16),
}

/// The t_Diff phase's data (REQ-DC-120..126).
#[derive(Debug, Clone, PartialEq, Eq, Hash)]
pub(crate) struct Tdiff<const N: usize> {
    pub(crate) latch: Latch,
    /// A slave is in SAFE-OP/OP (or an unknown state): no port is closed.
    running: bool,
    plan: [Plan; N],
    /// DL control 0x0100..0x0101 as read, per slave.
    dl_control: [u16; N],
    /// Port times of the latest read, per slave (validated when the read step is complete).
    cur: [[u32; 4]; N],
    /// Port times of the previous complete read (stale-latch reference).
    prev: [[u32; 4]; N],
    /// Per target: Σ X over the all-open rounds (upstream slave's clock), then, once they are
    /// done, Σ (X − rtt) with `rtt` converted to the upstream slave's clock.
    base: [i64; N],
    /// Per target: Σ rtt over the all-open rounds (its own clock).
    rtt: [i64; N],
    /// Per target: the upstream slave's stamp at `q` and the target's at its entry in the first
    /// all-open round, for the ratio of the two free-running clocks.
    first: [(u32, u32); N],
    /// Σ X' over the closed rounds of the current target.
    closed: i64,
    /// (station, DL control) of a target whose ports may still be closed: set before its close
    /// is sent, cleared once the restore is answered. Survives a restart, so that the next
    /// bring-up first reopens the ports (REQ-DC-124).
    pending: Option<(u16, u16)>,
    /// The current `CountSlaves` step starts with the restore of `pending`.
    pub(crate) recovering: bool,
    /// Per position, (ESC type, value) of the last value measured there, and the slave count
    /// of that bring-up: used when a later bring-up may not close ports (REQ-DC-123), e.g. a
    /// re-initialisation while the application holds the slaves in OP. Survives restarts.
    kept: [Option<(u16, i32)>; N],
    kept_count: u16,
}

impl<const N: usize> Tdiff<N> {
    pub(crate) const fn new() -> Self {
        Tdiff {
            latch: Latch::Pre,
            running: false,
            plan: [Plan::Skip; N],
            dl_control: [0; N],
            cur: [[0; 4]; N],
            prev: [[0; 4]; N],
            base: [0; N],
            rtt: [0; N],
            first: [(0, 0); N],
            closed: 0,
            pending: None,
            recovering: false,
            kept: [None; N],
            kept_count: 0,
        }
    }

    /// Back to [`Tdiff::new`] in place, except `pending`: a target whose ports may still be
    /// closed is reopened by the next bring-up whatever the configuration (REQ-DC-124).
    pub(crate) fn forget(&mut self) {
        let Tdiff {
            latch,
            running,
            plan,
            dl_control,
            cur,
            prev,
            base,
            rtt,
            first,
            closed,
            pending: _,
            recovering,
            kept,
            kept_count,
        } = self;
        *latch = Latch::Pre;
        *running = false;
        plan.fill(Plan::Skip);
        dl_control.fill(0);
        cur.fill([0; 4]);
        prev.fill([0; 4]);
        base.fill(0);
        rtt.fill(0);
        first.fill((0, 0));
        *closed = 0;
        *recovering = false;
        kept.fill(None);
        *kept_count = 0;
    }

    fn clear(&mut self) {
        self.latch = Latch::Pre;
        self.running = false;
        self.plan.fill(Plan::Skip);
        self.closed = 0;
        self.base.fill(0);
        self.rtt.fill(0);
    }

    fn plan_of(&self, i: u16) -> Plan {
        self.plan.get(usize::from(i)).copied().unwrap_or_default()
    }

    /// First target at or after position `from`.
    fn next_target(&self, from: u16) -> Option<u16> {
        (from..)
            .zip(self.plan.iter().skip(usize::from(from)))
            .find(|(_, p)| matches!(p, Plan::Measure { .. }))
            .map(|(i, _)| i)
    }
}

/// Wrapping difference `t[to] − t[from]` of one slave's stamps.
fn diff(t: &[u32; 4], to: Port, from: Port) -> i64 {
    let a = PortTime(t.get(to.index()).copied().unwrap_or(0));
    let b = PortTime(t.get(from.index()).copied().unwrap_or(0));
    i64::from(a.wrapping_since(b))
}

/// Whether the stamp of `port` changed between two reads.
fn changed(cur: &[u32; 4], prev: &[u32; 4], port: Port) -> bool {
    cur.get(port.index()) != prev.get(port.index())
}

/// `sum / n` rounded to nearest (ties up); `None` if it does not fit an `i32`.
fn mean(sum: i64, n: i64) -> Option<i32> {
    let q = sum
        .checked_mul(2)?
        .checked_add(n)?
        .checked_div_euclid(n.checked_mul(2)?)?;
    i32::try_from(q).ok()
}

impl<const N: usize> Machine<N> {
    fn tdiff_cfg(&self) -> &TdiffConfig {
        &self.sh.cfg.tdiff
    }

    /// The user's value for slave `i`, if any: a per-slave override, else a per-type entry.
    fn configured_t_diff(&self, i: u16, s: &SlaveInfo) -> Option<i32> {
        configured(&self.sh.line.t_diff, self.tdiff_cfg(), i, s)
    }

    /// Number of items of the current t_Diff step.
    pub(crate) fn tdiff_count(&self) -> u16 {
        match self.phase {
            Phase::Tdiff(TdiffStep::Read) => TdiffRead::items(self.sh.line.count),
            Phase::Tdiff(TdiffStep::Latch) => self
                .sh
                .line
                .count
                .saturating_add(u16::from(self.tdiff_chained())),
            Phase::Tdiff(TdiffStep::Trigger)
            | Phase::Tdiff(TdiffStep::Close)
            | Phase::Tdiff(TdiffStep::Restore) => 1,
            _ => 0,
        }
    }

    /// The typed work item `i` of the current step, `None` when there is nothing to send.
    fn tdiff_work(&self, i: u16) -> Option<Work> {
        let off = self.tdiff_cfg().mode == TdiffMode::Off;
        match self.phase {
            Phase::Tdiff(TdiffStep::Read) if !off => {
                let (pos, read) = TdiffRead::of(i)?;
                let s = self.sh.line.slave(pos)?;
                match read {
                    TdiffRead::Ident => Some(Work::Ident(pos)),
                    TdiffRead::AlStatus => Some(Work::AlStatus(pos)),
                    TdiffRead::DlControl => (s.dc.has_latches()
                        && PortSet::from_dl_status(s.dl_status).len() >= 2)
                        .then_some(Work::ReadDlControl(pos)),
                }
            }
            Phase::Tdiff(TdiffStep::Latch) if i == self.sh.line.count => {
                self.tdiff_chained().then_some(Work::Trigger)
            }
            Phase::Tdiff(TdiffStep::Latch) => {
                let s = self.sh.line.slave(i)?;
                match self.sh.tdiff.latch {
                    Latch::Closed { target, .. } => match self.sh.tdiff.plan_of(target) {
                        Plan::Measure { parent, .. } if parent == i => Some(Work::ReadPorts(i)),
                        _ => None,
                    },
                    _ => s.dc.has_latches().then_some(Work::ReadPorts(i)),
                }
            }
            Phase::Tdiff(TdiffStep::Trigger) => Some(Work::Trigger),
            Phase::Tdiff(TdiffStep::Close) | Phase::Tdiff(TdiffStep::Restore) => {
                match self.sh.tdiff.latch {
                    Latch::Closed { target, .. }
                        if matches!(self.phase, Phase::Tdiff(TdiffStep::Close)) =>
                    {
                        Some(Work::Close(target))
                    }
                    Latch::Closed { target, .. } => Some(Work::Restore(target)),
                    _ => None,
                }
            }
            _ => None,
        }
    }

    pub(crate) fn tdiff_item(&self, i: u16) -> Item {
        let Some(w) = self.tdiff_work(i) else {
            return Item::Skip;
        };
        let station = |pos: u16| self.sh.line.slave(pos).map_or(0, |s| s.station);
        let op = match w {
            Work::Ident(pos) => Op::fprd(station(pos), ESC_TYPE, 2),
            Work::AlStatus(pos) => Op::fprd(station(pos), reg::AL_STATUS, 2),
            Work::ReadDlControl(pos) => Op::fprd(station(pos), DL_CONTROL, 2),
            Work::Trigger => LATCH_TRIGGER,
            Work::ReadPorts(pos) => Op::fprd(station(pos), reg::RECEIVE_TIME_PORT0, 16),
            Work::Close(pos) => {
                let original = self.sh.tdiff.dl_control.get(usize::from(pos)).copied();
                let close = match self.sh.tdiff.plan_of(pos) {
                    Plan::Measure { close, .. } => close,
                    Plan::Skip | Plan::Done { .. } => PortSet::EMPTY,
                };
                let mut v = original.unwrap_or(0);
                for p in Port::PROCESSING_ORDER {
                    if close.contains(p) {
                        v |= LOOP_CLOSED << (8u8.saturating_add(p.number().saturating_mul(2)));
                    }
                }
                Op::fpwr(station(pos), DL_CONTROL, 2, u64::from(v))
            }
            Work::Restore(pos) => {
                let original = self.sh.tdiff.dl_control.get(usize::from(pos)).copied();
                Op::fpwr(
                    station(pos),
                    DL_CONTROL,
                    2,
                    u64::from(original.unwrap_or(0)),
                )
            }
        };
        Item::Send(op)
    }

    /// Whether the read step of the current latch also carries the trigger of the next one
    /// (last in the step, so in its last frame): the next latch is of the same kind (all ports
    /// open, or the same target closed). Every read of a frame comes before its trigger, and a
    /// read sees the registers as the previous latch left them: an ESC stamps port 0 and its
    /// EPU at the start of the frame but shows them only once the write to 0x0900 has been
    /// processed, and the other ports only when the frame comes back through them (Beckhoff
    /// ESC datasheet section I, propagation delay measurement). So one frame per round instead
    /// of two; the check that every stamp changed (REQ-DC-124) still catches a latch that did
    /// not happen.
    fn tdiff_chained(&self) -> bool {
        let c = self.tdiff_cfg();
        match self.sh.tdiff.latch {
            Latch::Pre => true,
            Latch::Base { round } => round.saturating_add(1) < c.base_rounds,
            Latch::Closed { round, .. } => round.saturating_add(1) < c.rounds,
        }
    }

    /// Slaves (all, latching) that the current trigger can reach.
    fn tdiff_reachable(&self) -> (u16, u16) {
        let cut = match self.sh.tdiff.latch {
            Latch::Closed { target, .. } => match self.sh.tdiff.plan_of(target) {
                Plan::Measure { end, .. } => Some((target, end)),
                Plan::Skip | Plan::Done { .. } => None,
            },
            _ => None,
        };
        let mut all = 0u16;
        let mut latching = 0u16;
        for (i, s) in (0u16..).zip(self.slaves()) {
            if cut.is_some_and(|(t, end)| i > t && i < end) {
                continue;
            }
            all = all.saturating_add(1);
            if s.dc.has_latches() {
                latching = latching.saturating_add(1);
            }
        }
        (all, latching)
    }

    pub(crate) fn tdiff_reply(&mut self, r: Reply<'_>) -> Result<(), Error> {
        let (i, p, wkc, data) = r.parts();
        let Some(w) = self.tdiff_work(i) else {
            return Ok(());
        };
        let bad = p.out_of_range();
        if w == Work::Trigger {
            // REQ-DC-125: the slaves behind a closed port are cut off and do not count.
            let (all, latching) = self.tdiff_reachable();
            return p.check_latch_wkc(wkc, latching, all);
        }
        expect_wkc(p, 1, wkc)?;
        let word = || le(data, 2).and_then(|v| u16::try_from(v).ok()).ok_or(bad);
        match w {
            Work::Ident(pos) => {
                let v = word()?;
                if let Some(s) = self.sh.line.slave_mut(pos) {
                    s.esc_type = v;
                }
            }
            Work::AlStatus(pos) => {
                let v = word()?;
                if let Some(s) = self.sh.line.slave_mut(pos) {
                    s.al_status = Some(v);
                }
            }
            Work::ReadDlControl(pos) => {
                let v = word()?;
                if let Some(slot) = self.sh.tdiff.dl_control.get_mut(usize::from(pos)) {
                    *slot = v;
                }
            }
            Work::ReadPorts(pos) => {
                let t = ReceiveTimes::parse_ports(data).map_err(|_| bad)?;
                if let Some(slot) = self.sh.tdiff.cur.get_mut(usize::from(pos)) {
                    *slot = t;
                }
            }
            Work::Trigger | Work::Close(_) | Work::Restore(_) => {}
        }
        Ok(())
    }

    /// Retry target of a failed t_Diff step: a failed trigger or read latches again.
    pub(crate) fn tdiff_retry_state(&self) -> Option<State> {
        matches!(
            self.phase,
            Phase::Tdiff(TdiffStep::Trigger | TdiffStep::Latch)
        )
        .then_some(State::TdiffTrigger)
    }

    pub(crate) fn tdiff_done(&mut self) -> Result<State, Error> {
        match self.phase {
            Phase::Tdiff(TdiffStep::Read) => {
                if self.tdiff_cfg().mode == TdiffMode::Off {
                    return Ok(self.tdiff_finish());
                }
                // REQ-DC-123: never cut off a running slave.
                self.sh.tdiff.running = self
                    .slaves()
                    .iter()
                    .any(|s| !s.al_status.is_some_and(offset_write_permitted));
                if self.sh.tdiff.running {
                    return Ok(self.tdiff_finish());
                }
                self.sh.tdiff.latch = Latch::Pre;
                Ok(State::TdiffLatch)
            }
            Phase::Tdiff(TdiffStep::Trigger) => Ok(State::TdiffLatch),
            Phase::Tdiff(TdiffStep::Latch) => self.tdiff_latch_done(),
            Phase::Tdiff(TdiffStep::Close) => Ok(State::TdiffTrigger),
            Phase::Tdiff(TdiffStep::Restore) => {
                self.sh.tdiff.pending = None;
                if let Latch::Closed { target, .. } = self.sh.tdiff.latch {
                    let c = self.tdiff_cfg();
                    let base = self
                        .sh
                        .tdiff
                        .base
                        .get(usize::from(target))
                        .copied()
                        .unwrap_or(0);
                    // closed/R − base/B = (closed·B − base·R) / (R·B), rounded once.
                    let m = self
                        .sh
                        .tdiff
                        .closed
                        .checked_mul(i64::from(c.base_rounds))
                        .zip(base.checked_mul(i64::from(c.rounds)))
                        .and_then(|(x, y)| x.checked_sub(y))
                        .and_then(|d| {
                            mean(
                                d,
                                i64::from(c.rounds).saturating_mul(i64::from(c.base_rounds)),
                            )
                        });
                    if let Some(slot) = self.sh.tdiff.plan.get_mut(usize::from(target)) {
                        *slot = Plan::Done { mean: m };
                    }
                    return Ok(self.tdiff_next(target.saturating_add(1)));
                }
                Ok(self.tdiff_finish())
            }
            _ => Ok(self.state()),
        }
    }

    /// The next target from position `from` on (its port gets closed), or the end.
    fn tdiff_next(&mut self, from: u16) -> State {
        match self.sh.tdiff.next_target(from) {
            Some(t) => {
                self.sh.tdiff.latch = Latch::Closed {
                    target: t,
                    round: 0,
                };
                let station = self.sh.line.slave(t).map_or(0, |s| s.station);
                let original = self.sh.tdiff.dl_control.get(usize::from(t)).copied();
                self.sh.tdiff.pending = Some((station, original.unwrap_or(0)));
                self.sh.tdiff.closed = 0;
                State::TdiffClose
            }
            None => self.tdiff_finish(),
        }
    }

    fn tdiff_latch_done(&mut self) -> Result<State, Error> {
        let rounds = self.tdiff_cfg().rounds;
        let base_rounds = self.tdiff_cfg().base_rounds;
        let stale = |m: &Self, pos: u16| Error::Measurement {
            station: m.sh.line.slave(pos).map_or(0, |s| s.station),
        };
        match self.sh.tdiff.latch {
            Latch::Pre => {
                self.sh.tdiff.prev = self.sh.tdiff.cur;
                self.sh.tdiff.latch = Latch::Base { round: 0 };
                // The read step carried the first trigger (`tdiff_chained`).
                Ok(State::TdiffLatch)
            }
            Latch::Base { round } => {
                if round == 0 {
                    self.tdiff_plan()?;
                    if self.sh.tdiff.next_target(0).is_none() {
                        // Nothing to measure (e.g. a two-slave line: the first DC slave and a
                        // line end): the remaining all-open rounds would serve no target.
                        return Ok(self.tdiff_finish());
                    }
                }
                for b in self.positions() {
                    let Plan::Measure {
                        parent,
                        q,
                        p,
                        entry,
                        last,
                        ..
                    } = self.sh.tdiff.plan_of(b)
                    else {
                        continue;
                    };
                    let (tc, tp) = self.tdiff_times(parent);
                    let (bc, bp) = self.tdiff_times(b);
                    if !changed(&tc, &tp, q)
                        || !changed(&tc, &tp, p)
                        || !changed(&bc, &bp, entry)
                        || !changed(&bc, &bp, last)
                    {
                        return Err(stale(self, b));
                    }
                    let i = usize::from(b);
                    if round == 0 {
                        if let Some(f) = self.sh.tdiff.first.get_mut(i) {
                            *f = (
                                tc.get(q.index()).copied().unwrap_or(0),
                                bc.get(entry.index()).copied().unwrap_or(0),
                            );
                        }
                    }
                    if let Some(x) = self.sh.tdiff.base.get_mut(i) {
                        *x = x.saturating_add(diff(&tc, p, q));
                    }
                    if let Some(r) = self.sh.tdiff.rtt.get_mut(i) {
                        *r = r.saturating_add(diff(&bc, last, entry));
                    }
                }
                self.sh.tdiff.prev = self.sh.tdiff.cur;
                let next = round.saturating_add(1);
                if next < base_rounds {
                    self.sh.tdiff.latch = Latch::Base { round: next };
                    return Ok(State::TdiffLatch);
                }
                self.tdiff_rate_correct();
                Ok(self.tdiff_next(0))
            }
            Latch::Closed { target, round } => {
                let Plan::Measure { parent, q, p, .. } = self.sh.tdiff.plan_of(target) else {
                    return Ok(self.tdiff_next(target.saturating_add(1)));
                };
                let (tc, tp) = self.tdiff_times(parent);
                if !changed(&tc, &tp, q) || !changed(&tc, &tp, p) {
                    return Err(stale(self, parent));
                }
                self.sh.tdiff.closed = self.sh.tdiff.closed.saturating_add(diff(&tc, p, q));
                if let (Some(dst), Some(src)) = (
                    self.sh.tdiff.prev.get_mut(usize::from(parent)),
                    self.sh.tdiff.cur.get(usize::from(parent)),
                ) {
                    *dst = *src;
                }
                let next = round.saturating_add(1);
                if next < rounds {
                    self.sh.tdiff.latch = Latch::Closed {
                        target,
                        round: next,
                    };
                    return Ok(State::TdiffLatch);
                }
                Ok(State::TdiffRestore)
            }
        }
    }

    /// After the all-open rounds: `base[b]` = Σ X − Σ rtt·(Δ_a/Δ_b). X is read on the upstream
    /// slave's free-running clock and rtt on the target's; both are long on a long line (the
    /// whole subtree's round trip) and two crystals differ by up to ~100 ppm, i.e. 50 ns over
    /// 500 µs, so rtt is converted to the upstream clock with the ratio of the two clocks'
    /// advance between the first and the last round (Δ_a at port q, Δ_b at the target's entry:
    /// the same frames). REQ-DC-121.
    fn tdiff_rate_correct(&mut self) {
        for b in self.positions() {
            let Plan::Measure {
                parent, q, entry, ..
            } = self.sh.tdiff.plan_of(b)
            else {
                continue;
            };
            let i = usize::from(b);
            let (fa, fb) = self.sh.tdiff.first.get(i).copied().unwrap_or((0, 0));
            let last_a = self
                .sh
                .tdiff
                .prev
                .get(usize::from(parent))
                .and_then(|t| t.get(q.index()));
            let last_b = self.sh.tdiff.prev.get(i).and_then(|t| t.get(entry.index()));
            let span = |last: Option<&u32>, first: u32| {
                last.map(|l| i64::from(PortTime(*l).wrapping_since(PortTime(first))))
            };
            let rtt = self.sh.tdiff.rtt.get(i).copied().unwrap_or(0);
            // Without a usable span (one round), the clocks are taken as equal.
            let conv = match (span(last_a, fa), span(last_b, fb)) {
                (Some(da), Some(db)) if da > 0 && db > 0 => rtt
                    .checked_mul(da)
                    .and_then(|v| v.checked_add(db.checked_div(2)?))
                    .and_then(|v| v.checked_div(db))
                    .unwrap_or(rtt),
                _ => rtt,
            };
            if let Some(x) = self.sh.tdiff.base.get_mut(i) {
                *x = x.saturating_sub(conv);
            }
        }
    }

    fn tdiff_times(&self, pos: u16) -> ([u32; 4], [u32; 4]) {
        let i = usize::from(pos);
        (
            self.sh.tdiff.cur.get(i).copied().unwrap_or_default(),
            self.sh.tdiff.prev.get(i).copied().unwrap_or_default(),
        )
    }

    /// REQ-DC-121/122: from the first all-open latch, which slaves are measured and through
    /// which upstream port pair.
    fn tdiff_plan(&mut self) -> Result<(), Error> {
        let count = usize::from(self.sh.line.count);
        for ((s, out), (cur, prev)) in self
            .sh
            .line
            .slaves
            .iter()
            .zip(self.sh.scratch.samples.iter_mut())
            .zip(self.sh.tdiff.cur.iter().zip(self.sh.tdiff.prev.iter()))
            .take(count)
        {
            let open = PortSet::from_dl_status(s.dl_status);
            let mut ports = open;
            let latches = if s.dc.has_latches() {
                ports = open.passed(prev, cur);
                Some(Latches::from_raw(*cur, 0))
            } else {
                None
            };
            *out = SlaveSample {
                ports,
                latches,
                t_diff: 0,
            };
        }
        let sc = &mut self.sh.scratch;
        let samples = sc.samples.get(..count).unwrap_or(&[]);
        sc.topo
            .build_in_place(samples, &mut sc.stack)
            .map_err(|_| Error::Measurement { station: 0 })?;
        let topo = &sc.topo;
        // Subtree ends: preorder, so the subtree of i is i..i+size(i).
        let size = &mut sc.subtree;
        size.fill(1);
        for i in (0..count).rev() {
            let own = size.get(i).copied().unwrap_or(1);
            if let Some(parent) = topo.node(i).and_then(|n| n.parent) {
                if let Some(ps) = size.get_mut(usize::from(parent.slave)) {
                    *ps = ps.saturating_add(own);
                }
            }
        }
        let mode = self.sh.cfg.tdiff.mode;
        let mut types_done: [Option<u16>; 8] = [None; 8];
        let (samples, topo, size) = (&sc.samples, &sc.topo, &sc.subtree);
        let plan = &mut self.sh.tdiff.plan;
        plan.fill(Plan::Skip);
        for (b, slot) in (0u16..).zip(plan.iter_mut()).take(count) {
            let Some(s) = self.sh.line.slaves.get(usize::from(b)) else {
                continue;
            };
            if !s.dc.has_latches()
                || configured(&self.sh.line.t_diff, &self.sh.cfg.tdiff, b, s).is_some()
            {
                continue;
            }
            let Some(node) = topo.node(usize::from(b)) else {
                continue;
            };
            // Only an ESC entered at port 0 with a downstream port turns the frame round through
            // its EPU when closed, and only then does its return hop cost t_F (REQ-DC-122).
            if node.entry != Port::P0 || node.downstream_ports() == 0 {
                continue;
            }
            // Nearest upstream slave with latches; non-DC slaves in between must be plain wire
            // (two ports), as in the delay walk (REQ-DC-017).
            let Some(mut link) = node.parent else {
                continue;
            };
            let mut ok = true;
            let mut steps = 0usize;
            while samples
                .get(usize::from(link.slave))
                .is_some_and(|x| x.latches.is_none())
            {
                let up = topo.node(usize::from(link.slave));
                match up
                    .and_then(|u| (u.ports.len() == 2).then_some(u.parent))
                    .flatten()
                {
                    Some(l) => link = l,
                    None => {
                        ok = false;
                        break;
                    }
                }
                steps = steps.saturating_add(1);
                if steps > N {
                    ok = false;
                    break;
                }
            }
            let Some(up) = topo.node(usize::from(link.slave)) else {
                continue;
            };
            if !ok {
                continue;
            }
            if mode == TdiffMode::PerEscType {
                if types_done.iter().flatten().any(|t| *t == s.esc_type) {
                    continue;
                }
                if let Some(free) = types_done.iter_mut().find(|t| t.is_none()) {
                    *free = Some(s.esc_type);
                }
            }
            let mut close = PortSet::EMPTY;
            for p in Port::PROCESSING_ORDER {
                if p != node.entry && node.ports.contains(p) {
                    close = close.with(p);
                }
            }
            let own = size.get(usize::from(b)).copied().unwrap_or(1);
            *slot = Plan::Measure {
                parent: link.slave,
                q: up.ports.prev_before(link.port).unwrap_or(up.entry),
                p: link.port,
                entry: node.entry,
                last: node.last_port(),
                close,
                end: b.saturating_add(own),
            };
        }
        Ok(())
    }

    /// REQ-DC-126: every slave's t_Diff and its source; then the delay measurement.
    fn tdiff_finish(&mut self) -> State {
        let cfg = *self.tdiff_cfg();
        let default = self.sh.cfg.t_diff_ns;
        let count = usize::from(self.sh.line.count);
        let mut measured = 0u16;
        let mut same_type = 0u16;
        let mut configured = 0u16;
        let mut fallback = 0u16;
        self.sh.scratch.resolved.fill((0, TdiffSource::Default));
        for i in (0u16..).take(count) {
            let Some(s) = self.sh.line.slave(i) else {
                continue;
            };
            let r = match self.sh.tdiff.plan_of(i) {
                Plan::Done { mean } => mean,
                _ => None,
            };
            let v = if let Some(v) = self.configured_t_diff(i, s) {
                (v, TdiffSource::Configured)
            } else if let Some(v) = r.filter(|v| (cfg.min_ns..=cfg.max_ns).contains(v)) {
                (v, TdiffSource::Measured)
            } else if let Some(v) = r {
                (
                    default,
                    TdiffSource::Fallback(TdiffFallback::Implausible { measured_ns: v }),
                )
            } else if let Some(v) = self.tdiff_earlier(i, s) {
                (v, TdiffSource::Earlier)
            } else if self.sh.tdiff.running && s.dc.has_latches() && cfg.mode != TdiffMode::Off {
                (default, TdiffSource::Fallback(TdiffFallback::Running))
            } else {
                (default, TdiffSource::Default)
            };
            if let Some(out) = self.sh.scratch.resolved.get_mut(usize::from(i)) {
                *out = v;
            }
        }
        let resolved = &mut self.sh.scratch.resolved;
        // Slaves without their own value (including non-DC slaves, whose t_Diff enters the
        // delays of the DC slaves behind them, and slaves a running network kept from being
        // measured) take one measured on the same ESC type + revision.
        for i in 0..count {
            let Some((_, TdiffSource::Default | TdiffSource::Fallback(TdiffFallback::Running))) =
                resolved.get(i).copied()
            else {
                continue;
            };
            let Some(s) = self.sh.line.slaves.get(i) else {
                continue;
            };
            let ty = s.esc_type;
            let from = (0u16..)
                .zip(self.sh.line.slaves.iter().zip(resolved.iter()))
                .take(count)
                .find(|(_, (o, (_, src)))| {
                    o.esc_type == ty && matches!(src, TdiffSource::Measured | TdiffSource::Earlier)
                })
                .map(|(j, (_, (v, _)))| (j, *v));
            if let (Some((j, v)), Some(slot)) = (from, resolved.get_mut(i)) {
                *slot = (v, TdiffSource::SameType { from: j });
            }
        }
        if resolved
            .iter()
            .take(count)
            .any(|(_, src)| *src == TdiffSource::Measured)
        {
            // A new measurement replaces what was kept (the slave count may have changed).
            self.sh.tdiff.kept.fill(None);
            self.sh.tdiff.kept_count = self.sh.line.count;
            for ((slot, s), (v, src)) in self
                .sh
                .tdiff
                .kept
                .iter_mut()
                .zip(self.sh.line.slaves.iter())
                .zip(resolved.iter())
                .take(count)
            {
                if *src == TdiffSource::Measured {
                    *slot = Some((s.esc_type, *v));
                }
            }
        }
        for (s, (v, src)) in self
            .sh
            .line
            .slaves
            .iter_mut()
            .zip(resolved.iter())
            .take(count)
        {
            s.t_diff_ns = *v;
            s.t_diff_source = *src;
            match src {
                TdiffSource::Measured | TdiffSource::Earlier => {
                    measured = measured.saturating_add(1);
                }
                TdiffSource::SameType { .. } => same_type = same_type.saturating_add(1),
                TdiffSource::Configured => configured = configured.saturating_add(1),
                TdiffSource::Fallback(_) => fallback = fallback.saturating_add(1),
                TdiffSource::Default => {}
            }
        }
        self.sh.push_event(Event::TdiffResolved {
            measured,
            same_type,
            configured,
            fallback,
        });
        self.sh.tdiff.clear();
        State::LatchReadBefore
    }

    /// The value measured at position `i` in an earlier bring-up, if this bring-up may not
    /// measure (a slave runs), the network has the same slave count and the slave there has
    /// the same ESC type and revision.
    fn tdiff_earlier(&self, i: u16, s: &SlaveInfo) -> Option<i32> {
        if !self.sh.tdiff.running || self.sh.tdiff.kept_count != self.sh.line.count {
            return None;
        }
        match self.sh.tdiff.kept.get(usize::from(i)).copied().flatten() {
            Some((ty, v)) if ty == s.esc_type => Some(v),
            _ => None,
        }
    }

    /// Resets the phase's data at the start of a bring-up; a restore left pending by an
    /// interrupted measurement becomes the first datagram of `CountSlaves`.
    pub(crate) fn tdiff_reset(&mut self) {
        self.sh.tdiff.clear();
        self.sh.tdiff.recovering = self.sh.tdiff.pending.is_some();
    }

    /// The restore of a target left closed by an interrupted bring-up (`CountSlaves` item 0
    /// while recovering): FPWR 0x0100 with the value read before it was closed.
    pub(crate) fn tdiff_recover_item(&self) -> Item {
        match self.sh.tdiff.pending {
            Some((station, v)) => Item::Send(Op::fpwr(station, DL_CONTROL, 2, u64::from(v))),
            None => Item::Skip,
        }
    }

    /// Its reply ends the recovery whatever its working counter (REQ-DC-124):
    /// - 1: restored;
    /// - 0: the slave is gone or was power-cycled (which also resets DL control);
    /// - 2 or more: the target kept its address while a topology change re-assigned that
    ///   address to another slave (the bring-up after a link break addresses only the slaves
    ///   it reaches; the ones behind the break keep their old addresses and come back with
    ///   them). The write has already been executed by every slave with that address, the
    ///   target among them, so its ports are open again. Sending it again would not change
    ///   that and, if treated as a fault, would repeat before every count: the bring-up could
    ///   never reach the address step that ends the duplicate.
    pub(crate) fn tdiff_recover_reply(&mut self) {
        self.sh.tdiff.pending = None;
    }
}

/// The user's value for slave `i`, if any: its override in `t_diff`, else a per-type entry
/// of `cfg`.
fn configured(t_diff: &[Option<i32>], cfg: &TdiffConfig, i: u16, s: &SlaveInfo) -> Option<i32> {
    if let Some(v) = t_diff.get(usize::from(i)).copied().flatten() {
        return Some(v);
    }
    cfg.types
        .iter()
        .flatten()
        .find(|t| t.esc_type == s.esc_type)
        .map(|t| t.t_diff_ns)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Where a t_Diff came from, in words, for every source.
    #[test]
    fn source_display() {
        let implausible = TdiffFallback::Implausible { measured_ns: -30 };
        for (source, words) in [
            (TdiffSource::Default, "default"),
            (TdiffSource::Configured, "configured"),
            (TdiffSource::Measured, "measured"),
            (TdiffSource::SameType { from: 4 }, "same type as 4"),
            (TdiffSource::Earlier, "measured in an earlier bring-up"),
            (
                TdiffSource::Fallback(TdiffFallback::Running),
                "fallback: running",
            ),
            (
                TdiffSource::Fallback(implausible),
                "fallback: measured -30 ns implausible",
            ),
        ] {
            assert_eq!(std::format!("{source}"), words);
        }
    }
    use super::mean;

    /// The stamp helpers: a wrapping difference of one slave's port times, and whether a
    /// port's stamp changed between two reads.
    #[test]
    fn stamp_difference_and_change() {
        let t = [0xFFFF_FF00u32, 0x0000_0100, 7, 7];
        assert_eq!(diff(&t, Port::P1, Port::P0), 0x200);
        assert_eq!(diff(&t, Port::P0, Port::P1), -0x200);
        assert_eq!(diff(&t, Port::P2, Port::P3), 0);
        let prev = [0xFFFF_FF00u32, 0x0000_00FF, 7, 8];
        assert!(!changed(&t, &prev, Port::P0));
        assert!(changed(&t, &prev, Port::P1));
        assert!(changed(&t, &prev, Port::P3));
    }

    fn measure(parent: u16) -> Plan {
        Plan::Measure {
            parent,
            q: Port::P0,
            p: Port::P1,
            entry: Port::P0,
            last: Port::P0,
            close: crate::dc::port::PortSet::EMPTY,
            end: parent + 2,
        }
    }

    /// Targets are found in position order from where the search starts; `forget` and
    /// `clear` drop the plans, and only `clear` keeps what survives a bring-up.
    #[test]
    fn plans_targets_and_resets() {
        let mut t = Tdiff::<6>::new();
        t.plan[2] = measure(1);
        t.plan[4] = measure(3);
        t.plan[5] = Plan::Done { mean: Some(3) };
        assert_eq!(t.plan_of(2), measure(1));
        assert_eq!(t.plan_of(9), Plan::Skip);
        assert_eq!(
            [0, 2, 3, 5, 6].map(|f| t.next_target(f)),
            [Some(2), Some(2), Some(4), None, None]
        );
        t.pending = Some((0x1003, 0x0F00));
        t.kept[1] = Some((0x0111, 12));
        t.kept_count = 6;
        t.running = true;
        t.closed = 5;
        t.rtt[2] = 9;
        let mut cleared = t.clone();
        cleared.clear();
        assert_eq!(cleared.next_target(0), None);
        assert_eq!(
            (cleared.running, cleared.closed, cleared.rtt[2]),
            (false, 0, 0)
        );
        assert_eq!(
            (cleared.kept[1], cleared.kept_count),
            (Some((0x0111, 12)), 6)
        );
        t.forget();
        assert_eq!(t.next_target(0), None);
        assert_eq!((t.running, t.closed, t.rtt[2]), (false, 0, 0));
        assert_eq!((t.kept[1], t.kept_count), (None, 0));
        assert_eq!(
            t.pending,
            Some((0x1003, 0x0F00)),
            "a closed port is still reopened"
        );
    }

    /// A slave's own override wins over a per-type entry; a type without an entry has none.
    #[test]
    fn configured_override_then_type() {
        let mut cfg = TdiffConfig::default();
        cfg.types[1] = Some(crate::dc::TdiffType {
            esc_type: 0x0111,
            t_diff_ns: 25,
        });
        let of_type = |esc_type| SlaveInfo {
            esc_type,
            ..SlaveInfo::default()
        };
        let overrides = [None, Some(-7)];
        assert_eq!(configured(&overrides, &cfg, 0, &of_type(0x0111)), Some(25));
        assert_eq!(configured(&overrides, &cfg, 1, &of_type(0x0111)), Some(-7));
        assert_eq!(configured(&overrides, &cfg, 0, &of_type(0x0222)), None);
        assert_eq!(configured(&overrides, &cfg, 5, &of_type(0x0222)), None);
        // The machine's view: its per-slave overrides and its configuration.
        let mut m = Machine::<4>::new(crate::dc::Config::default()).unwrap();
        m.set_slave_t_diff(1, Some(-7)).unwrap();
        let s = of_type(0x0111);
        assert_eq!(
            (m.configured_t_diff(0, &s), m.configured_t_diff(1, &s)),
            (None, Some(-7))
        );
    }

    #[test]
    fn mean_rounds_to_nearest() {
        assert_eq!(mean(80 * 16, 16), Some(80));
        assert_eq!(mean(8 * 16 + 8, 16), Some(9));
        assert_eq!(mean(8 * 16 + 7, 16), Some(8));
        assert_eq!(mean(-(8 * 16 + 7), 16), Some(-8));
        assert_eq!(mean(i64::MAX, 16), None);
        assert_eq!(mean(5, 0), None);
    }
}

#[cfg(test)]
mod recovery_tests {
    use super::DL_CONTROL;
    use crate::dc::{Config, Machine, State};
    use crate::time::SystemTime;
    use crate::wire::{Command, EthernetFrame};

    /// REQ-DC-124: a port an interrupted t_Diff step may have left closed is reopened in a
    /// frame of its own, before the slave count: a BRD in the same frame would not reach the
    /// slaves behind the still-closed port, and the count would miss them.
    #[test]
    fn restore_goes_alone_before_the_count() {
        let mut m = Machine::<4>::new(Config::default()).unwrap();
        m.sh.tdiff.pending = Some((0x1002, 0x0000));
        m.start(SystemTime(0));
        let mut buf = [0u8; 1514];
        let n = m.poll_transmit(SystemTime(0), &mut buf).unwrap();
        let eth = EthernetFrame::new_checked(&buf[..n]).unwrap();
        let frame = eth.ecat_frame().unwrap();
        assert_eq!(frame.datagram_count(), Ok(1));
        let d = frame.iter().next().unwrap().unwrap();
        assert_eq!(
            (d.command(), d.adp(), d.ado()),
            (Ok(Command::Fpwr), 0x1002, DL_CONTROL)
        );
        // Its reply ends the recovery whatever its working counter (here 0: the slave is
        // gone); the count follows in the next frame and counts from its own reply.
        let mut reply = buf[..n].to_vec();
        let mut eth = EthernetFrame::new_unchecked(&mut reply[..]);
        eth.mark_processed_by_slave();
        m.handle_frame(SystemTime(1_000), &reply);
        assert_eq!(m.sh.tdiff.pending, None);
        let n = m.poll_transmit(SystemTime(2_000), &mut buf).unwrap();
        let mut reply = buf[..n].to_vec();
        let mut eth = EthernetFrame::new_unchecked(&mut reply[..]);
        eth.mark_processed_by_slave();
        let mut frame = eth.ecat_frame_mut().unwrap();
        let mut d = frame.iter_mut().next().unwrap().unwrap();
        assert_eq!((d.command(), d.ado()), (Ok(Command::Brd), 0x0000));
        d.set_wkc(3);
        m.handle_frame(SystemTime(3_000), &reply);
        assert_eq!((m.state(), m.sh.line.count), (State::AssignAddresses, 3));
    }
}
