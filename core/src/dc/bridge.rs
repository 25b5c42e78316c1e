//! Glue between the machine and the pure DC maths (`topology`, `delay`): turns the latches the
//! machine gathered into delays, offsets and the SYNC start time. Nothing here touches the wire.

use crate::dc::config::SyncConfig;
use crate::dc::delay::{self, DelayError};
use crate::dc::error::Error;
use crate::dc::machine::Machine;
use crate::dc::port::{Port, PortSet};
use crate::dc::slave::SlaveInfo;
use crate::dc::topology::{Latches, SlaveSample, Topology, TopologyError};
use crate::time::{PortTime, SystemTime};
use crate::wire::register::reg;

impl<const N: usize> Machine<N> {
    /// REQ-DC-101: one latch round's delays, added to every slave's `delay_sum`.
    ///
    /// Stale-latch detection: a port that DL status calls open but whose receive time did not
    /// change across the trigger was not passed by the frame (bypassed, e.g. a redundancy
    /// link); it is treated as closed. A latching slave with no changed port at all was not
    /// reached, and the round is rejected.
    pub(crate) fn accumulate_round(&mut self) -> Result<(), Error> {
        let count = usize::from(self.count);
        let mut samples = [SlaveSample::default(); N];
        for (s, out) in self.slaves.iter().zip(samples.iter_mut()).take(count) {
            let open = PortSet::from_dl_status(s.dl_status);
            let mut ports = open;
            let latches = if s.dc.has_latches() {
                let mut changed = PortSet::EMPTY;
                for p in Port::PROCESSING_ORDER {
                    let k = p.index();
                    let before = s.times_before.get(k).copied().unwrap_or(0);
                    let after = s.times_after.get(k).copied().unwrap_or(0);
                    if open.contains(p) && before != after {
                        changed = changed.with(p);
                    }
                }
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
                t_diff: self.cfg.t_diff_ns,
            };
        }
        let samples = samples.get(..count).unwrap_or(&[]);
        let topo = Topology::<N>::build(samples).map_err(|e| self.topology_error(e))?;
        let delays = delay::compute(samples, &topo, usize::from(self.reference))
            .map_err(|e| self.delay_error(e))?;
        for (i, s) in self.slaves.iter_mut().enumerate().take(count) {
            if !s.dc.has_system_time() {
                continue;
            }
            let station = s.station;
            let v = delays
                .register_value(i)
                .map_err(|_| Error::Measurement { station })?;
            s.delay_sum = s.delay_sum.saturating_add(u64::from(v));
        }
        Ok(())
    }

    fn station_at(&self, pos: u16) -> u16 {
        self.slave(pos).map_or(0, |s| s.station)
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

    /// REQ-DC-102: offset of every slave with a system time, with its propagation delay folded
    /// in: at the instant the last trigger frame reached slave `i`, the reference's system time
    /// is `t_master + delay_i`, where `t_master` was sampled just before the trigger left. So
    /// `offset_i = t_master + delay_i − epu_i` (mod 2^64; 32-bit slaves keep the low half,
    /// REQ-CONV-004). No hardware loop has to remove the delay afterwards.
    ///
    /// REQ-DC-112: the EPU time is only used if its low 32 bits agree (within
    /// [`EPU_PORT_TOLERANCE_NS`]) with the earliest port time that changed across the trigger,
    /// the port the frame entered through; otherwise the read is garbage and no offset is
    /// derived from it.
    pub(crate) fn compute_offsets(&mut self) -> Result<(), Error> {
        let t = SystemTime(self.latch_time);
        let count = usize::from(self.count);
        for s in self.slaves.iter_mut().take(count) {
            if !s.dc.has_system_time() {
                continue;
            }
            let mut entry: [Option<PortTime>; 4] = [None; 4];
            for (k, e) in entry.iter_mut().enumerate() {
                let (Some(b), Some(a)) = (s.times_before.get(k), s.times_after.get(k)) else {
                    continue;
                };
                if b != a {
                    *e = Some(PortTime(*a));
                }
            }
            let bad = Error::OutOfRange {
                station: s.station,
                register: reg::RECEIVE_TIME_EPU,
            };
            let first = PortTime::earliest(&entry)
                .and_then(|k| entry.get(k).copied().flatten())
                .ok_or(bad)?;
            let epu_low = PortTime(SystemTime(s.epu_time).low32());
            if epu_low.wrapping_since(first).unsigned_abs() > EPU_PORT_TOLERANCE_NS {
                return Err(bad);
            }
            s.offset = t
                .wrapping_add(u64::from(s.delay_ns))
                .0
                .wrapping_sub(s.epu_time);
        }
        Ok(())
    }

    /// REQ-DC-105: the one SYNC0 start time for every slave, from the reference's system time
    /// `raw` read at master time `now`:
    /// `start = ⌈(t_ref + start_delay) / T⌉·T + shift`, with `T` the SYNC0 cycle (SYNC0+SYNC1
    /// with SYNC1 longer than SYNC0 uses the SOEM "true cycle" ⌊(c1/c0)+1⌋·c0), on a grid
    /// anchored at the DC epoch, so the phase is the same on every start (linuxcnc #465).
    /// A 32-bit reference's time is widened around the master's clock (REQ-TIME-006). When the
    /// reference's offset was written in this bring-up its time must be within 1 s of the
    /// master's, otherwise the read is rejected as garbage (no start time is written from it).
    pub(crate) fn compute_sync_start(
        &self,
        now: u64,
        raw: u64,
        r: &SlaveInfo,
        sync: &SyncConfig,
    ) -> Option<u64> {
        let t_ref = if r.dc.time_width() == 8 {
            SystemTime(raw)
        } else {
            SystemTime::extend_low32(u32::try_from(raw).ok()?, SystemTime(now))
        };
        if r.offset_written
            && t_ref.wrapping_since(SystemTime(now)).unsigned_abs() > PLAUSIBLE_REF_DEVIATION_NS
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
        let start = t_ref
            .wrapping_add(sync.start_delay_ns)
            .next_multiple_of(period)?;
        Some(start.wrapping_add(u64::from(sync.shift_ns)).0)
    }
}

/// Largest accepted distance between the reference's system time and the master clock right
/// after the offsets were written. ecdc choice: 1 s (clock rates differ by ≤ 200 ppm, so a real
/// deviation after a few seconds of bring-up is < 1 ms).
const PLAUSIBLE_REF_DEVIATION_NS: u64 = 1_000_000_000;

/// Largest accepted distance between the EPU receive time (0x0918) and the entry port's receive
/// time of the same frame. They are stamped on the same frame at the same port (DS S2-74
/// Tab.99), so they differ only by stamp quantisation. ecdc choice: 1 µs.
const EPU_PORT_TOLERANCE_NS: u32 = 1_000;
