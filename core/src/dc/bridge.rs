//! Glue between the machine and the pure DC maths (`topology`, `delay`, `offset`, `sync`): builds
//! their inputs from the registers the machine read and maps their errors to the machine's typed
//! errors. Every formula lives in those modules, so the machine and the proofs use one copy of
//! it. Nothing here touches the wire.

use crate::dc::config::SyncConfig;
use crate::dc::delay::{self, DelayError};
use crate::dc::error::Error;
use crate::dc::offset::{self, ClockWidth};
use crate::dc::port::{Port, PortSet};
use crate::dc::shared::Shared;
use crate::dc::slave::{DcKind, SlaveInfo};
use crate::dc::sync;
use crate::dc::topology::{Latches, Node, SlaveSample, TopologyError};
use crate::num::low32;
use crate::time::{PortTime, SystemTime};
use crate::wire::register::reg;

impl<const N: usize> Shared<N> {
    /// REQ-DC-101, REQ-DC-012..018: the topology (`scratch.topo`) and exact delays
    /// (`scratch.round`) of the latest latch round, built in the machine's working tables.
    ///
    /// Stale-latch detection: a port that DL status calls open but whose receive time did not
    /// change across the trigger was not passed by the frame (bypassed, e.g. a redundancy
    /// link); it is treated as closed. A latching slave with no changed port at all was not
    /// reached, and the round is rejected.
    fn latch_round_delays(&mut self) -> Result<(), Error> {
        let count = usize::from(self.line.count);
        for (s, out) in self
            .line
            .slaves
            .iter()
            .zip(self.scratch.samples.iter_mut())
            .take(count)
        {
            let open = PortSet::from_dl_status(s.dl_status);
            let mut ports = open;
            let latches = if s.dc.has_latches() {
                let changed = open.passed(&s.times_before, &s.times_after);
                if changed.is_empty() {
                    return Err(Error::Measurement { station: s.station });
                }
                ports = changed;
                Some(Latches::from_raw(s.times_after, s.epu_time))
            } else {
                None
            };
            *out = SlaveSample {
                ports,
                latches,
                t_diff: s.t_diff_ns, // REQ-DC-015, REQ-DC-126
            };
        }
        let sc = &mut self.scratch;
        let samples = sc.samples.get(..count).unwrap_or(&[]);
        let built = sc.topo.build_in_place(samples, &mut sc.stack);
        built.map_err(|e| self.topology_error(e))?;
        let sc = &mut self.scratch;
        let samples = sc.samples.get(..count).unwrap_or(&[]);
        let reference = usize::from(self.line.reference);
        let computed =
            delay::compute_in_place(samples, &sc.topo, reference, &mut sc.delay, &mut sc.round);
        computed.map_err(|e| self.delay_error(e))
    }

    /// REQ-DC-101, REQ-DC-019: adds the latest latch round of the bring-up measurement to the
    /// exact sum of its rounds (`self.latch.sum`, restarted at round 0) with
    /// [`Delays::accumulate`](delay::Delays::accumulate), so the mean over the K rounds is
    /// rounded once, not once per round. This round's topology stays in `scratch.topo` (its
    /// entry ports are needed for the offsets). A failed sum is dropped, so the next round
    /// starts a new one.
    pub(crate) fn add_latch_round(&mut self) -> Result<(), Error> {
        self.latch_round_delays()?;
        if self.latch.round > 0 && self.latch.sum.has_rounds() {
            if let Err(e) = self.latch.sum.accumulate(&self.scratch.round) {
                self.latch.sum.clear();
                return Err(self.delay_error(e));
            }
        } else {
            self.latch.sum.copy_from(&self.scratch.round);
        }
        Ok(())
    }

    /// REQ-DC-107: one latch round (a re-measurement during cyclic operation) into every
    /// slave's `delay_sum`: its 0x0928 value, rounded once. Bring-up rounds are averaged
    /// exactly by [`Self::add_latch_round`] instead.
    pub(crate) fn accumulate_round(&mut self) -> Result<(), Error> {
        self.latch_round_delays()?;
        let delays = &self.scratch.round;
        for (i, s) in self
            .line
            .slaves
            .iter_mut()
            .enumerate()
            .take(usize::from(self.line.count))
        {
            if !s.dc.has_system_time() {
                continue;
            }
            let station = s.station;
            s.delay_sum = u64::from(
                delays
                    .register_value(i)
                    .map_err(|_| Error::Measurement { station })?,
            );
        }
        Ok(())
    }

    fn station_at(&self, pos: u16) -> u16 {
        self.line.slave(pos).map_or(0, |s| s.station)
    }

    fn topology_error(&self, e: TopologyError) -> Error {
        let pos = match e {
            TopologyError::NoOpenPort { slave }
            | TopologyError::NoFreePort { slave }
            | TopologyError::DanglingPort { slave, .. }
            | TopologyError::LatchOrder { slave } => Some(slave),
            _ => None,
        };
        Error::Measurement {
            station: pos.map_or(0, |p| self.station_at(p)),
        }
    }

    fn delay_error(&self, e: DelayError) -> Error {
        let pos = match e {
            DelayError::BadReference { slave }
            | DelayError::NoUpstreamDc { slave }
            | DelayError::NonDcJunction { slave }
            | DelayError::Inconsistent { slave }
            | DelayError::NegativeHop { slave }
            | DelayError::Overflow { slave }
            | DelayError::BeforeReference { slave } => Some(slave),
            _ => None,
        };
        Error::Measurement {
            station: pos.map_or(0, |p| self.station_at(p)),
        }
    }

    /// REQ-DC-102, REQ-DC-021..023: the offset of every slave with a system time, with its
    /// propagation delay (`delay_ns`, the 0x0928 value) folded in, from the latches of the last
    /// round and its topology (`scratch.topo`). The frame entered slave `s` at local time
    /// [`offset::entry_local_time`] — 0x0918 moved back to the entry port's stamp, which is not
    /// 0x0918 itself when the slave is entered through port 1, 2 or 3 — and the offset is
    /// [`offset::initial_offset`] of the slave's clock width.
    ///
    /// REQ-DC-112: no offset is derived from an implausible EPU time ([`epu_plausible`]).
    pub(crate) fn compute_offsets(&mut self) -> Result<(), Error> {
        let topo = &self.scratch.topo;
        let master = self.latch.trigger_time;
        let count = usize::from(self.line.count);
        for (i, s) in self.line.slaves.iter_mut().enumerate().take(count) {
            let Some(width) = clock_width(s.dc) else {
                continue;
            };
            let bad = Error::OutOfRange {
                station: s.station,
                register: reg::RECEIVE_TIME_EPU,
            };
            let node = topo.node(i).ok_or(bad)?;
            let latches = Latches::from_raw(s.times_after, s.epu_time);
            if !epu_plausible(&latches, node) {
                return Err(bad);
            }
            let entry_local = offset::entry_local_time(&latches, node.entry);
            s.entry_local = entry_local;
            s.running_offset = None;
            s.offset =
                offset::initial_offset(master, i64::from(s.delay_ns), entry_local, width).as_u64();
        }
        Ok(())
    }

    /// REQ-DC-131: when slaves keep their offset because they may be running (REQ-DC-103),
    /// the offsets to be written are re-anchored on the running domain's time instead of the
    /// master's clock. The anchor is the reference if it runs, else the first running slave
    /// with a system time: its system time when the latch frame entered it, `entry_local +
    /// 0x0920`, less its delay behind the reference, is the reference's system time `m` when
    /// the frame passed the reference (the domain's time at the latch). A 32-bit anchor's time
    /// is widened to the 64-bit value nearest the master's clock (REQ-DC-051). Every writable
    /// slave then gets [`offset::initial_offset`] of `m`, as [`Self::compute_offsets`] gives it
    /// of the master's time. No running slave: nothing changes.
    pub(crate) fn anchor_on_running_domain(&mut self) -> Result<(), Error> {
        let count = usize::from(self.line.count);
        let slaves = self.line.slaves.get(..count).unwrap_or(&[]);
        let running = |s: &&SlaveInfo| s.running_offset.is_some() && !s.may_step_offset();
        let anchor = match self.line.slave(self.line.reference).filter(running) {
            Some(r) => Some(*r),
            None => slaves.iter().find(running).copied(),
        };
        let Some(a) = anchor else {
            self.line.domain_shift = 0;
            return Ok(());
        };
        let (Some(width), Some(read)) = (clock_width(a.dc), a.running_offset) else {
            return Err(Error::OutOfRange {
                station: a.station,
                register: reg::SYSTEM_TIME_OFFSET,
            });
        };
        let master = self.latch.trigger_time;
        let at_latch = a
            .entry_local
            .wrapping_add(read)
            .wrapping_sub(u64::from(a.delay_ns));
        let m = sync::reference_now(at_latch, width, master);
        let shift = m.wrapping_since(master);
        if shift.unsigned_abs() > MAX_DOMAIN_SHIFT_NS {
            // REQ-DC-112: not a drifted domain but a 0x0920 that was never set by a master of
            // this epoch (or garbage): nothing is derived from it.
            self.line.domain_shift = 0;
            return Ok(());
        }
        self.line.domain_shift = shift;
        for s in self.line.slaves.iter_mut().take(count) {
            let Some(width) = clock_width(s.dc) else {
                continue;
            };
            if s.may_step_offset() {
                s.offset =
                    offset::initial_offset(m, i64::from(s.delay_ns), s.entry_local, width).as_u64();
            }
        }
        Ok(())
    }

    /// REQ-DC-105: the one SYNC0 start time for every slave, from the reference's system time
    /// `raw` read at master time `now` (a 32-bit reference's time widened around the master's
    /// clock, REQ-DC-051), by [`sync::start_time`] (REQ-DC-050): the first multiple of the
    /// SYNC0 cycle `T` at or after `t_ref + start_delay`, plus the shift, on a grid anchored at
    /// the DC epoch. SYNC0+SYNC1 with SYNC1 longer than SYNC0 uses the SOEM "true cycle"
    /// ⌊(c1/c0)+1⌋·c0 as `T`.
    ///
    /// `None` (the caller's typed `OutOfRange` error; nothing is written) when the start is not
    /// strictly inside `(t_ref, t_ref + 2^31 ns)` (32-bit slaves and the ESC's near-future
    /// window would take it as a time in the past), when it overflows, or when the reference's
    /// offset was written in this bring-up and its time is more than 1 s from the master's
    /// (a garbage read).
    pub(crate) fn compute_sync_start(
        &self,
        now: SystemTime,
        raw: u64,
        r: &SlaveInfo,
        sync: &SyncConfig,
    ) -> Option<SystemTime> {
        let width = clock_width(r.dc)?;
        // REQ-DC-131: the domain runs `domain_shift` away from the master's clock.
        let expected = now.wrapping_add_signed(self.line.domain_shift);
        let t_ref = sync::reference_now(raw, width, expected);
        if r.offset_written
            && t_ref.wrapping_since(expected).unsigned_abs() > PLAUSIBLE_REF_DEVIATION_NS
        {
            return None;
        }
        let c0 = u64::from(sync.sync0_cycle_ns);
        let c1 = u64::from(sync.sync1_cycle_ns);
        let period = if c1 > c0 {
            c1.checked_div(c0)?.checked_add(1)?.checked_mul(c0)?
        } else {
            c0
        };
        sync::start_time(t_ref, sync.start_delay_ns, period, i64::from(sync.shift_ns)).ok()
    }
}

/// The width of a slave's system time, `None` for slaves without one.
fn clock_width(dc: DcKind) -> Option<ClockWidth> {
    match dc {
        DcKind::Bits64 => Some(ClockWidth::Bits64),
        DcKind::Bits32 => Some(ClockWidth::Bits32),
        DcKind::None | DcKind::DelayOnly => None,
    }
}

/// REQ-DC-112: whether the EPU receive time 0x0918 belongs to the latched frame. The EPU
/// follows port 0's receiver (REQ-DC-010), so when the frame passed port 0 (whatever port it
/// entered through) 0x0918 and port 0's stamp mark the same frame at the same place and agree
/// within [`EPU_PORT_TOLERANCE_NS`]. With port 0 closed the frame loops back into the EPU
/// between the entry port and the last port it visits, so 0x0918 must lie in that span.
fn epu_plausible(latches: &Latches, node: &Node) -> bool {
    let epu = PortTime(low32(latches.epu));
    if node.ports.contains(Port::P0) {
        return epu.wrapping_since(latches.at(Port::P0)).unsigned_abs() <= EPU_PORT_TOLERANCE_NS;
    }
    let entry = latches.at(node.entry);
    let since_entry = i64::from(epu.wrapping_since(entry));
    let span = i64::from(latches.at(node.last_port()).wrapping_since(entry));
    let tol = i64::from(EPU_PORT_TOLERANCE_NS);
    since_entry >= tol.saturating_neg() && since_entry <= span.saturating_add(tol)
}

/// Largest accepted distance between the reference's system time and the master clock right
/// after the offsets were written. ecdc choice: 1 s (clock rates differ by ≤ 200 ppm, so a real
/// deviation after a few seconds of bring-up is < 1 ms).
const PLAUSIBLE_REF_DEVIATION_NS: u64 = 1_000_000_000;

/// Largest distance between a running domain's time and the master's clock that REQ-DC-131
/// joins. ecdc choice: one day (clock rates differ by ≤ 200 ppm, so that is over 13 years of
/// uptime since the domain was last set to the master's time).
const MAX_DOMAIN_SHIFT_NS: u64 = 86_400_000_000_000;

/// Largest accepted distance between the EPU receive time (0x0918) and port 0's receive time
/// of the same frame. They are stamped on the same frame at the same place (DS S2-74 Tab.99),
/// so they differ only by stamp quantisation. ecdc choice: 1 µs.
const EPU_PORT_TOLERANCE_NS: u32 = 1_000;

#[cfg(test)]
mod tests {
    //! The machine's path from hand-made latch registers to 0x0928/0x0920/0x0990 values, for
    //! cases the emulator cannot produce (its slaves are always cabled upstream on port 0).

    use super::*;
    use crate::dc::{Config, Machine, State};

    /// Master time sampled before the trigger (REQ-DC-002).
    const M: u64 = 800_000_000_000_000_000;

    /// `compute_sync_start` on raw nanoseconds.
    fn sync_start_at<const N: usize>(
        m: &Machine<N>,
        now: u64,
        raw: u64,
        r: &SlaveInfo,
        sync: &SyncConfig,
    ) -> Option<u64> {
        m.sh.compute_sync_start(SystemTime(now), raw, r, sync)
            .map(SystemTime::as_nanos)
    }
    /// DL status bits: port `n` open = bit 9+2n set (communication) and bit 8+2n clear.
    use crate::dc::testing::{closed, open};

    /// Two 64-bit DC slaves; slave 0 (the reference) with the given DL status, slave 1 a line
    /// end on port 0. `times_before` differ from every value used after the trigger.
    fn pair(dl_0: u16) -> Machine<4> {
        let mut m = Machine::<4>::new(Config::default()).unwrap();
        m.sh.line.count = 2;
        m.sh.line.reference = 0;
        m.sh.line.sys_count = 2;
        let dl_1 = open(0) | closed(1) | closed(2) | closed(3);
        for (i, dl) in [dl_0, dl_1].into_iter().enumerate() {
            let s = &mut m.sh.line.slaves[i];
            s.station = 0x1001 + i as u16;
            s.dc = DcKind::Bits64;
            s.dl_status = dl;
            s.times_before = [1, 1, 1, 1];
        }
        m.sh.latch.trigger_time = SystemTime(M);
        m
    }

    /// Runs the last step of the bring-up measurement (REQ-DC-101) on the latches in place.
    fn finish_round(m: &mut Machine<4>) -> Result<State, Error> {
        m.phase = m.phase.enter(State::LatchReadAfter);
        m.measure_done()
    }

    /// REQ-DC-022, REQ-DC-021, REQ-DC-013: slave 0 is entered through port 3 and reaches slave 1
    /// through port 0, so the frame passes slave 0's EPU (and 0x0918 is stamped) only on its
    /// way back, `x` ns after it entered. The offset must use the entry time, not 0x0918: at the
    /// entry instant slave 0's system time is M, and slave 1's is M + its delay when the frame
    /// reaches it. The old bridge used 0x0918 directly (slave 0 then `x` ns behind) or, for
    /// `x` > 1 µs, rejected the plausible EPU time.
    // verifies: REQ-DC-013, REQ-DC-021, REQ-DC-022
    #[test]
    fn offset_uses_entry_port_not_epu_when_entered_on_port_3() {
        for x in [800u32, 1_210, 250_000] {
            let mut m = pair(open(0) | closed(1) | closed(2) | open(3));
            m.sh.cfg.latch_rounds = 1;
            let t3 = 10_000u32;
            let t0 = t3 + x; // back from slave 1 into port 0, then the EPU
            let epu_0 = 0x5_0000_0000u64 + u64::from(t0);
            let epu_1 = 0x9_0000_0000u64 + 50_000;
            m.sh.line.slaves[0].times_after = [t0, 1, 1, t3];
            m.sh.line.slaves[0].epu_time = epu_0;
            m.sh.line.slaves[1].times_after = [50_000, 1, 1, 1];
            m.sh.line.slaves[1].epu_time = epu_1;
            assert_eq!(finish_round(&mut m), Ok(State::ReadAlStatus), "x = {x}");
            let delay = x / 2; // slave 1 is a line end: half the excursion behind port 0
            assert_eq!(m.sh.line.slaves[0].delay_ns, 0);
            assert_eq!(m.sh.line.slaves[1].delay_ns, delay);
            let entry_0 = epu_0 - u64::from(x);
            assert_eq!(
                entry_0.wrapping_add(m.sh.line.slaves[0].offset),
                M,
                "x = {x}"
            );
            assert_eq!(
                epu_1.wrapping_add(m.sh.line.slaves[1].offset),
                M + u64::from(delay),
                "x = {x}"
            );
        }
    }

    /// REQ-DC-112: with entry on port 3 the EPU time is checked against port 0's stamp (where
    /// the EPU sits), not the entry port's; a 0x0918 far from it is rejected, no offset derived.
    // verifies: REQ-DC-112
    #[test]
    fn garbage_epu_rejected_when_entered_on_port_3() {
        let mut m = pair(open(0) | closed(1) | closed(2) | open(3));
        m.sh.cfg.latch_rounds = 1;
        m.sh.line.slaves[0].times_after = [12_000, 1, 1, 10_000];
        m.sh.line.slaves[0].epu_time = 0x5_0000_0000 + 10_000; // the entry stamp, not port 0's
        m.sh.line.slaves[1].times_after = [50_000, 1, 1, 1];
        m.sh.line.slaves[1].epu_time = 50_000;
        assert_eq!(
            finish_round(&mut m),
            Err(Error::OutOfRange {
                station: 0x1001,
                register: reg::RECEIVE_TIME_EPU
            })
        );
        assert_eq!(m.sh.line.slaves[0].offset, 0);
    }

    /// REQ-DC-019: K rounds are averaged from their exact doubled sums, rounded once. Round
    /// trips 1209, 1209, 1208, 1208 ns give 604.25 ns → 604; rounding each round first
    /// (605, 605, 604, 604) and averaging those gives 605.
    // verifies: REQ-DC-019
    #[test]
    fn rounds_averaged_exactly() {
        let mut m = pair(open(0) | open(1) | closed(2) | closed(3));
        m.sh.cfg.latch_rounds = 4;
        for (k, x) in (0u32..).zip([1_209, 1_209, 1_208, 1_208]) {
            latch_round(&mut m, k, x);
            let next = if k < 3 {
                State::LatchReadBefore
            } else {
                State::ReadAlStatus
            };
            assert_eq!(finish_round(&mut m), Ok(next));
        }
        assert_eq!(m.sh.line.slaves[1].delay_ns, 604);
        assert!(!m.sh.latch.sum.has_rounds(), "the sum is consumed");
    }

    /// REQ-DC-112: a delay of exactly `max_delay_ns` is written; one nanosecond more is out of
    /// range and names the slave and 0x0928.
    // verifies: REQ-DC-112
    #[test]
    fn delay_up_to_max_delay_is_accepted() {
        for (max, result) in [
            (604, Ok(State::ReadAlStatus)),
            (
                603,
                Err(Error::OutOfRange {
                    station: 0x1002,
                    register: 0x0928,
                }),
            ),
        ] {
            let mut m = pair(open(0) | open(1) | closed(2) | closed(3));
            m.sh.cfg.latch_rounds = 1;
            m.sh.cfg.max_delay_ns = max;
            latch_round(&mut m, 0, 1_208);
            assert_eq!(finish_round(&mut m), result, "max_delay_ns {max}");
        }
    }

    /// REQ-DC-050, REQ-DC-105: a start that would lie 2^31 ns or more ahead of the reference's
    /// time is refused (the caller turns it into `OutOfRange`), never written.
    // verifies: REQ-DC-050, REQ-DC-105
    #[test]
    fn sync_start_outside_window_refused() {
        let m = Machine::<4>::new(Config::default()).unwrap();
        let now = M;
        for dc in [DcKind::Bits64, DcKind::Bits32] {
            let r = SlaveInfo {
                dc,
                ..SlaveInfo::default()
            };
            let raw = if dc == DcKind::Bits64 {
                now
            } else {
                u64::from(low32(now))
            };
            let ok = SyncConfig::default();
            let start = sync_start_at(&m, now, raw, &r, &ok).unwrap();
            let lead = start - now;
            assert!(lead >= ok.start_delay_ns && lead < 1 << 31, "{lead}");
            assert_eq!(start % u64::from(ok.sync0_cycle_ns), 0);
            let far = SyncConfig {
                start_delay_ns: 3_000_000_000,
                ..ok
            };
            assert_eq!(sync_start_at(&m, now, raw, &r, &far), None);
            // SYNC1 "true cycle" of 3 × 0.9 s pushes the first grid point past 2^31 ns.
            let long = SyncConfig {
                sync0_cycle_ns: 900_000_000,
                sync1_cycle_ns: 2_000_000_000,
                ..ok
            };
            let now_on_grid = 2_700_000_000 * 300_000_000;
            let raw = if dc == DcKind::Bits64 {
                now_on_grid + 1
            } else {
                u64::from(low32(now_on_grid + 1))
            };
            assert_eq!(sync_start_at(&m, now_on_grid, raw, &r, &long), None);
        }
    }

    /// Slave 0 (the reference) runs with 0x0920 = `off0` read back, slave 1 is in INIT; both
    /// entered through port 0 at the given local times, slave 1 `delay` ns behind.
    fn running_reference(
        dc0: DcKind,
        off0: u64,
        entry0: u64,
        entry1: u64,
        delay: u32,
    ) -> Machine<4> {
        let mut m = pair(open(0) | open(1) | closed(2) | closed(3));
        m.sh.line.slaves[0].dc = dc0;
        m.sh.line.slaves[0].al_status = Some(0x08);
        m.sh.line.slaves[0].running_offset = Some(off0);
        m.sh.line.slaves[0].entry_local = entry0;
        m.sh.line.slaves[1].al_status = Some(0x01);
        m.sh.line.slaves[1].entry_local = entry1;
        m.sh.line.slaves[1].delay_ns = delay;
        m
    }

    /// REQ-DC-131: with the reference running 3 ms ahead of the master's clock, the INIT slave
    /// is written to the reference's time at the latch plus its delay, not to the master's
    /// time; the running slave's offset is left as read.
    // verifies: REQ-DC-131
    #[test]
    fn writable_slave_anchored_on_running_reference() {
        let ahead = 3_000_000u64;
        let entry0 = 0x7_0000_1234u64;
        let entry1 = 0x2_9000_0000u64;
        let off0 = (M + ahead).wrapping_sub(entry0);
        let mut m = running_reference(DcKind::Bits64, off0, entry0, entry1, 700);
        m.sh.anchor_on_running_domain().unwrap();
        assert_eq!(m.sh.line.domain_shift, ahead as i64);
        assert_eq!(
            entry1.wrapping_add(m.sh.line.slaves[1].offset),
            M + ahead + 700
        );
        // No running slave: the offsets stay those of the master's time.
        let mut m = running_reference(DcKind::Bits64, off0, entry0, entry1, 700);
        m.sh.line.slaves[0].al_status = Some(0x02);
        m.sh.line.slaves[1].offset = 5;
        m.sh.anchor_on_running_domain().unwrap();
        assert_eq!((m.sh.line.domain_shift, m.sh.line.slaves[1].offset), (0, 5));
        // A running slave whose 0x0920 was never set (its system time is its local time) is
        // not a domain to join.
        let mut m = running_reference(DcKind::Bits64, 0, entry0, entry1, 700);
        m.sh.line.slaves[1].offset = 5;
        m.sh.anchor_on_running_domain().unwrap();
        assert_eq!((m.sh.line.domain_shift, m.sh.line.slaves[1].offset), (0, 5));
    }

    /// REQ-DC-131, REQ-DC-051: a 32-bit running reference's time is widened around the
    /// master's time, so a 64-bit slave gets the full 64-bit domain time, also when the domain
    /// runs behind the master's clock across a 2^32 boundary.
    // verifies: REQ-DC-131
    #[test]
    fn thirty_two_bit_anchor_widened_around_master() {
        let behind = 5_000_000u64;
        let entry0 = 0x1234_5678u64;
        let entry1 = 0x3_0000_0000u64;
        for master in [M, (M | 0xFFFF_FFFF) - 1_000_000 + behind] {
            let domain = master - behind;
            let off0 = u64::from(low32(domain.wrapping_sub(entry0)));
            let mut m = running_reference(DcKind::Bits32, off0, entry0, entry1, 300);
            m.sh.latch.trigger_time = SystemTime(master);
            m.sh.anchor_on_running_domain().unwrap();
            assert_eq!(m.sh.line.domain_shift, -(behind as i64));
            assert_eq!(
                entry1.wrapping_add(m.sh.line.slaves[1].offset),
                domain + 300
            );
        }
    }

    /// REQ-DC-131: with the domain 1.5 s ahead of the master's clock the SYNC start's
    /// plausibility bound is checked against the domain, so a reference written onto it is
    /// accepted and one on the master's time refused.
    // verifies: REQ-DC-131, REQ-DC-105
    #[test]
    fn sync_start_plausibility_follows_the_domain() {
        let mut m = Machine::<4>::new(Config::default()).unwrap();
        let r = SlaveInfo {
            dc: DcKind::Bits64,
            offset_written: true,
            ..SlaveInfo::default()
        };
        let sync = SyncConfig::default();
        let ahead = 1_500_000_000u64;
        assert_eq!(sync_start_at(&m, M, M + ahead, &r, &sync), None);
        m.sh.line.domain_shift = ahead as i64;
        let start = sync_start_at(&m, M, M + ahead, &r, &sync).unwrap();
        assert!(start > M + ahead && start < M + ahead + (1 << 31));
        assert_eq!(sync_start_at(&m, M, M, &r, &sync), None);
    }

    /// Sets a valid latch round on `pair(open(0) | open(1) | ..)`: slave 1 `x / 2` ns behind.
    fn latch_round(m: &mut Machine<4>, k: u32, x: u32) {
        let t0 = 10_000 + 100_000 * k;
        m.sh.line.slaves[0].times_after = [t0, t0 + x, 1, 1];
        m.sh.line.slaves[0].epu_time = u64::from(t0);
        m.sh.line.slaves[1].times_after = [50_000 + 100_000 * k, 1, 1, 1];
        m.sh.line.slaves[1].epu_time = u64::from(m.sh.line.slaves[1].times_after[0]);
    }

    /// REQ-DC-019: round 0 starts the sum afresh, even over a stale one; a later round adds to
    /// the sum, or starts it again when a failed sum was dropped.
    // verifies: REQ-DC-019
    #[test]
    fn latch_rounds_start_and_add() {
        let mut m = pair(open(0) | open(1) | closed(2) | closed(3));
        latch_round(&mut m, 0, 1_200);
        m.sh.latch.round = 0;
        m.sh.add_latch_round().unwrap();
        assert_eq!(m.sh.latch.sum.rounds(), 1);
        latch_round(&mut m, 1, 1_202);
        m.sh.latch.round = 1;
        m.sh.add_latch_round().unwrap();
        assert_eq!(m.sh.latch.sum.rounds(), 2);
        assert_eq!(m.sh.latch.sum.exact(1), Some((1_200 + 1_202, 4)));
        // Round 0 of a new measurement over the stale sum: a new sum.
        m.sh.latch.round = 0;
        m.sh.add_latch_round().unwrap();
        assert_eq!(m.sh.latch.sum.exact(1), Some((1_202, 2)));
        // A later round after the sum was dropped: a new sum too.
        m.sh.latch.sum.clear();
        m.sh.latch.round = 3;
        m.sh.add_latch_round().unwrap();
        assert_eq!(m.sh.latch.sum.exact(1), Some((1_202, 2)));
    }

    /// A measurement fault names the station of the slave at fault (topology and delay
    /// errors), or 0 when the error concerns no slave.
    #[test]
    fn measurement_faults_name_the_station() {
        let m = pair(open(0) | open(1) | closed(2) | closed(3));
        let t = m.sh.topology_error(TopologyError::NoOpenPort { slave: 1 });
        assert_eq!(t, Error::Measurement { station: 0x1002 });
        let t = m.sh.topology_error(TopologyError::Capacity);
        assert_eq!(t, Error::Measurement { station: 0 });
        let d = m.sh.delay_error(DelayError::NegativeHop { slave: 1 });
        assert_eq!(d, Error::Measurement { station: 0x1002 });
        let d = m.sh.delay_error(DelayError::Mismatch);
        assert_eq!(d, Error::Measurement { station: 0 });
        // A round whose hop to slave 1 comes out negative (t_Diff larger than the round trip):
        // slave 1's station in the error.
        let mut m = pair(open(0) | open(1) | closed(2) | closed(3));
        latch_round(&mut m, 0, 1_200);
        m.sh.line.slaves[0].t_diff_ns = -10_000;
        let e = m.sh.add_latch_round();
        assert_eq!(e, Err(Error::Measurement { station: 0x1002 }), "{e:?}");
    }

    /// REQ-DC-112 with port 0 closed: 0x0918 must lie between the entry stamp and the last
    /// port's, each end widened by the tolerance, and nowhere else.
    // verifies: REQ-DC-112
    #[test]
    fn epu_inside_the_loop_when_port_0_is_closed() {
        let node = Node {
            entry: Port::P3,
            ports: PortSet::EMPTY.with(Port::P3).with(Port::P1),
            parent: None,
            children: [None; 4],
        };
        let (entry, last) = (10_000u32, 12_000u32);
        let tol = EPU_PORT_TOLERANCE_NS;
        let at = |epu: u32| {
            epu_plausible(
                &Latches::from_raw([0, last, 0, entry], u64::from(epu)),
                &node,
            )
        };
        assert!(at(entry) && at(last) && at(11_000));
        assert!(at(entry - tol) && at(last + tol));
        assert!(!at(entry - tol - 1) && !at(last + tol + 1));
    }

    /// REQ-DC-105 boundaries: SYNC1 equal to SYNC0 keeps the SYNC0 grid (only a longer SYNC1
    /// makes the "true cycle"); a reference exactly 1 s from the master's time is still
    /// believed, 1 ns more is not.
    // verifies: REQ-DC-105
    #[test]
    fn sync_start_boundaries() {
        let m = Machine::<4>::new(Config::default()).unwrap();
        let r = SlaveInfo {
            dc: DcKind::Bits64,
            ..SlaveInfo::default()
        };
        let now = M + 300_000;
        let same = SyncConfig {
            sync0_cycle_ns: 1_000_000,
            sync1_cycle_ns: 1_000_000,
            start_delay_ns: 0,
            shift_ns: 0,
            ..SyncConfig::default()
        };
        let start = sync_start_at(&m, now, now, &r, &same).unwrap();
        assert_eq!(
            start,
            (now / 1_000_000 + 1) * 1_000_000,
            "next 1 ms, not 2 ms, grid point"
        );
        assert_ne!(start % 2_000_000, 0);
        let written = SlaveInfo {
            offset_written: true,
            ..r
        };
        let one_s = now + 1_000_000_000;
        assert!(m
            .sh
            .compute_sync_start(SystemTime(now), one_s, &written, &same)
            .is_some());
        assert!(m
            .sh
            .compute_sync_start(SystemTime(now), one_s + 1, &written, &same)
            .is_none());
    }

    /// REQ-DC-131/112: a running domain up to one day from the master's clock is joined, one
    /// nanosecond more is taken for an unset 0x0920 and ignored.
    // verifies: REQ-DC-131
    #[test]
    fn running_domain_joined_up_to_one_day() {
        let (entry0, entry1) = (0x7_0000_1234u64, 0x2_9000_0000u64);
        for (ahead, joined) in [
            (MAX_DOMAIN_SHIFT_NS, true),
            (MAX_DOMAIN_SHIFT_NS + 1, false),
        ] {
            let off0 = (M + ahead).wrapping_sub(entry0);
            let mut m = running_reference(DcKind::Bits64, off0, entry0, entry1, 700);
            m.sh.anchor_on_running_domain().unwrap();
            let want = if joined { ahead as i64 } else { 0 };
            assert_eq!(m.sh.line.domain_shift, want, "{ahead}");
        }
    }
}
