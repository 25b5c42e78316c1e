//! Cyclic operation (REQ-DC-106, REQ-DC-107): every cycle one FRMW to the reference's 0x0910,
//! one BRD 0x092C (upper bound of every |Δt|, and by its WKC a topology check), a few per-slave
//! FPRD 0x092C in round robin, and, when requested, the steps of a delay re-measurement in the
//! room left. Lock and loss of lock use hysteresis on the bound; lost cycles are coasted over
//! up to `max_lost_cycles`; a topology change, a lost slave or a reset reference end in a typed
//! error and a re-initialisation.

use crate::dc::error::Error;
use crate::dc::event::Event;
use crate::dc::machine::Machine;
use crate::dc::request::{le, Op, Pending, Tag};
use crate::dc::state::State;
use crate::time::SystemTime;
use crate::wire::register::{reg, SystemTimeDifference};
use crate::wire::FrameBuilder;

/// Steps of a delay re-measurement running inside cyclic frames.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub(crate) enum Remeasure {
    /// Not running.
    #[default]
    Idle,
    /// FPRD 0x0900 (16 bytes) per latching slave.
    Before,
    /// BWR 0x0900.
    Trigger,
    /// FPRD 0x0900..0x091F per latching slave.
    After,
    /// FPWR 0x0928 per slave with a system time.
    Write,
}

/// Per-cycle bookkeeping.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub(crate) struct CyclicState {
    pub(crate) next_due: u64,
    pub(crate) cycles: u32,
    pub(crate) rr: u16,
    pub(crate) lost_streak: u16,
    pub(crate) wkc_streak: u16,
    pub(crate) topo_streak: u16,
    pub(crate) locked: bool,
    pub(crate) good_streak: u16,
    pub(crate) bad_streak: u16,
    pub(crate) not_locked_reported: bool,
    pub(crate) bound_ns: Option<u32>,
    pub(crate) ref_time: Option<u64>,
    // Results of the cycle in flight.
    pub(crate) frmw_wkc: Option<u16>,
    pub(crate) bound_wkc: Option<u16>,
    pub(crate) topo_wkc: Option<u16>,
    pub(crate) lost_station: Option<u16>,
    pub(crate) sent_at: u64,
    // Delay re-measurement.
    pub(crate) remeasure_requested: bool,
    pub(crate) remeasure: Remeasure,
    pub(crate) rm_cursor: u16,
    pub(crate) rm_sent_to: u16,
    pub(crate) rm_error: Option<Error>,
}

impl<const N: usize> Machine<N> {
    pub(crate) fn cyclic_enter(&mut self) {
        self.cyc = CyclicState::default();
    }

    pub(crate) fn fill_cyclic(
        &mut self,
        now: u64,
        b: &mut FrameBuilder<'_>,
        into_caller: bool,
    ) -> bool {
        if !into_caller && now < self.cyc.next_due {
            return false;
        }
        if self.busy {
            // The previous cycle's datagrams never came back.
            self.cyclic_lost(now);
            if self.state != State::Cyclic {
                return false;
            }
        }
        let period = self.cfg.monitor.cycle_ns;
        let next = self.cyc.next_due.saturating_add(period);
        self.cyc.next_due = if next <= now {
            now.saturating_add(period)
        } else {
            next
        };
        let before = b.datagram_count();
        self.inflight.clear();
        self.cyc.frmw_wkc = None;
        self.cyc.bound_wkc = None;
        self.cyc.topo_wkc = None;
        self.cyc.lost_station = None;
        if !self.push_op(b, self.frmw_op(now), Tag::Frmw) {
            if before == 0 {
                self.push_event(Event::Error(Error::BufferTooSmall));
            }
            return false;
        }
        let _ = self.push_op(b, Op::brd(reg::SYSTEM_TIME_DIFFERENCE, 4), Tag::CycBound);
        let _ = self.push_op(b, Op::brd(reg::AL_STATUS, 2), Tag::CycTopology);
        // Round robin over the slaves with a system time.
        let mut budget = self.cfg.monitor.slaves_per_cycle;
        let mut scanned = 0u16;
        while budget > 0 && scanned < self.count {
            // rr < count except after a re-count; `count > 0` inside the loop.
            let pos = if self.cyc.rr < self.count {
                self.cyc.rr
            } else {
                self.cyc.rr.checked_rem(self.count).unwrap_or(0)
            };
            let next = pos.wrapping_add(1);
            self.cyc.rr = if next >= self.count { 0 } else { next };
            scanned = scanned.saturating_add(1);
            let Some((station, has_time)) =
                self.slave(pos).map(|s| (s.station, s.dc.has_system_time()))
            else {
                break;
            };
            if !has_time {
                continue;
            }
            if !self.push_op(
                b,
                Op::fprd(station, reg::SYSTEM_TIME_DIFFERENCE, 4),
                Tag::CycDiff(pos),
            ) {
                break;
            }
            budget = budget.saturating_sub(1);
        }
        self.fill_remeasure(now, b);
        self.busy = true;
        self.cyc.sent_at = now;
        let timeout = self.cfg.response_timeout_ns.min(period);
        self.inflight.deadline = now.saturating_add(timeout);
        self.cyc.cycles = self.cyc.cycles.saturating_add(1);
        self.stats.cycles = self.stats.cycles.saturating_add(1);
        self.stats.frames_sent = self.stats.frames_sent.saturating_add(1);
        true
    }

    pub(crate) fn on_cyclic_reply(&mut self, now: u64, p: Pending, wkc: u16, data: &[u8]) {
        match p.tag {
            Tag::Frmw => {
                self.cyc.frmw_wkc = Some(wkc);
                if wkc == self.sys_count {
                    if let Some(v) = le(data, usize::from(p.len)) {
                        let t = if p.len == 8 {
                            v
                        } else {
                            let low = u32::try_from(v).unwrap_or(0);
                            SystemTime::extend_low32(low, SystemTime(now)).0
                        };
                        self.cyc.ref_time = Some(t);
                    }
                }
            }
            Tag::CycBound => {
                self.cyc.bound_wkc = Some(wkc);
                if wkc == self.sys_count {
                    if let Some(raw) = le(data, 4).and_then(|v| u32::try_from(v).ok()) {
                        self.cyc.bound_ns = Some(SystemTimeDifference::from_raw(raw).magnitude());
                    }
                }
            }
            Tag::CycTopology => self.cyc.topo_wkc = Some(wkc),
            Tag::CycDiff(pos) => {
                if wkc != 1 {
                    self.cyc.lost_station.get_or_insert(p.station);
                } else if let Some(raw) = le(data, 4).and_then(|v| u32::try_from(v).ok()) {
                    if let Some(s) = self.slave_mut(pos) {
                        s.last_diff_ns =
                            Some(i64::from(SystemTimeDifference::from_raw(raw).to_ns()));
                    }
                }
            }
            Tag::CycRemeasure(i) => self.remeasure_reply(i, p, wkc, data),
            Tag::Item(_) => {}
        }
    }

    /// All of this cycle's datagrams came back: evaluate faults, then lock.
    pub(crate) fn cyclic_complete(&mut self, now: u64) {
        self.cyc.lost_streak = 0;
        let max_wkc = self.cfg.monitor.max_wkc_errors;
        // Every slave counts the BRD of 0x0130, every slave with a system time the BRD of
        // 0x092C: either count changing means slaves appeared or disappeared.
        let topo = match (self.cyc.topo_wkc, self.cyc.bound_wkc) {
            (Some(w), _) if w != self.count => Some(w),
            (_, Some(w)) if w != self.sys_count => {
                Some(self.count.saturating_sub(self.sys_count).saturating_add(w))
            }
            _ => None,
        };
        match topo {
            // A slave gone from its address in the same cycle as the count changed: the
            // topology changed, no need to wait for confirmation.
            Some(found) if self.cyc.lost_station.is_some() => {
                return self.fault(
                    now,
                    Error::TopologyChanged {
                        expected: self.count,
                        found,
                    },
                );
            }
            Some(found) => {
                self.cyc.topo_streak = self.cyc.topo_streak.saturating_add(1);
                if self.cyc.topo_streak >= max_wkc {
                    return self.fault(
                        now,
                        Error::TopologyChanged {
                            expected: self.count,
                            found,
                        },
                    );
                }
            }
            None => self.cyc.topo_streak = 0,
        }
        // A reset or lost reference no longer reads the FRMW; slaves behind a break no longer
        // write it.
        match self.cyc.frmw_wkc {
            Some(w) if w != self.sys_count => {
                self.cyc.wkc_streak = self.cyc.wkc_streak.saturating_add(1);
                if self.cyc.wkc_streak >= max_wkc {
                    let station = self.slave(self.reference).map_or(0, |s| s.station);
                    return self.fault(
                        now,
                        Error::Wkc {
                            command: self.frmw_op(now).command,
                            station,
                            register: reg::SYSTEM_TIME,
                            expected: self.sys_count,
                            actual: w,
                        },
                    );
                }
            }
            _ => self.cyc.wkc_streak = 0,
        }
        if let Some(station) = self.cyc.lost_station {
            // A power-cycled ESC has lost its station address; a broken link drops it too.
            return self.fault(now, Error::SlaveLost { station });
        }
        if let Some(e) = self.cyc.rm_error.take() {
            self.cyc.remeasure = crate::dc::cyclic::Remeasure::Idle;
            return self.fault(now, e);
        }
        self.remeasure_advance(now);
        if self.state != State::Cyclic {
            return;
        }
        self.update_lock();
    }

    fn update_lock(&mut self) {
        let m = self.cfg.monitor;
        let Some(bound) = self.cyc.bound_ns else {
            return;
        };
        if bound <= m.lock_ns {
            self.cyc.good_streak = self.cyc.good_streak.saturating_add(1);
        } else {
            self.cyc.good_streak = 0;
        }
        if bound > m.unlock_ns {
            self.cyc.bad_streak = self.cyc.bad_streak.saturating_add(1);
        } else {
            self.cyc.bad_streak = 0;
        }
        if !self.cyc.locked && self.cyc.good_streak >= m.lock_cycles {
            self.cyc.locked = true;
            let frames = self.stats.frames_sent.saturating_sub(self.frames_at_start);
            self.stats.lock_frames = Some(frames);
            self.push_event(Event::Locked {
                frames,
                bound_ns: bound,
            });
        } else if self.cyc.locked && self.cyc.bad_streak >= m.unlock_cycles {
            self.cyc.locked = false;
            self.cyc.not_locked_reported = false;
            self.cyc.cycles = 0;
            self.push_event(Event::LockLost { bound_ns: bound });
        }
        if !self.cyc.locked
            && !self.cyc.not_locked_reported
            && self.cyc.cycles >= m.lock_timeout_cycles
        {
            self.cyc.not_locked_reported = true;
            self.push_event(Event::Error(Error::NotLocked {
                cycles: self.cyc.cycles,
                bound_ns: bound,
            }));
        }
    }

    /// The cycle in flight is lost: coast, or give up after `max_lost_cycles`.
    pub(crate) fn cyclic_lost(&mut self, now: u64) {
        self.inflight.clear();
        self.busy = false;
        self.stats.lost_cycles = self.stats.lost_cycles.saturating_add(1);
        self.cyc.lost_streak = self.cyc.lost_streak.saturating_add(1);
        // A lost re-measurement step is resent (a lost trigger restarts the measurement).
        self.cyc.rm_sent_to = self.cyc.rm_cursor;
        if self.cyc.remeasure == Remeasure::After {
            self.cyc.remeasure = Remeasure::Before;
            self.cyc.rm_cursor = 0;
            self.cyc.rm_sent_to = 0;
        }
        if self.cyc.lost_streak >= self.cfg.monitor.max_lost_cycles {
            self.fault(
                now,
                Error::Timeout {
                    state: State::Cyclic,
                },
            );
        }
    }
}
