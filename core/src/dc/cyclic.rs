//! Cyclic operation (REQ-DC-106, REQ-DC-107): every cycle one FRMW to the reference's 0x0910,
//! one BRD 0x092C (upper bound of every |Δt|, and by its WKC a topology check), a few per-slave
//! FPRD 0x092C in round robin, and, when requested, the steps of a delay re-measurement in the
//! room left. Lock and loss of lock use hysteresis on the bound; lost cycles are coasted over
//! up to `max_lost_cycles`; a topology change, a lost slave or a reset reference end in a typed
//! error and a re-initialisation.

use crate::dc::error::Error;
use crate::dc::event::Event;
use crate::dc::holdover::{Holdover, HoldoverCause};
use crate::dc::lock::{LockChange, LockHysteresis};
use crate::dc::machine::Machine;
use crate::dc::phase::Phase;
use crate::dc::remeasure::{Remeasure, RemeasureRun};
use crate::dc::request::{le, Op, Pending, Reply, Tag};
use crate::dc::shared::Shared;
use crate::dc::slave::SlaveInfo;
use crate::dc::state::State;
use crate::dc::timer::Timer;
use crate::time::SystemTime;
use crate::wire::register::{reg, SystemTimeDifference};
use crate::wire::FrameBuilder;

/// Per-cycle bookkeeping; its `Default` is a cycle run not started.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default)]
pub(crate) struct CyclicState {
    pub(crate) cycles: u32,
    pub(crate) rr: u16,
    pub(crate) lost_streak: u16,
    pub(crate) wkc_streak: u16,
    pub(crate) topo_streak: u16,
    /// Lock and loss of lock (`dc/lock.rs`).
    pub(crate) lock: LockHysteresis,
    pub(crate) bound_ns: Option<u32>,
    pub(crate) ref_time: Option<SystemTime>,
    /// What the replies of the cycle in flight reported.
    pub(crate) replies: CycleReplies,
    /// Master time the cycle in flight was sent.
    pub(crate) sent_at: SystemTime,
    /// Delay re-measurement (`dc/remeasure.rs`).
    pub(crate) remeasure: RemeasureRun,
    // Hold-over (`dc/holdover.rs`).
    /// The hold-over sub-state, when silent.
    pub(crate) holdover: Option<Holdover>,
    /// Master time of the last complete cycle's transmission (`None`: none yet).
    pub(crate) last_good: Option<SystemTime>,
    /// [`CycleReplies::al_status`] of the last complete cycle.
    pub(crate) al_ok: Option<u16>,
}

/// What the replies of one cycle reported; cleared when a cycle is sent.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default)]
pub(crate) struct CycleReplies {
    /// WKC of the FRMW that distributes the reference time.
    pub(crate) frmw_wkc: Option<u16>,
    /// WKC of the BRD 0x092C, and the bound it read (`CyclicState::bound_ns` keeps the last
    /// one read).
    pub(crate) bound_wkc: Option<u16>,
    pub(crate) bound_ns: Option<u32>,
    /// WKC of the BRD 0x0130 topology check, and the OR of every AL status it read.
    pub(crate) topo_wkc: Option<u16>,
    pub(crate) al_status: Option<u16>,
    /// A monitored slave whose FPRD 0x092C came back unanswered (WKC ≠ 1).
    pub(crate) lost_station: Option<u16>,
}

/// Cyclic operation at work: its own data and the machine's shared parts. A fault found here
/// ends the cyclic phase, so it is only recorded ([`CyclicCx::fail`]); the machine carries it
/// out when the cyclic code returns ([`Machine::in_cyclic`]), and the code returns right after
/// recording it.
pub(crate) struct CyclicCx<'a, const N: usize> {
    pub(crate) c: &'a mut CyclicState,
    pub(crate) sh: &'a mut Shared<N>,
    pub(crate) fault: Option<Error>,
}

impl<const N: usize> Machine<N> {
    /// Runs `f` on the cyclic phase's data and the shared parts, then carries out the fault it
    /// recorded, if any, at master time `now`. `None` outside `Cyclic`.
    #[inline(always)]
    pub(crate) fn in_cyclic<R>(
        &mut self,
        now: SystemTime,
        f: impl FnOnce(&mut CyclicCx<'_, N>) -> R,
    ) -> Option<R> {
        let Machine { phase, sh } = self;
        let Phase::Cyclic(c) = phase else {
            return None;
        };
        let mut cx = CyclicCx { c, sh, fault: None };
        let r = f(&mut cx);
        if let Some(e) = cx.fault {
            self.fault(now, e);
        }
        Some(r)
    }
}

impl<const N: usize> CyclicCx<'_, N> {
    /// Records a fault: cyclic operation ends with it once the cyclic code returns.
    pub(crate) fn fail(&mut self, e: Error) {
        self.fault.get_or_insert(e);
    }

    pub(crate) fn fill_cyclic(
        &mut self,
        now: SystemTime,
        b: &mut FrameBuilder<'_>,
        into_caller: bool,
    ) -> bool {
        if !into_caller && !self.sh.timers.expired(Timer::Cycle, now) {
            return false;
        }
        let period = self.sh.cfg.monitor.cycle_ns;
        // No transmission for more than `max_lost_cycles` periods: the master stalled.
        let stall = period.saturating_mul(u64::from(self.sh.cfg.monitor.max_lost_cycles));
        if self.holdover_enabled()
            && self.c.holdover.is_none()
            && self.c.cycles > 0
            && now.saturating_since(self.c.sent_at) > stall
        {
            self.holdover_start(self.silence_since(), HoldoverCause::Stall);
        }
        if self.sh.timers.is_set(Timer::Reply) {
            // The previous cycle's datagrams never came back.
            self.cyclic_lost(now);
            if self.fault.is_some() {
                return false;
            }
        }
        if self.holdover_expired(now) {
            return false;
        }
        // The next cycle one period after this one's due time, or after now if that passed
        // (the timer is armed throughout `Cyclic`; a cycle the caller forces is due now).
        let due = self.sh.timers.get(Timer::Cycle).unwrap_or(now);
        let next = due.wrapping_add(period);
        let next = if next.is_after(now) {
            next
        } else {
            now.wrapping_add(period)
        };
        self.sh.timers.set(Timer::Cycle, next);
        let before = b.datagram_count();
        self.sh.inflight.clear();
        self.c.replies = CycleReplies::default();
        let frmw = self.sh.frmw_op(now);
        if !self.push_cycle_block(b, frmw) && !self.push_cycle_each(b, frmw) {
            if before == 0 {
                self.sh.push_event(Event::Error(Error::BufferTooSmall));
            }
            return false;
        }
        self.fill_remeasure(b);
        self.c.sent_at = now;
        let timeout = self.sh.cfg.response_timeout_ns.min(period);
        self.sh.timers.set(Timer::Reply, now.wrapping_add(timeout));
        self.c.cycles = self.c.cycles.saturating_add(1);
        self.sh.stats.cycles = self.sh.stats.cycles.saturating_add(1);
        self.sh.stats.frames_sent = self.sh.stats.frames_sent.saturating_add(1);
        true
    }

    /// The next round-robin position (and advances the cursor). `count > 0`; `rr < count`
    /// except after a re-count.
    #[inline]
    fn rr_step(&mut self) -> u16 {
        let pos = self.rr_start();
        self.c.rr = rr_after(pos, self.sh.line.count);
        pos
    }

    /// The round robin's current position: the cursor, or (after a re-count left it beyond
    /// the slaves) the cursor modulo the count; 0 without slaves.
    #[inline]
    pub(crate) fn rr_start(&self) -> u16 {
        if self.c.rr < self.sh.line.count {
            self.c.rr
        } else {
            self.c.rr.checked_rem(self.sh.line.count).unwrap_or(0)
        }
    }

    /// The round robin's next slave with a system time, as (position, station); `scanned`
    /// counts the positions stepped over this cycle, at most `count`. `None` when they are
    /// used up (or the position is beyond the table).
    #[inline]
    pub(crate) fn rr_next_monitored(&mut self, scanned: &mut u16) -> Option<(u16, u16)> {
        while *scanned < self.sh.line.count {
            let pos = self.rr_step();
            *scanned = scanned.saturating_add(1);
            let (station, has_time) = self
                .sh
                .line
                .slave(pos)
                .map(|s| (s.station, s.dc.has_system_time()))?;
            if has_time {
                return Some((pos, station));
            }
        }
        None
    }

    /// The cycle's fixed datagrams pushed one by one: FRMW, BRD 0x092C, BRD 0x0130, then
    /// round robin over the slaves with a system time (up to `slaves_per_cycle` FPRD 0x092C),
    /// as many as fit. False if not even the FRMW fits.
    pub(crate) fn push_cycle_each(&mut self, b: &mut FrameBuilder<'_>, frmw: Op) -> bool {
        if !self.sh.push_op(b, frmw, Tag::Frmw) {
            return false;
        }
        let _ = self
            .sh
            .push_op(b, Op::brd(reg::SYSTEM_TIME_DIFFERENCE, 4), Tag::CycBound);
        let _ = self
            .sh
            .push_op(b, Op::brd(reg::AL_STATUS, 2), Tag::CycTopology);
        let mut budget = self.sh.cfg.monitor.slaves_per_cycle;
        let mut scanned = 0u16;
        while budget > 0 {
            let Some((pos, station)) = self.rr_next_monitored(&mut scanned) else {
                break;
            };
            if !self.sh.push_op(
                b,
                Op::fprd(station, reg::SYSTEM_TIME_DIFFERENCE, 4),
                Tag::CycDiff(pos),
            ) {
                break;
            }
            budget = budget.saturating_sub(1);
        }
        true
    }

    #[inline]
    pub(crate) fn on_cyclic_reply(&mut self, now: SystemTime, p: Pending, wkc: u16, data: &[u8]) {
        match p.tag {
            Tag::Frmw => self.on_frmw_reply(now, p.len, wkc, data),
            Tag::CycBound => self.on_bound_reply(wkc, data),
            Tag::CycTopology => self.on_topology_reply(wkc, data),
            Tag::CycDiff(pos) => {
                if let Some(&raw) = data.first_chunk::<4>().filter(|_| data.len() == 4) {
                    self.on_diff_reply(pos, p.station, wkc, raw);
                } else if wkc != 1 {
                    self.c.replies.lost_station.get_or_insert(p.station);
                }
            }
            Tag::CycRemeasure(i) => self.remeasure_reply(Reply {
                item: i,
                sent: p,
                wkc,
                data,
            }),
            Tag::Item(_) => {}
        }
    }

    /// The cycle's FRMW (or ARMW) reply: the reference's system time (`len` 8, or 4 extended
    /// around `now`), used only with the full working counter.
    #[inline(always)]
    pub(crate) fn on_frmw_reply(&mut self, now: SystemTime, len: u16, wkc: u16, data: &[u8]) {
        self.c.replies.frmw_wkc = Some(wkc);
        if wkc == self.sh.line.sys_count {
            if let Some(v) = le(data, usize::from(len)) {
                let t = if len == 8 {
                    SystemTime(v)
                } else {
                    let low = u32::try_from(v).unwrap_or(0);
                    SystemTime::extend_low32(low, now)
                };
                self.c.ref_time = Some(t);
            }
        }
    }

    /// The cycle's BRD 0x092C reply: the upper bound of every |Δt|, used only with the full
    /// working counter.
    #[inline(always)]
    pub(crate) fn on_bound_reply(&mut self, wkc: u16, data: &[u8]) {
        self.c.replies.bound_wkc = Some(wkc);
        if wkc == self.sh.line.sys_count {
            if let Some(raw) = le(data, 4).and_then(|v| u32::try_from(v).ok()) {
                let bound = SystemTimeDifference::from_raw(raw).magnitude();
                self.c.bound_ns = Some(bound);
                self.c.replies.bound_ns = Some(bound);
            }
        }
    }

    /// The cycle's BRD 0x0130 reply: its working counter is the slave count, its data the OR
    /// of every AL status.
    #[inline(always)]
    pub(crate) fn on_topology_reply(&mut self, wkc: u16, data: &[u8]) {
        self.c.replies.topo_wkc = Some(wkc);
        if wkc > 0 {
            self.c.replies.al_status = le(data, 2).and_then(|v| u16::try_from(v).ok());
        }
    }

    /// Master time the current silence is counted from: the cycle after the last complete
    /// one (the first that did not come back or was not sent), or the first cycle's
    /// transmission before any completed.
    pub(crate) fn silence_since(&self) -> SystemTime {
        self.c.last_good.map_or(self.c.sent_at, |t| {
            t.wrapping_add(self.sh.cfg.monitor.cycle_ns)
        })
    }

    /// A round-robin FPRD 0x092C reply: [`diff_reply`].
    #[inline(always)]
    pub(crate) fn on_diff_reply(&mut self, pos: u16, station: u16, wkc: u16, raw: [u8; 4]) {
        diff_reply(
            &mut self.sh.line.slaves,
            self.sh.line.count,
            self.c,
            pos,
            station,
            wkc,
            raw,
        );
    }

    /// All of this cycle's datagrams came back: evaluate faults, then lock.
    pub(crate) fn cyclic_complete(&mut self, now: SystemTime) {
        if let Some(h) = self.c.holdover {
            if self.holdover_expired(now) || !self.resume_check(now, h) {
                return;
            }
        }
        self.c.last_good = Some(self.c.sent_at);
        self.c.al_ok = self.c.replies.al_status;
        self.c.lost_streak = 0;
        let max_wkc = self.sh.cfg.monitor.max_wkc_errors;
        // Every slave counts the BRD of 0x0130, every slave with a system time the BRD of
        // 0x092C: either count changing means slaves appeared or disappeared.
        let topo = match (self.c.replies.topo_wkc, self.c.replies.bound_wkc) {
            (Some(w), _) if w != self.sh.line.count => Some(w),
            (_, Some(w)) if w != self.sh.line.sys_count => Some(
                self.sh
                    .line
                    .count
                    .saturating_sub(self.sh.line.sys_count)
                    .saturating_add(w),
            ),
            _ => None,
        };
        match topo {
            // A slave gone from its address in the same cycle as the count changed: the
            // topology changed, no need to wait for confirmation.
            Some(found) if self.c.replies.lost_station.is_some() => {
                return self.fail(Error::TopologyChanged {
                    expected: self.sh.line.count,
                    found,
                });
            }
            Some(found) => {
                self.c.topo_streak = self.c.topo_streak.saturating_add(1);
                if self.c.topo_streak >= max_wkc {
                    return self.fail(Error::TopologyChanged {
                        expected: self.sh.line.count,
                        found,
                    });
                }
            }
            None => self.c.topo_streak = 0,
        }
        // A reset or lost reference no longer reads the FRMW; slaves behind a break no longer
        // write it.
        match self.c.replies.frmw_wkc {
            Some(w) if w != self.sh.line.sys_count => {
                self.c.wkc_streak = self.c.wkc_streak.saturating_add(1);
                if self.c.wkc_streak >= max_wkc {
                    let station = self
                        .sh
                        .line
                        .slave(self.sh.line.reference)
                        .map_or(0, |s| s.station);
                    return self.fail(Error::Wkc {
                        command: self.sh.frmw_op(now).command,
                        station,
                        register: reg::SYSTEM_TIME,
                        expected: self.sh.line.sys_count,
                        actual: w,
                    });
                }
            }
            _ => self.c.wkc_streak = 0,
        }
        if let Some(station) = self.c.replies.lost_station {
            // A power-cycled ESC has lost its station address; a broken link drops it too.
            return self.fail(Error::SlaveLost { station });
        }
        if let Some(e) = self.c.remeasure.error.take() {
            self.c.remeasure.step = Remeasure::Idle;
            return self.fail(e);
        }
        self.remeasure_advance();
        if self.fault.is_some() {
            return;
        }
        self.update_lock();
    }

    fn update_lock(&mut self) {
        let m = self.sh.cfg.monitor;
        let Some(bound) = self.c.bound_ns else {
            return;
        };
        match self.c.lock.judge(bound, &m) {
            Some(LockChange::Locked) => {
                self.sh.restarts.streak = 0;
                let frames = self
                    .sh
                    .stats
                    .frames_sent
                    .saturating_sub(self.sh.restarts.frames_at_start);
                self.sh.stats.lock_frames = Some(frames);
                self.sh.push_event(Event::Locked {
                    frames,
                    bound_ns: bound,
                });
            }
            Some(LockChange::Lost) => {
                self.c.cycles = 0;
                self.sh.push_event(Event::LockLost { bound_ns: bound });
            }
            None => {}
        }
        if self
            .c
            .lock
            .not_locked_due(self.c.cycles, m.lock_timeout_cycles)
        {
            self.sh.push_event(Event::Error(Error::NotLocked {
                cycles: self.c.cycles,
                bound_ns: bound,
            }));
        }
    }

    /// The cycle in flight is lost: coast, or give up after `max_lost_cycles`.
    pub(crate) fn cyclic_lost(&mut self, now: SystemTime) {
        self.sh.stop_awaiting();
        self.sh.stats.lost_cycles = self.sh.stats.lost_cycles.saturating_add(1);
        self.c.lost_streak = self.c.lost_streak.saturating_add(1);
        // A lost re-measurement step is resent (a lost trigger restarts the measurement).
        self.c.remeasure.sent_to = self.c.remeasure.cursor;
        if self.c.remeasure.step == Remeasure::After {
            self.c.remeasure.step = Remeasure::Before;
            self.c.remeasure.cursor = 0;
            self.c.remeasure.sent_to = 0;
        }
        if self.c.holdover.is_some() {
            let _ = self.holdover_expired(now);
        } else if self.c.lost_streak >= self.sh.cfg.monitor.max_lost_cycles {
            if self.holdover_enabled() {
                self.holdover_start(self.silence_since(), HoldoverCause::Silence);
                let _ = self.holdover_expired(now);
            } else {
                self.fail(Error::Timeout {
                    state: State::Cyclic,
                });
            }
        }
    }
}

/// The round-robin position after `pos` among `count` slaves.
#[inline]
pub(crate) fn rr_after(pos: u16, count: u16) -> u16 {
    let next = pos.wrapping_add(1);
    if next >= count {
        0
    } else {
        next
    }
}

/// A round-robin FPRD 0x092C reply (4 data bytes `raw`) of the slave at `pos` (of `count` in
/// `slaves`): its Δt, or, if it did not answer (WKC ≠ 1), the cycle's first lost station.
/// (Split borrows: the cyclic receive path reads the in-flight table meanwhile.)
#[inline(always)]
pub(crate) fn diff_reply(
    slaves: &mut [SlaveInfo],
    count: u16,
    cyc: &mut CyclicState,
    pos: u16,
    station: u16,
    wkc: u16,
    raw: [u8; 4],
) {
    if wkc != 1 {
        cyc.replies.lost_station.get_or_insert(station);
    } else if let Some(s) = slaves.get_mut(usize::from(pos)).filter(|_| pos < count) {
        let d = SystemTimeDifference::from_raw(u32::from_le_bytes(raw));
        s.last_diff_ns = Some(i64::from(d.to_ns()));
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::dc::config::{Config, DriftCommand};
    use crate::dc::slave::DcKind;
    use crate::wire::{Address, Command, EthernetFrame};
    use std::format;

    const T: u64 = 0x0123_4567_89AB_CDEF;

    /// A machine in `Cyclic` with `n` slaves (every third without a system time, one 32-bit).
    fn cyclic_machine(n: u16, per_cycle: u8, rr: u16, cmd: DriftCommand, next: u8) -> Machine<48> {
        let mut cfg = Config::default();
        cfg.monitor.slaves_per_cycle = per_cycle;
        cfg.drift_command = cmd;
        let mut m = Machine::<48>::new(cfg).unwrap();
        m.phase = m.phase.enter(State::Cyclic);
        m.sh.timers.set(Timer::Cycle, SystemTime(0));
        m.sh.line.count = n;
        m.sh.line.sys_count = 0;
        for (i, s) in m.sh.line.slaves.iter_mut().enumerate().take(usize::from(n)) {
            s.station = 0x1001 + i as u16 * 0x0101;
            s.dc = match i % 3 {
                1 => DcKind::None,
                _ if i == 3 => DcKind::Bits32,
                _ => DcKind::Bits64,
            };
            if s.dc.has_system_time() {
                m.sh.line.sys_count += 1;
            }
        }
        m.phase.cyclic_mut().unwrap().rr = rr;
        m.sh.inflight.next_index = next;
        m
    }

    /// The block path writes exactly what pushing one by one writes (bytes, M bits, header
    /// length, indexes, in-flight entries, round-robin cursor, datagram a later push chains
    /// to), and when it declines it changes nothing. Over slave counts, per-cycle budgets,
    /// cursors (also past the count), both drift commands, the reference's width, buffer
    /// sizes (partial fits), an index counter about to wrap and a caller's datagram in front.
    #[test]
    fn cycle_block_equals_one_by_one() {
        let mut declined = 0u32;
        let mut taken = 0u32;
        for n in [0u16, 1, 2, 4, 5, 9, 31, 40] {
            for per_cycle in [0u8, 1, 3, 8, 29, 30, 64] {
                for rr in [0u16, n / 2, n.saturating_sub(1), n + 3] {
                    for cmd in [DriftCommand::Frmw, DriftCommand::Armw] {
                        for reference in [0u16, 3] {
                            for next in [0x80u8, 0xFE, 0xFF] {
                                for size in [60usize, 90, 120, 200, 1514] {
                                    for caller in [false, true] {
                                        let mut m = cyclic_machine(n, per_cycle, rr, cmd, next);
                                        if reference < n {
                                            m.sh.line.reference = reference;
                                        }
                                        if compare(&m, size, caller) {
                                            taken += 1;
                                        } else {
                                            declined += 1;
                                        }
                                    }
                                }
                            }
                        }
                    }
                }
            }
        }
        assert!(taken > 1000 && declined > 100, "{taken} {declined}");
    }

    /// The cyclic receive fast path changes the machine exactly as the general path does
    /// (state, table, slaves, stats, events), on the reply to a cyclic frame and on every
    /// single-byte change of it, with datagrams in flight already taken or not.
    #[test]
    fn cyclic_fast_equals_general() {
        let mut fast_taken = 0u32;
        let mut cases = 0u32;
        let mut block_taken = 0u32;
        let mut pattern_taken = 0u32;
        let shapes = [(1u16, 8u8), (5, 3), (9, 8), (40, 29), (3, 0)];
        for ((n, per_cycle), remeasure) in shapes.into_iter().flat_map(|s| [(s, false), (s, true)])
        {
            let mut m = cyclic_machine(n, per_cycle, 0, DriftCommand::Frmw, 0x80);
            m.sh.line.reference = 0;
            if remeasure {
                // Re-measurement reads ride behind the cycle's own datagrams: the table is
                // no longer the cycle's block, so the pattern walk applies.
                m.request_delay_measurement();
            }
            let mut buf = std::vec![0u8; 1514];
            let len = m.poll_transmit(SystemTime(T), &mut buf).unwrap();
            assert!(m.is_awaiting_reply());
            let mut reply = buf[..len].to_vec();
            // As the slaves return it: processed-by-slave bit, data and working counters.
            reply[6] |= 0x02;
            {
                let mut eth = EthernetFrame::new_checked(&mut reply[..]).unwrap();
                let mut f = eth.ecat_frame_mut().unwrap();
                for (k, mut d) in f.iter_mut().map(Result::unwrap).enumerate() {
                    let fill = 0x10u8.wrapping_add(k as u8);
                    d.data_mut().iter_mut().for_each(|b| *b = fill);
                    d.set_wkc(if k < 2 { m.sh.line.sys_count } else { 1 });
                }
            }
            let mut variants = std::vec![reply.clone()];
            for at in 14..reply.len() {
                for x in [0x01u8, 0x02, 0x07, 0x40, 0x80, 0xFF] {
                    let mut v = reply.clone();
                    v[at] ^= x;
                    variants.push(v);
                }
            }
            variants.push(reply[..reply.len() - 1].to_vec());
            // The unchanged reply takes the path the table's shape calls for.
            {
                let eth = EthernetFrame::new_checked(&reply[..]).unwrap();
                let f = eth.ecat_frame_unvalidated().unwrap().into_inner();
                let n_sent = m.sh.inflight.fresh_len().unwrap();
                let mut c = m.clone();
                match c
                    .in_cyclic(SystemTime(T + 1), |cx| {
                        cx.cyclic_block_reply(SystemTime(T + 1), f, n_sent)
                    })
                    .unwrap()
                {
                    Some(true) => block_taken += 1,
                    Some(false) => panic!("block path refused its own reply"),
                    None => {
                        assert!(c
                            .in_cyclic(SystemTime(T + 1), |cx| cx.cyclic_pattern_reply(
                                SystemTime(T + 1),
                                f,
                                n_sent
                            ))
                            .unwrap());
                        pattern_taken += 1;
                    }
                }
            }
            for v in &variants {
                let mut a = m.clone();
                let mut b = m.clone();
                let mut c = m.clone();
                let eth = EthernetFrame::new_checked(&v[..]).unwrap();
                if let Some(f) = eth.ecat_frame_unvalidated() {
                    if c.in_cyclic(SystemTime(T + 1), |cx| {
                        cx.cyclic_fast(SystemTime(T + 1), f.into_inner())
                    }) == Some(true)
                    {
                        fast_taken += 1;
                    }
                }
                a.handle_frame_with(SystemTime(T + 1), v, true);
                b.handle_frame_with(SystemTime(T + 1), v, false);
                assert_eq!(format!("{a:?}"), format!("{b:?}"));
                // Once a reply is taken the table is no longer as filled: the path declines.
                if a.is_awaiting_reply() && a.sh.stats.foreign_frames == m.sh.stats.foreign_frames {
                    let before = format!("{a:?}");
                    let eth = EthernetFrame::new_checked(&reply[..]).unwrap();
                    let f = eth.ecat_frame_unvalidated().unwrap();
                    assert_eq!(
                        a.in_cyclic(SystemTime(T + 2), |cx| cx
                            .cyclic_fast(SystemTime(T + 2), f.into_inner())),
                        Some(false)
                    );
                    assert_eq!(format!("{a:?}"), before);
                }
                cases += 1;
            }
        }
        assert!(cases > 1000 && fast_taken > 100, "{cases} {fast_taken}");
        assert!(
            block_taken >= 5 && pattern_taken >= 1,
            "{block_taken} {pattern_taken}"
        );
    }

    /// Runs both paths on clones of `m`; returns whether the block path was taken.
    fn compare(m: &Machine<48>, size: usize, caller: bool) -> bool {
        let mut m1 = m.clone();
        let mut m2 = m.clone();
        let mut buf1 = std::vec![0xAAu8; size];
        let mut buf2 = std::vec![0xAAu8; size];
        let mut b1 = FrameBuilder::new(&mut buf1).unwrap();
        let mut b2 = FrameBuilder::new(&mut buf2).unwrap();
        if caller {
            let a = Address::logical(0x1000);
            b1.push(Command::Lrw, 7, a, &[1, 2, 3]).unwrap();
            b2.push(Command::Lrw, 7, a, &[1, 2, 3]).unwrap();
        }
        let before = m1.clone();
        let frmw = m1.sh.frmw_op(SystemTime(T));
        let block = m1
            .in_cyclic(SystemTime(T), |cx| cx.push_cycle_block(&mut b1, frmw))
            .unwrap();
        if !block {
            assert_eq!(
                m1.control_state(),
                before.control_state(),
                "declined block changed the machine"
            );
            assert_eq!(b1.datagram_count(), usize::from(caller));
            let each = m1
                .in_cyclic(SystemTime(T), |cx| cx.push_cycle_each(&mut b1, frmw))
                .unwrap();
            let each2 = m2
                .in_cyclic(SystemTime(T), |cx| cx.push_cycle_each(&mut b2, frmw))
                .unwrap();
            assert_eq!(each, each2);
        } else {
            assert!(m2
                .in_cyclic(SystemTime(T), |cx| cx.push_cycle_each(&mut b2, frmw))
                .unwrap());
        }
        assert_eq!(b1.datagram_count(), b2.datagram_count());
        assert_eq!(b1.len(), b2.len());
        // A later push chains to the same datagram.
        let r1 = b1.push(Command::Brd, 9, Address::broadcast(0x0130), &[0, 0]);
        let r2 = b2.push(Command::Brd, 9, Address::broadcast(0x0130), &[0, 0]);
        assert_eq!(r1, r2);
        let n1 = b1.finish();
        let n2 = b2.finish();
        assert_eq!(n1, n2);
        assert_eq!(buf1, buf2);
        assert_eq!(m1.control_state(), m2.control_state());
        if let Ok(n) = n1 {
            let eth = EthernetFrame::new_checked(&buf1[..n]).unwrap();
            assert!(eth.ecat_frame().is_ok());
        }
        block
    }

    /// The cycle goes out when its timer is due and not before (a caller's own frame aside).
    #[test]
    fn cycle_waits_for_its_timer() {
        let mut m = cyclic_machine(5, 3, 0, DriftCommand::Frmw, 0x80);
        m.sh.timers.set(Timer::Cycle, SystemTime(T + 1_000));
        let mut buf = std::vec![0u8; 1514];
        assert_eq!(m.poll_transmit(SystemTime(T), &mut buf), None);
        assert!(m.poll_transmit(SystemTime(T + 1_000), &mut buf).is_some());
    }

    /// A cycle that does not fit as one block still goes out, as far as it fits.
    #[test]
    fn cycle_too_big_for_one_block_goes_out_in_part() {
        let mut m = cyclic_machine(40, 29, 0, DriftCommand::Frmw, 0x80);
        let mut buf = std::vec![0u8; 200];
        let len = m
            .poll_transmit(SystemTime(T), &mut buf)
            .expect("a partial cycle");
        assert!(len <= 200 && m.is_awaiting_reply());
        assert!(m
            .sh
            .inflight
            .fresh_len()
            .is_some_and(|n| (3..32).contains(&n)));
    }

    /// A master that did not send for more than `max_lost_cycles` periods enters hold-over
    /// (cause Stall); exactly that long, or less, is no stall.
    #[test]
    fn stalled_master_enters_holdover() {
        let m0 = cyclic_machine(5, 3, 0, DriftCommand::Frmw, 0x80);
        let period = m0.sh.cfg.monitor.cycle_ns;
        let stall = period * u64::from(m0.sh.cfg.monitor.max_lost_cycles);
        for (gap, stalled) in [(stall - period, false), (stall, false), (stall + 1, true)] {
            let mut m = m0.clone();
            let c = m.phase.cyclic_mut().unwrap();
            c.cycles = 1;
            c.sent_at = SystemTime(T);
            let mut buf = std::vec![0u8; 1514];
            let _ = m.poll_transmit(SystemTime(T + gap), &mut buf);
            let cause = m.phase.cyclic_mut().unwrap().holdover.map(|h| h.cause);
            let want = stalled.then_some(HoldoverCause::Stall);
            assert_eq!(cause, want, "gap {gap}");
        }
    }

    /// A fault the cyclic code records ends cyclic operation with that error once it returns.
    #[test]
    fn recorded_fault_ends_cyclic_operation() {
        let mut m = cyclic_machine(5, 3, 0, DriftCommand::Frmw, 0x80);
        assert_eq!(
            m.in_cyclic(SystemTime(T), |cx| cx
                .fail(Error::SlaveLost { station: 0x1001 })),
            Some(())
        );
        assert_ne!(m.state(), State::Cyclic);
        let evs: std::vec::Vec<_> = core::iter::from_fn(|| m.poll_event()).collect();
        assert!(
            evs.contains(&Event::Error(Error::SlaveLost { station: 0x1001 })),
            "{evs:?}"
        );
    }

    /// A frame with no room for the cycle is an error only when the cycle would have had the
    /// frame to itself; a caller's frame that is already full just goes without it.
    #[test]
    fn no_room_for_the_cycle() {
        let mut m = cyclic_machine(5, 3, 0, DriftCommand::Frmw, 0x80);
        let mut tiny = std::vec![0u8; 40];
        assert_eq!(m.poll_transmit(SystemTime(T), &mut tiny), None);
        let evs: std::vec::Vec<_> = core::iter::from_fn(|| m.poll_event()).collect();
        assert!(
            evs.contains(&Event::Error(Error::BufferTooSmall)),
            "{evs:?}"
        );
        let mut m = cyclic_machine(5, 3, 0, DriftCommand::Frmw, 0x80);
        let mut buf = std::vec![0u8; 60];
        let mut b = FrameBuilder::new(&mut buf).unwrap();
        b.push(Command::Lrw, 7, Address::logical(0x1000), &[0; 16])
            .unwrap();
        assert!(!m.poll_transmit_into(SystemTime(T), &mut b));
        let evs: std::vec::Vec<_> = core::iter::from_fn(|| m.poll_event()).collect();
        assert!(
            !evs.contains(&Event::Error(Error::BufferTooSmall)),
            "{evs:?}"
        );
    }

    /// Entering `Cyclic` forgets the list of monitored slaves the block path keeps: a new
    /// bring-up that finds as many slaves as the last one but a different table (a slave with
    /// a system time where there was none, another at a new station) is read as found now.
    #[test]
    fn entering_cyclic_rebuilds_the_monitored_list() {
        use crate::dc::phase::{ActivationStep, Phase};
        let mut m = cyclic_machine(3, 3, 0, DriftCommand::Frmw, 0x80);
        let reads = |m: &mut Machine<48>| {
            let mut buf = [0u8; 1514];
            let n = m.poll_transmit(SystemTime(T), &mut buf).unwrap();
            m.sh.stop_awaiting();
            crate::dc::testing::headers(&buf[..n])
                .into_iter()
                .filter(|h| h.0 == Command::Fprd && h.3 == reg::SYSTEM_TIME_DIFFERENCE)
                .map(|h| h.2)
                .collect::<std::vec::Vec<u16>>()
        };
        assert_eq!(reads(&mut m), [0x1001, 0x1203]);
        m.sh.line.slaves[1].dc = DcKind::Bits64;
        m.sh.line.slaves[2].station = 0x2203;
        m.sh.line.sys_count = 3;
        m.phase = Phase::Activation(ActivationStep::ActivateSync);
        m.enter(State::Cyclic);
        m.sh.timers.set(Timer::Cycle, SystemTime(T));
        assert_eq!(reads(&mut m), [0x1001, 0x1102, 0x2203]);
    }

    /// The round robin starts at its cursor, wrapped into the slave count.
    #[test]
    fn round_robin_start_wraps_into_the_count() {
        let mut m = cyclic_machine(5, 3, 0, DriftCommand::Frmw, 0x80);
        for (rr, start) in [(0u16, 0u16), (4, 4), (5, 0), (7, 2)] {
            m.phase.cyclic_mut().unwrap().rr = rr;
            assert_eq!(
                m.in_cyclic(SystemTime(T), |cx| cx.rr_start()),
                Some(start),
                "rr {rr}"
            );
        }
    }

    /// The FRMW reply gives the reference time only with every system-time slave counted, a
    /// 4-byte one widened around the master's time; a short 0x092C read that nobody answered
    /// names its station as lost, one that was answered does not.
    #[test]
    fn frmw_and_short_diff_replies() {
        let mut m = cyclic_machine(5, 3, 0, DriftCommand::Frmw, 0x80);
        let all = m.sh.line.sys_count;
        let v = T + 12_345;
        m.in_cyclic(SystemTime(T), |cx| {
            cx.on_frmw_reply(SystemTime(T), 8, all, &v.to_le_bytes())
        });
        assert_eq!(m.phase.cyclic_mut().unwrap().ref_time, Some(SystemTime(v)));
        let mut m = cyclic_machine(5, 3, 0, DriftCommand::Frmw, 0x80);
        m.in_cyclic(SystemTime(T), |cx| {
            cx.on_frmw_reply(SystemTime(T), 8, all - 1, &v.to_le_bytes())
        });
        assert_eq!(m.phase.cyclic_mut().unwrap().ref_time, None);
        let low = (v as u32).to_le_bytes();
        m.in_cyclic(SystemTime(T), |cx| {
            cx.on_frmw_reply(SystemTime(T), 4, all, &low)
        });
        assert_eq!(m.phase.cyclic_mut().unwrap().ref_time, Some(SystemTime(v)));
        let diff = |station| Pending {
            command: Command::Fprd,
            index: 9,
            station,
            register: 0x092C,
            len: 4,
            tag: Tag::CycDiff(2),
        };
        m.in_cyclic(SystemTime(T), |cx| {
            cx.on_cyclic_reply(SystemTime(T), diff(0x1203), 1, &[0, 0])
        });
        assert_eq!(m.phase.cyclic_mut().unwrap().replies.lost_station, None);
        m.in_cyclic(SystemTime(T), |cx| {
            cx.on_cyclic_reply(SystemTime(T), diff(0x1203), 0, &[0, 0])
        });
        assert_eq!(
            m.phase.cyclic_mut().unwrap().replies.lost_station,
            Some(0x1203)
        );
    }

    /// The end-of-cycle fault rules: a changed slave count (BRD 0x0130) or system-time count
    /// (BRD 0x092C) or a short FRMW working counter is confirmed over `max_wkc_errors` cycles
    /// and not before; a lost station fails at once, and with a changed count as a topology
    /// change. Nothing fails on a good cycle.
    #[test]
    fn end_of_cycle_fault_rules() {
        let base = cyclic_machine(5, 3, 0, DriftCommand::Frmw, 0x80);
        let (n, sys) = (base.sh.line.count, base.sh.line.sys_count);
        let max = u32::from(base.sh.cfg.monitor.max_wkc_errors);
        let frmw = base.sh.frmw_op(SystemTime(T)).command;
        // (topology WKC, bound WKC, FRMW WKC, lost station) -> cycles to fail, and the error.
        let cases = [
            ((n, sys, sys, None), None),
            (
                (n + 1, sys, sys, None),
                Some((
                    max,
                    Error::TopologyChanged {
                        expected: n,
                        found: n + 1,
                    },
                )),
            ),
            (
                (n, sys - 1, sys, None),
                Some((
                    max,
                    Error::TopologyChanged {
                        expected: n,
                        found: n - 1,
                    },
                )),
            ),
            (
                (n - 1, sys, sys, Some(0x1001)),
                Some((
                    1,
                    Error::TopologyChanged {
                        expected: n,
                        found: n - 1,
                    },
                )),
            ),
            (
                (n, sys, sys, Some(0x1001)),
                Some((1, Error::SlaveLost { station: 0x1001 })),
            ),
            (
                (n, sys, sys - 1, None),
                Some((
                    max,
                    Error::Wkc {
                        command: frmw,
                        station: 0x1001,
                        register: 0x0910,
                        expected: sys,
                        actual: sys - 1,
                    },
                )),
            ),
        ];
        for ((topo, bound, fr, lost), want) in cases {
            let mut m = base.clone();
            let mut failed_after = None;
            for k in 1..=max + 2 {
                let c = m.phase.cyclic_mut().unwrap();
                (
                    c.replies.topo_wkc,
                    c.replies.bound_wkc,
                    c.replies.frmw_wkc,
                    c.replies.lost_station,
                ) = (Some(topo), Some(bound), Some(fr), lost);
                m.in_cyclic(SystemTime(T), |cx| cx.cyclic_complete(SystemTime(T)));
                if m.state() != State::Cyclic {
                    failed_after = Some(k);
                    break;
                }
            }
            let evs: std::vec::Vec<_> = core::iter::from_fn(|| m.poll_event()).collect();
            match want {
                None => assert_eq!(failed_after, None, "{topo} {bound} {fr} {lost:?}: {evs:?}"),
                Some((k, e)) => {
                    assert_eq!(failed_after, Some(k), "{topo} {bound} {fr} {lost:?}");
                    assert!(evs.contains(&Event::Error(e)), "{e:?} not in {evs:?}");
                }
            }
        }
        // The AL status OR is taken only from a BRD 0x0130 some slave answered.
        let mut m = base.clone();
        m.in_cyclic(SystemTime(T), |cx| cx.on_topology_reply(0, &[0x08, 0]));
        assert_eq!(m.phase.cyclic_mut().unwrap().replies.al_status, None);
        m.in_cyclic(SystemTime(T), |cx| cx.on_topology_reply(1, &[0x08, 0]));
        assert_eq!(m.phase.cyclic_mut().unwrap().replies.al_status, Some(0x08));
    }

    /// Lock is lost only when the bound stays above `unlock_ns` for `unlock_cycles` cycles;
    /// a bound exactly at it keeps the lock.
    #[test]
    fn unlock_threshold_is_exclusive() {
        let base = cyclic_machine(5, 3, 0, DriftCommand::Frmw, 0x80);
        let mon = base.sh.cfg.monitor;
        for (bound, lost) in [(mon.unlock_ns, false), (mon.unlock_ns + 1, true)] {
            let mut m = base.clone();
            m.phase.cyclic_mut().unwrap().lock.locked = true;
            for _ in 0..mon.unlock_cycles {
                m.phase.cyclic_mut().unwrap().bound_ns = Some(bound);
                m.in_cyclic(SystemTime(T), |cx| cx.update_lock());
            }
            assert_eq!(
                !m.phase.cyclic_mut().unwrap().lock.locked,
                lost,
                "bound {bound}"
            );
            let evs: std::vec::Vec<_> = core::iter::from_fn(|| m.poll_event()).collect();
            assert_eq!(
                evs.contains(&Event::LockLost { bound_ns: bound }),
                lost,
                "{evs:?}"
            );
        }
    }

    /// A 0x092C read stores the slave's signed Δt (sign-magnitude on the wire) only when
    /// answered and for a slave inside the count; unanswered, it names the station as lost.
    #[test]
    fn diff_reply_stores_or_loses() {
        let mut m = cyclic_machine(5, 3, 0, DriftCommand::Frmw, 0x80);
        let minus_300 = (0x8000_0000u32 | 300).to_le_bytes();
        let crate::dc::shared::Shared { line, .. } = &mut m.sh;
        let mut c = CyclicState::default();
        diff_reply(&mut line.slaves, 5, &mut c, 2, 0x1203, 1, minus_300);
        assert_eq!(line.slaves[2].last_diff_ns, Some(-300));
        diff_reply(&mut line.slaves, 5, &mut c, 5, 0x1606, 1, minus_300);
        assert_eq!(
            line.slaves[5].last_diff_ns, None,
            "position 5 is beyond the count"
        );
        assert_eq!(c.replies.lost_station, None);
        diff_reply(&mut line.slaves, 5, &mut c, 3, 0x1304, 0, minus_300);
        assert_eq!(
            (c.replies.lost_station, line.slaves[3].last_diff_ns),
            (Some(0x1304), None)
        );
    }

    /// Not locked after `lock_timeout_cycles`: reported once, at that cycle, and not while
    /// locked.
    #[test]
    fn not_locked_reported_once_at_the_timeout() {
        let base = cyclic_machine(5, 3, 0, DriftCommand::Frmw, 0x80);
        let timeout = base.sh.cfg.monitor.lock_timeout_cycles;
        let bound = base.sh.cfg.monitor.unlock_ns + 1;
        let run = |locked: bool, cycles: &[u32]| {
            let mut m = base.clone();
            let mut reports = 0;
            for &n in cycles {
                let c = m.phase.cyclic_mut().unwrap();
                (c.lock.locked, c.cycles, c.bound_ns) = (locked, n, Some(bound));
                m.in_cyclic(SystemTime(T), |cx| cx.update_lock());
                reports += core::iter::from_fn(|| m.poll_event())
                    .filter(|e| matches!(e, Event::Error(Error::NotLocked { .. })))
                    .count();
            }
            reports
        };
        assert_eq!(run(false, &[timeout - 1]), 0);
        assert_eq!(run(false, &[timeout - 1, timeout, timeout + 1]), 1);
        assert_eq!(run(true, &[timeout, timeout + 1]), 0);
    }
}
