//! SYNC0/SYNC1 programming (REQ-DC-105): one start time for all slaves, computed from the
//! reference's 64-bit system time (a 32-bit reference's time is extended around the master
//! clock) on a grid anchored at the DC epoch plus the shift; 0x0981 cleared first; 0x0990 with
//! the slave's exact width, 0x09A0 and 0x09A4 with 4 bytes; activation by the 2-byte
//! AssignActivate word at 0x0980. Running slaves (SAFEOP/OP) keep their SYNC unit untouched.
//! 0x0982 (pulse length) is never written (REQ-DC-035); every slave gets the same start, from
//! one reference read (REQ-DC-036).

use crate::dc::error::Error;
use crate::dc::event::Event;
use crate::dc::machine::{Item, Machine};
use crate::dc::phase::{ActivationStep, Phase};
use crate::dc::request::{le, Op, Reply};
use crate::dc::shared::expect_wkc;
use crate::dc::slave::SlaveInfo;
use crate::dc::state::State;
use crate::dc::work::PerSlave;
use crate::time::SystemTime;
use crate::wire::register::reg;

/// The writes of `ProgramSync`, per SYNC slave.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum SyncWrite {
    /// 0x0990, the slave's exact width.
    StartTime,
    /// 0x09A0.
    Sync0Cycle,
    /// 0x09A4.
    Sync1Cycle,
}

impl PerSlave for SyncWrite {
    const ALL: &'static [Self] = &[
        SyncWrite::StartTime,
        SyncWrite::Sync0Cycle,
        SyncWrite::Sync1Cycle,
    ];
}

/// Whether a slave gets its SYNC unit programmed: it has a system time and is provably not
/// running (same rule as the offset step, REQ-DC-103).
fn sync_target(s: &SlaveInfo) -> bool {
    s.dc.has_system_time() && s.may_step_offset()
}

impl<const N: usize> Machine<N> {
    /// Items of a SYNC step.
    pub(crate) fn activation_count(&self, step: ActivationStep) -> u16 {
        let n = self.sh.line.count;
        match step {
            ActivationStep::ReadReferenceTime => 1,
            ActivationStep::ClearActivation | ActivationStep::ActivateSync => n,
            ActivationStep::ProgramSync => SyncWrite::items(n),
        }
    }

    pub(crate) fn activation_item(&self, i: u16) -> Item {
        let Some(sync) = self.sh.cfg.sync else {
            return Item::Skip;
        };
        match self.phase {
            Phase::Activation(ActivationStep::ReadReferenceTime) => {
                match self.sh.line.slave(self.sh.line.reference) {
                    Some(r) => Item::Send(Op::fprd(r.station, reg::SYSTEM_TIME, r.dc.time_width())),
                    None => Item::Skip,
                }
            }
            Phase::Activation(ActivationStep::ClearActivation) => match self.sh.line.slave(i) {
                Some(s) if sync_target(s) => {
                    Item::Send(Op::fpwr(s.station, reg::SYNC_ACTIVATION, 1, 0))
                }
                _ => Item::Skip,
            },
            // `activation_done` leaves the reference-time read only with a start time, so
            // `start` is always there; without one nothing is written.
            Phase::Activation(ActivationStep::ProgramSync) => {
                match (SyncWrite::of(i), self.sh.line.sync_start) {
                    (Some((pos, write)), Some(start)) => match self.sh.line.slave(pos) {
                        Some(s) if sync_target(s) => Item::Send(match write {
                            SyncWrite::StartTime => Op::fpwr(
                                s.station,
                                reg::SYNC0_START_TIME,
                                s.dc.time_width(),
                                start.as_nanos(),
                            ),
                            SyncWrite::Sync0Cycle => Op::fpwr(
                                s.station,
                                reg::SYNC0_CYCLE,
                                4,
                                u64::from(sync.sync0_cycle_ns),
                            ),
                            SyncWrite::Sync1Cycle => Op::fpwr(
                                s.station,
                                reg::SYNC1_CYCLE,
                                4,
                                u64::from(sync.sync1_cycle_ns),
                            ),
                        }),
                        _ => Item::Skip,
                    },
                    _ => Item::Skip,
                }
            }
            Phase::Activation(ActivationStep::ActivateSync) => match self.sh.line.slave(i) {
                Some(s) if sync_target(s) => Item::Send(Op::fpwr(
                    s.station,
                    reg::CYCLIC_UNIT_CONTROL,
                    2,
                    u64::from(sync.assign_activate),
                )),
                _ => Item::Skip,
            },
            _ => Item::Skip,
        }
    }

    pub(crate) fn activation_reply(&mut self, now: SystemTime, r: Reply<'_>) -> Result<(), Error> {
        let (i, p, wkc, data) = r.parts();
        expect_wkc(p, 1, wkc)?;
        match self.phase {
            Phase::Activation(ActivationStep::ReadReferenceTime) => {
                let bad = p.out_of_range();
                let raw = le(data, usize::from(p.len)).ok_or(bad)?;
                let r = self
                    .sh
                    .line
                    .slave(self.sh.line.reference)
                    .copied()
                    .ok_or(bad)?;
                let sync = self.sh.cfg.sync.ok_or(bad)?;
                self.sh.line.sync_start =
                    Some(self.sh.compute_sync_start(now, raw, &r, &sync).ok_or(bad)?);
            }
            Phase::Activation(ActivationStep::ActivateSync) => {
                if let Some(s) = self.sh.line.slave_mut(i) {
                    s.sync_programmed = true;
                }
            }
            _ => {}
        }
        Ok(())
    }

    pub(crate) fn activation_done(&mut self) -> Result<State, Error> {
        match self.phase {
            // The read is skipped when the reference is not a slave found; no SYNC unit is
            // then programmed (REQ-DC-036: one start, from one reference read).
            Phase::Activation(ActivationStep::ReadReferenceTime) => match self.sh.line.sync_start {
                Some(_) => Ok(State::ClearActivation),
                None => Err(Error::NoReferenceClock),
            },
            Phase::Activation(ActivationStep::ClearActivation) => Ok(State::ProgramSync),
            Phase::Activation(ActivationStep::ProgramSync) => Ok(State::ActivateSync),
            Phase::Activation(ActivationStep::ActivateSync) => {
                let n = self.slaves().iter().filter(|s| s.sync_programmed).count();
                let slaves = u16::try_from(n).unwrap_or(u16::MAX);
                // Set by the reference-time read that opened this phase.
                if let Some(start) = self.sh.line.sync_start {
                    self.sh.push_event(Event::SyncStarted { start, slaves });
                }
                Ok(State::Cyclic)
            }
            _ => Ok(self.state()),
        }
    }
}
